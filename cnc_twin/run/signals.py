"""SIGINT and SIGTERM at any moment of a command: either nothing is left, or the run is written whole.

:class:`SignalGuard` is installed when a command starts and decides what a signal does by the
phase the command is in:

- before the run begins (loading, compiling, starting the planner, building the workpiece; for a
  twin, until its clock starts, see :meth:`SignalGuard.stopping`): the first signal raises
  :class:`Interrupted`; the ``finally`` blocks and context managers on the
  way out end the child processes and remove what was staged, so nothing is left;
- while the twin runs (:meth:`SignalGuard.stopping`): the twin is asked to stop at its next
  period and the run goes on to be written, marked interrupted;
- while the run directory is written (:meth:`SignalGuard.deferred`): the signal is only noted;
  the writing completes, then the command ends with the signal's exit code.

After the first signal every further one is only noted, so a second Ctrl-C cannot cut the
clean-up short. Where the raised :class:`Interrupted` lands in code whose exceptions Python only
prints and drops (a C library calling back into Python, as llvmlite does while numba compiles; a
finaliser), the guard's ``sys.unraisablehook`` keeps it off the terminal and asks the target of
:meth:`SignalGuard.stopping` to stop instead. Exit codes: 130 for SIGINT, 143 for SIGTERM (128 + the signal number).
"""

from __future__ import annotations

import signal
import sys
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM)


def exit_code(name: str) -> int:
    """The shell's exit code for a process ended by the signal ``name`` ("SIGINT" -> 130)."""
    return 128 + int(signal.Signals[name])


class Interrupted(BaseException):
    """A signal arrived before the run began (a BaseException, like KeyboardInterrupt: ``except
    Exception`` clauses on the way out do not swallow it)."""

    def __init__(self, name: str):
        super().__init__(name)
        self.name = name


class SignalGuard:
    """Context manager: SIGINT / SIGTERM handled by phase (see the module docstring).
    ``received`` is the first signal's name ("SIGINT", "SIGTERM"), or None. With ``restore``
    False (the command is the whole process) the signals are ignored after the block: one while
    the interpreter shuts down cannot kill a process whose work is done."""

    def __init__(self, *, restore: bool = True):
        self.restore = restore
        self.received: str | None = None
        self._previous: dict[int, object] = {}
        self._previous_unraisable = sys.unraisablehook
        self._on_signal = self._raise
        self._target = None  # the target of :meth:`stopping`, within its block

    def __enter__(self) -> "SignalGuard":
        for sig in SIGNALS:
            self._previous[sig] = signal.signal(sig, self._handle)
        self._previous_unraisable = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if self.restore or self.received is None:
            sys.unraisablehook = self._previous_unraisable
        # else the process ends next, interrupted: the guard's hook stays, for the finalisers of
        # what the signal left half built (seen in CI: llvmlite's ObjectRef.__del__ failing with
        # AttributeError at exit, the interruption having cut its construction short)
        self._restore()
        if exc_type is not None and issubclass(exc_type, Exception) and self.received is not None \
                and interruption_in(exc) is None:
            # an error after the signal, that does not carry the interruption: the signal's doing
            # (an extension module's import failing with an error of its own, as numpy's
            # "Importing the numpy C-extensions failed" after PyCapsule_Import lost it; numba's
            # compiler failing to cache a function whose object-code callback the signal cut
            # short, "no compiled object yet"): the command was asked to stop, and stops so
            raise Interrupted(self.received) from None
        return False

    def _restore(self) -> None:
        if self.restore:
            for sig, handler in self._previous.items():
                signal.signal(sig, handler)
        else:  # the process ends next, its work done: a signal while it shuts down changes nothing.
            # Ignored, not handled: Python resets its own handlers to the default (die) early in
            # the interpreter's finalization, but leaves an ignored signal ignored
            for sig in SIGNALS:
                signal.signal(sig, signal.SIG_IGN)

    def _handle(self, signum: int, frame) -> None:
        if self.received is not None:
            return  # only noted: the first one is being handled
        self.received = signal.Signals(signum).name
        not_begun = self._target is not None and not getattr(self._target, "begun", True)
        if self._on_signal == self._raise or not_begun:
            if not _swallowed_here(frame):
                self._raise(self.received)
            elif not_begun:  # cannot raise here: the target stops as soon as it begins
                self._target.request_stop(self.received)
            # else only noted; the run that follows stops at once (:meth:`stopping`)
        else:
            self._on_signal(self.received)

    def _unraisable(self, report) -> None:
        """``sys.unraisablehook`` while the guard is in place: an :class:`Interrupted` raised where
        Python can only print and drop it (a C library's callback into Python, as llvmlite's object
        cache during numba's compiling, a finaliser) is not printed as "Exception ignored ...
        Traceback"; the signal stays noted, and the target of :meth:`stopping` (a twin still
        compiling) is asked to stop, which it does at its first period. After a signal anything
        else dropped so is the interruption's debris (a finaliser of an object it left half
        built) and is not printed either; before any signal it goes to the hook that was in
        place."""
        if isinstance(report.exc_value, Interrupted):
            if self._target is not None:
                self._target.request_stop(report.exc_value.name)
            return
        if self.received is not None:
            return
        self._previous_unraisable(report)

    def _raise(self, name: str) -> None:
        self._on_signal = _note  # clean-up on the way out is not cut short by a second signal
        raise Interrupted(name)

    @contextmanager
    def stopping(self, target):
        """Within the block a signal asks ``target`` to stop: a twin (at its next period), or
        anything else with ``request_stop(name)`` (a sweep's stop). One that came before the
        block stops it at once.

        A target with a ``begun`` attribute that is still False (a twin compiling its kernels and
        starting its planner: nothing recorded yet) is not asked: the signal raises
        :class:`Interrupted` as before the run, so a Ctrl-C during a first run's minute of
        compiling ends the command at once instead of after it."""
        if self.received is not None:
            target.request_stop(self.received)
        self._on_signal, self._target = target.request_stop, target
        try:
            yield
        finally:
            self._on_signal, self._target = _note, None

    @contextmanager
    def deferred(self):
        """Within the block a signal is only noted (``received``)."""
        self._on_signal = _note
        yield


def _swallowed_here(frame) -> bool:
    """The signal came inside a callback whose exceptions Python ignores: the weakref callback of
    importlib's module locks, run when an import on the way finishes. Raised there, Interrupted
    would be printed as "Exception ignored ... Traceback" and lost."""
    while frame is not None:
        code = frame.f_code
        if code.co_filename.startswith("<frozen importlib") and code.co_name == "cb":
            return True
        frame = frame.f_back
    return False


def _note(_name: str) -> None:
    """A signal that only needs noting (``SignalGuard.received`` holds it)."""


def interruption_in(exc: BaseException) -> BaseException | None:
    """The Interrupted or KeyboardInterrupt in ``exc``'s chain of causes, if any."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, (Interrupted, KeyboardInterrupt)):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is, so that its ``finally`` blocks and context managers
    clean up as for Ctrl-C."""


def terminate(signum, frame):
    """The SIGTERM handler: further SIGTERMs ignored (the cleanup is not interrupted again), then
    :class:`Terminated` raised."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # once: the cleanup itself is not interrupted again
    raise Terminated

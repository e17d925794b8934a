"""Starting a helper process (the planner, the recording): a new interpreter, or a fork of this one.

A helper is ``python -m MODULE ARGS`` with pipes on its stdin and stdout (:func:`start_helper`),
ended by :func:`cnc_twin.core.child_process.end_process`. A new interpreter pays its imports
(0.2 - 1 s). In a command the warm server started (:mod:`cnc_twin.server`), the process has
imported everything already, so :data:`FORK` is set there and a helper is this process forked:
the module's ``main(args)`` called in the child, which starts in a millisecond. It is forked only
while this process runs no other Python thread (a thread holding a lock at the fork would hold it
forever in the child); otherwise, and whenever :data:`FORK` is off, a new interpreter is started.

:class:`ForkedHelper` offers the part of :class:`subprocess.Popen` the helpers' owners use: ``pid``,
``stdin``, ``stdout``, ``poll``, ``wait``, ``terminate``, ``kill``, ``returncode``.
"""

from __future__ import annotations

import importlib
import io
import os
import select
import signal
import subprocess
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import IO, Callable, Sequence

from cnc_twin.core.messages import framed, read_message

FORK = False
"""set by the warm server's command process: helpers are forks of it (see the module's text)"""

SPARES: dict[str, tuple[int, int, int, int]] = {}
"""helpers the warm server started ahead, by module: (process id, its stdin's and stdout's pipe
ends, its stderr file's descriptor), handed to the command it forked; each taken once"""


def can_fork() -> bool:
    """Whether a new process had better be a fork of this one: it is warm (:data:`FORK`) and runs
    no other Python thread."""
    return FORK and threading.active_count() == 1


def start_helper(module: str, args: Sequence[str] = (), *, pass_fds: Sequence[int] = (), stderr: IO | None = None,
                 env: dict[str, str] | None = None) -> "subprocess.Popen | ForkedHelper":
    """``python -m module *args`` with piped stdin and stdout (binary), the descriptors ``pass_fds``
    kept open in it, ``stderr`` (a file) or this process's stderr; ``env`` for a new interpreter
    (a fork keeps this process's modules, so variables read at import are already read)."""
    if not args and module in SPARES:
        return AdoptedHelper(*SPARES.pop(module), module=module)
    if can_fork():
        return ForkedHelper(module, list(args), pass_fds=pass_fds, stderr=stderr)
    return subprocess.Popen(module_command(module, args), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=stderr, pass_fds=tuple(pass_fds), close_fds=True, env=env)


_RUN_MODULE = ("import runpy, sys; sys.path.insert(0, sys.argv.pop(1)); "
               "runpy.run_module(sys.argv.pop(1), run_name='__main__', alter_sys=True)")
"""``python -P -c`` this ``ROOT MODULE ARGS...``: ``python -m MODULE ARGS`` with the package from ROOT"""


def module_command(module: str, args: Sequence[str] = ()) -> list[str]:
    """The command line of ``python -m module *args`` that imports this very package: from the
    folder this process imported it from, not from the current folder (``-m`` puts that first:
    run from a checkout beside an installed package, a helper would run the checkout's code)."""
    root = str(Path(__file__).resolve().parent.parent.parent)
    return [sys.executable, "-P", "-c", _RUN_MODULE, root, module, *args]


class ForkedHelper:
    """A helper forked from this process, running ``module.main(args)`` (its return value the exit
    status). Its stdin and stdout are pipes to this process; every other descriptor but stderr and
    ``pass_fds`` is closed in it, as ``close_fds`` does for a new interpreter.

    A ``spare`` (the warm server's, started ahead for a command to come) first calls the module's
    ``prepare()`` (its slow imports), then waits for the working directory and environment of the
    command that adopts it (:class:`AdoptedHelper` sends them), takes them on, and only then runs
    ``main``."""

    def __init__(self, module: str, args: list[str], *, pass_fds: Sequence[int] = (), stderr: IO | None = None,
                 spare: bool = False):
        importlib.import_module(module)  # imported here, not in each child
        in_read, in_write = os.pipe()
        out_read, out_write = os.pipe()
        err_fd = stderr.fileno() if stderr is not None else 2
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child (its exit status is checked by the helpers' tests)
            _child(module, args, in_read, out_write, err_fd, tuple(pass_fds), spare)
        os.close(in_read)
        os.close(out_write)
        self._own(pid, [module, *args], in_write, out_read)

    def _own(self, pid: int, args: list[str], stdin_fd: int, stdout_fd: int) -> None:
        self.pid = pid
        self.args = args
        self.returncode: int | None = None
        self.stdin = io.open(stdin_fd, "wb")
        self.stdout = io.open(stdout_fd, "rb")
        self.pidfd = _pidfd(pid)
        """a descriptor that becomes readable when the helper ends (None where Linux has none)"""

    def poll(self) -> int | None:
        """The exit status if the helper has ended (reaped then), else None."""
        if self.returncode is None:
            try:
                done, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # reaped elsewhere: it has ended
                done, status = self.pid, 0
            if done == self.pid:
                self.returncode = os.waitstatus_to_exitcode(status)
                self._close_pidfd()
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Wait until the helper ends (at most ``timeout`` [s]: then :class:`subprocess.TimeoutExpired`)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise subprocess.TimeoutExpired(self.args, timeout)
            if self.pidfd is not None:
                select.select([self.pidfd], [], [], left)
            else:
                time.sleep(0.005 if left is None else min(0.005, left))
        return self.returncode

    def send_signal(self, signum: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, signum)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def _close_pidfd(self) -> None:
        if self.pidfd is not None:
            os.close(self.pidfd)
            self.pidfd = None

    def __del__(self):
        self._close_pidfd()


class AdoptedHelper(ForkedHelper):
    """A helper another process started (the warm server's spare, :data:`SPARES`): used as a
    :class:`ForkedHelper`, but its exit status is its parent's to collect, so
    :meth:`~AdoptedHelper.poll` knows only that it ended (status 0). ``stderr_file`` is its stderr,
    a file to read its last words from."""

    def __init__(self, pid: int, stdin_fd: int, stdout_fd: int, stderr_fd: int, *, module: str):
        self._own(pid, [module], stdin_fd, stdout_fd)
        self.stderr_file = io.open(stderr_fd, "w+b")
        try:  # what a new helper would have from this process (paths relative to it, DISPLAY...)
            self.stdin.write(framed((os.getcwd(), dict(os.environ))))
            self.stdin.flush()
        except OSError:  # it died: its owner finds out as from any helper
            pass

    def poll(self) -> int | None:
        if self.returncode is None:
            if self.pidfd is not None:
                ended = bool(select.select([self.pidfd], [], [], 0)[0])
            else:
                try:
                    os.kill(self.pid, 0)
                    ended = False
                except ProcessLookupError:
                    ended = True
            if ended:
                self.returncode = 0
                self._close_pidfd()
        return self.returncode


def _pidfd(pid: int) -> int | None:
    try:
        return os.pidfd_open(pid)
    except (AttributeError, OSError):  # not Linux 5.3+: wait() polls
        return None


def _child(module: str, args: list[str], stdin_fd: int, stdout_fd: int, stderr_fd: int,
           pass_fds: tuple[int, ...], spare: bool) -> None:  # pragma: no cover - runs in the forked child
    """The forked helper: its descriptors and signals as a new interpreter's, then (a spare: after
    ``prepare()`` and its adopter's directory and environment) ``main(args)``; never returns."""

    def helper() -> int | None:
        os.dup2(stdin_fd, 0)
        os.dup2(stdout_fd, 1)
        if stderr_fd != 2:
            os.dup2(stderr_fd, 2)
        keep = sorted({0, 1, 2, *pass_fds})
        for low, high in zip(keep, keep[1:] + [os.sysconf("SC_OPEN_MAX")]):
            os.closerange(low + 1, high)
        as_new_interpreter()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        code = importlib.import_module(module)
        if spare:
            getattr(code, "prepare", lambda: None)()
            adopted = read_message(0)
            if adopted is None:  # the server ended without handing it to a command
                return 0
            cwd, environment = adopted
            os.chdir(cwd)
            os.environ.clear()
            os.environ.update(environment)
        return code.main(args)

    exit_as_program(helper)


def as_new_interpreter() -> None:  # pragma: no cover - in forked processes
    """A forked process's signals and standard streams as a new interpreter would have them:
    no wake-up descriptor, SIGCHLD, SIGHUP, SIGQUIT and the user signals at their defaults, and
    ``sys.stdin``/``stdout``/``stderr`` new objects over descriptors 0, 1, 2 (nothing the parent
    buffered is written twice), buffered as Python buffers them (``PYTHONUNBUFFERED`` read now).
    SIGINT and SIGTERM are the caller's to set."""
    signal.set_wakeup_fd(-1)
    for signum in (signal.SIGCHLD, signal.SIGHUP, signal.SIGQUIT, signal.SIGUSR1, signal.SIGUSR2):
        signal.signal(signum, signal.SIG_DFL)
    unbuffered = bool(os.environ.get("PYTHONUNBUFFERED"))
    sys.stdin = io.TextIOWrapper(io.open(0, "rb", closefd=False), encoding=sys.__stdin__.encoding,
                                 errors=sys.__stdin__.errors)
    sys.stdout = io.TextIOWrapper(io.open(1, "wb", closefd=False), encoding=sys.__stdout__.encoding,
                                  errors=sys.__stdout__.errors, line_buffering=os.isatty(1), write_through=unbuffered)
    sys.stderr = io.TextIOWrapper(io.open(2, "wb", closefd=False), encoding=sys.__stderr__.encoding,
                                  errors="backslashreplace", line_buffering=True, write_through=unbuffered)


def exit_as_program(main: Callable[[], int | None]) -> None:  # pragma: no cover - in forked processes
    """Run ``main`` as a program's own would run, then end this forked process with its status:
    what it returns (None: 0); SystemExit's code as Python ends with it; 1, with the traceback,
    for any other exception. The standard streams are flushed, and nothing of the process it was
    forked from is torn down (``os._exit``)."""
    code = 1
    try:
        result = main()
        code = 0 if result is None else result
    except SystemExit as exc:  # argparse's usage errors, sys.exit()
        if exc.code is None or isinstance(exc.code, int):
            code = exc.code or 0
        else:
            print(exc.code, file=sys.stderr)
    except BaseException:
        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # the reader is gone: nothing more to tell it
                pass
        os._exit(code)

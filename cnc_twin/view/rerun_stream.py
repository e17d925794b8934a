"""Recording a run while it runs: a rerun recording process, fed stretch by stretch.

Exporting a finished run to rerun takes about a fifth of the run's own time on the reference
curve (rerun's Arrow encoding, the blueprint, the geometry, the close) plus half a second to
import rerun. A
:class:`RecordingProcess` does that work in a process of its own, on another core, while the
twin runs: the twin's process sends it each stretch of :class:`~cnc_twin.trace.trace.PeriodSamples`
(167 bytes per period) as the run records them, and when the run is over only the last stretch,
the paths, the events and the close remain. The recording is the same as
:func:`~cnc_twin.view.rerun_export.export_run` makes after the run (``tests/test_rerun_stream.py``).

The process is ``python -m cnc_twin.view.rerun_stream``. Its stdin carries length-prefixed pickles:

- ``("open", scenario, rrd, spawn, planned)``: the recording's sinks (a file path or None, a
  viewer) and the planned path (:func:`~cnc_twin.geometry.tip_path.planned_path`, computed by the
  twin's process, which has scipy loaded already);
- ``("samples", PeriodSamples)``: the next stretch;
- ``("finish", n_ticks, metrics, exchange_latency)``: the rest, then flush and close.

It writes ``ready`` on its stdout once its imports are done, and one more line when the
recording is closed: ``ok`` or ``error: ...``. EOF
before ``finish`` (the twin's process died) closes the recording with what it received, so
nothing sent is lost. It ignores SIGINT: Ctrl-C reaches the whole process group, and the twin
decides (it stops at the next period and finishes the recording).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import select
import signal
import sys
import tempfile
from pathlib import Path

from cnc_twin.core.child_process import end_process
from cnc_twin.core.helpers import start_helper
from cnc_twin.core.errors import one_line
from cnc_twin.core.messages import framed, read_message
from cnc_twin.trace.trace import PeriodSamples

PIPE_BYTES = 1 << 20
"""the pipe to the recording process is enlarged to this (Linux; 6 simulated seconds of
samples at 1 ms periods), so the twin does not wait on a recorder busy encoding"""
MIN_STRETCH = 250
"""periods gathered before a stretch is sent: each stretch costs the recording process about
4 ms of rerun calls whatever its length (and the twin about 20 us), so few and long, but the last
one is encoded after the run"""
NICENESS = 10
"""the recording process yields the CPU to the twin and the planner (in lockstep the card waits
for the planner's answers): recording is background work until the run is over"""
FINISH_TIMEOUT = 120.0
"""how long :meth:`RecordingProcess.finish` waits for the recording to be closed [s]"""


class RecordingError(RuntimeError):
    """The recording process failed or could not be reached; its reason in one line."""


class RecordingProcess:
    """A rerun recording process for one run. Start it early (its imports take about a second
    and overlap the twin's), :meth:`open` it, pass :meth:`observe` to
    :meth:`~cnc_twin.run.twin.Twin.run` as ``observer``, then :meth:`finish` with the result (or
    :meth:`hand_over` it, do other work, and :meth:`wait`).

    After a failure (the process died, a pipe broke) the sends stop and :meth:`finish` raises
    :class:`RecordingError`: the run itself is never held up by its recording.
    """

    def __init__(self, *, min_stretch: int = MIN_STRETCH):
        self.min_stretch = min_stretch
        """periods gathered before :meth:`observe` sends a stretch"""
        self._stderr = tempfile.TemporaryFile()
        self.popen = start_helper("cnc_twin.view.rerun_stream", stderr=self._stderr)
        if getattr(self.popen, "stderr_file", None) is not None:  # the warm server's spare: its own file
            self._stderr.close()
            self._stderr = self.popen.stderr_file
        try:
            fcntl.fcntl(self.popen.stdin.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)
        except (AttributeError, OSError):  # not Linux, or above /proc/sys/fs/pipe-max-size: the default pipe
            pass
        self.rrd: Path | None = None
        self.sent_periods = 0
        self.stretches = 0
        """stretches sent so far"""
        self.failure: str | None = None
        self._ticks_per_period = 1
        self._ready = False

    def wait_ready(self, timeout: float = 60.0) -> bool:
        """Wait until the process has imported what it needs (about a second after the start);
        True when it has. Not needed before :meth:`open`: messages queue in the pipe."""
        if not self._ready:
            self._ready = self._answer(timeout) == "ready"
        return self._ready

    def open(self, scenario, *, rrd: Path | None = None, spawn: bool = False) -> None:
        """Start the recording of a run of ``scenario`` into the file ``rrd`` and/or a spawned viewer."""
        self.rrd = None if rrd is None else Path(rrd)
        if self.rrd is not None:  # a folder that is not there yet is made, as result.write() makes its own
            with contextlib.suppress(OSError):  # not here: the recording process says why it cannot write
                self.rrd.parent.mkdir(parents=True, exist_ok=True)
        self._ticks_per_period = scenario.timing.ticks_per_period
        from cnc_twin.geometry.tip_path import planned_path  # scipy's splines: a curve scenario loaded them already

        self._send(("open", scenario, None if rrd is None else str(rrd), spawn, planned_path(scenario)))

    def observe(self, twin) -> None:
        """The twin's observer: sends the whole periods recorded since the last send, once at
        least :attr:`min_stretch` have gathered, or the recorder's window is full (a long run's
        recorder then moves its window on)."""
        recorder = twin.recorder
        done = recorder.count // self._ticks_per_period
        if done - self.sent_periods >= self.min_stretch or (done > self.sent_periods and recorder.count >= recorder.room):
            self._send_periods(recorder, done)

    def finish(self, result, *, timeout: float = FINISH_TIMEOUT) -> Path | None:
        """:meth:`hand_over` then :meth:`wait`: the finished recording's file (None without one)."""
        self.hand_over(result)
        return self.wait(timeout=timeout)

    def hand_over(self, result) -> None:
        """Send what is left of the run ``result`` and ask for the recording to be closed; returns
        at once (the twin's process can write its other files meanwhile)."""
        trace = result.trace
        self._send_periods(trace, trace.whole_periods)
        self._send(("finish", len(trace), result.metrics, result.exchange_latency, result.figures()))
        try:
            self.popen.stdin.close()
        except OSError:
            pass

    def wait(self, *, timeout: float = FINISH_TIMEOUT) -> Path | None:
        """After :meth:`hand_over`: wait until the recording is closed; returns its file. Raises
        :class:`RecordingError` (one line) if it could not be completed."""
        # A process that failed has said why on its stdout before it ended: prefer its reason.
        answer = self._answer(timeout if self.failure is None else 1.0)
        if answer == "ready":
            answer = self._answer(timeout if self.failure is None else 1.0)
        said = answer.startswith("error: ")
        if said:
            reason = answer.removeprefix("error: ")
            self.failure = reason if len(reason) <= 200 else reason[:200] + "..."
        elif answer != "ok" and self.failure is None:
            self.failure = "the recording process ended without closing the recording"
        if self.failure is not None:
            raise RecordingError(one_line(f"rerun recording process: {self.failure}"
                                          f"{'' if said else self._stderr_tail()}"))
        return self.rrd

    def close(self) -> None:
        """End the process (EOF, then SIGTERM, then SIGKILL); idempotent."""
        end_process(self.popen, grace=5.0, term_grace=2.0)
        self.popen.stdout.close()
        self._stderr.close()

    def __enter__(self) -> "RecordingProcess":
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False

    def _send_periods(self, source, stop: int) -> None:
        if stop > self.sent_periods and self.failure is None:
            self._send(("samples", PeriodSamples.take(source, self.sent_periods, stop)))
            self.sent_periods = stop
            self.stretches += 1

    def _send(self, message) -> None:
        if self.failure is not None:
            return
        data = framed(message)
        try:
            self.popen.stdin.write(data)
            self.popen.stdin.flush()
        except (BrokenPipeError, OSError, ValueError) as exc:
            self.failure = f"lost during the run ({type(exc).__name__})"

    def _answer(self, timeout: float) -> str:
        """The process's next line on its stdout ("" at EOF, "no answer ..." on time-out)."""
        ready, _, _ = select.select([self.popen.stdout], [], [], timeout)
        if not ready:
            return f"error: no answer within {timeout:g} s"
        return self.popen.stdout.readline().decode(errors="replace").strip()

    def _stderr_tail(self) -> str:
        try:
            self._stderr.seek(0)
            lines = self._stderr.read().decode(errors="replace").strip().splitlines()
        except (OSError, ValueError):
            return ""
        return f"; its last words: {lines[-1]}" if lines else ""


def _readable(fd: int) -> bool:
    return bool(select.select([fd], [], [], 0)[0])


def prepare() -> None:
    """What the process imports before its first message (rerun): a warm server's spare does it
    ahead (:class:`cnc_twin.core.helpers.ForkedHelper`, ``spare=True``)."""
    from cnc_twin.view.path_views import warm_up
    from cnc_twin.view.rerun_export import RunExporter  # noqa: F401

    warm_up()
    try:  # rerun's 3D points go through pyarrow, which loads pandas at its first such array (0.6 s)
        import pandas  # noqa: F401
    except ImportError:  # pragma: no cover - pyarrow then does without it
        pass


def serve(fd: int, out) -> int:
    """The recording process: messages from ``fd`` until ``finish`` or EOF; the answer to ``out``."""
    try:
        # Imported (and the path views' kernel loaded) before the first message: this overlaps
        # the twin process's own start-up.
        prepare()
        from cnc_twin.view.rerun_export import RunExporter
    except Exception as exc:  # pragma: no cover - a broken installation
        return _failed(exc, out)
    out.write(b"ready\n")
    out.flush()
    message = read_message(fd)
    if message is None:  # started but never used (a run that failed before it began)
        return 0
    try:
        _, scenario, rrd, spawn, planned = message
        exporter = RunExporter(scenario, compiled=False)  # numba's load would cost more than it saves
        exporter.start(rrd=None if rrd is None else Path(rrd), spawn=spawn, planned=planned)
        pending: list = []
        while True:
            message = read_message(fd)
            if message is None or message[0] == "finish":
                if pending:
                    exporter.send(PeriodSamples.join(pending))
                if message is None:  # the twin's process is gone: keep what it sent
                    exporter.finish(exporter.sent_periods * exporter.tpp, {})
                    return 1
                exporter.finish(*message[1:])
                out.write(b"ok\n")
                out.flush()
                return 0
            pending.append(message[1])
            # Stretches that queued while the last one was encoded go out as one (fewer calls).
            if not _readable(fd):
                exporter.send(PeriodSamples.join(pending))
                pending = []
    except Exception as exc:
        return _failed(exc, out)


def _failed(exc: Exception, out) -> int:
    """One line for the twin's process; the traceback goes to stderr."""
    import traceback

    traceback.print_exc()
    out.write(f"error: {type(exc).__name__}: {exc}".replace("\n", " ").encode() + b"\n")
    out.flush()
    return 1


def main(argv: list[str] | None = None) -> int:
    """``python -m cnc_twin.view.rerun_stream`` (no arguments): record what comes on stdin."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the group; the twin decides
    os.nice(NICENESS)
    return serve(sys.stdin.fileno(), sys.stdout.buffer)


if __name__ == "__main__":
    code = main()
    # the recording is closed (or its failure told): end without the interpreter's teardown of
    # rerun and numpy (half a second the twin's command would wait for)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)

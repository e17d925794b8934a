"""SIGINT and SIGTERM at any moment of `cnc-twin run`: either nothing is left (the run had not
begun) or a complete, readable run directory marked interrupted; exit 130 / 143 either way, and
no stray file, shared-memory segment or child process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml

from cnc_twin.run.run_dir import METRICS_FILE, RECORDING_FILE, SCENARIO_FILE, TRACE_FILE
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.whiteboard.block import leaked_segments, leftover_segments

SCENARIO = scenarios_dir() / "freeform_polish.yaml"
MOMENTS = 10


class StopTarget:
    """What :meth:`SignalGuard.stopping` stops, recording the request: a twin that has ``begun``
    (its clock runs) or not yet (compiling, starting its planner)."""

    def __init__(self, *, begun: bool = True):
        self.begun = begun
        self.stopped = None

    def request_stop(self, name):
        self.stopped = name


STEP_OVER = 25.0
"""[mm] the raster's step-over here (the bundled scenario's is 7 mm): 22 s simulated instead of 46,
about 1.5 s in the clock, half the CPU of each of this module's dozen runs"""


@pytest.fixture(scope="module")
def scenario(tmp_path_factory) -> Path:
    """The freeform polishing run with a wider step-over, whole: every stage a polishing run goes
    through (workpiece solid, MJCF, planner, seek, force loop, turns, removal map, recording,
    writing), its run in batches long enough (about 1.5 s) that the middle moment falls inside
    the clock."""
    data = yaml.safe_load(SCENARIO.read_text())
    data["program"]["path"]["step_over"] = STEP_OVER
    target = tmp_path_factory.mktemp("scenario") / SCENARIO.name
    target.write_text(yaml.safe_dump(data, sort_keys=False))
    return target


def _start(folder: Path, scenario: Path, env: dict[str, str] | None = None) -> subprocess.Popen:
    """`cnc-twin run scenario` into ``folder/run``, in a session of its own (its process group is
    its pid)."""
    folder.mkdir(parents=True)
    return subprocess.Popen([sys.executable, "-m", "cnc_twin", "run", str(scenario), "--out", str(folder / "run")],
                            cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=env)


def _wait_until_running(proc: subprocess.Popen) -> None:
    """Until the twin runs: the command says so on stderr (its clock has started: kernels
    compiled, planner started; the freeform run lasts seconds after it); the moment whose
    outcome is asserted is found this way rather than from a clean run's time, which a loaded
    machine can stretch many times over. (Its whiteboard's existence is earlier: the kernels
    load after it, and a signal then ends the command with nothing written.)"""
    for line in proc.stderr:
        if ": running (" in line:
            return
    pytest.fail(f"the run never started (exit {proc.wait()})")


def _wait_until_started(proc: subprocess.Popen, timeout: float = 60.0) -> None:
    """Until the CLI has started: its first lines catch SIGINT and SIGTERM (cnc_twin/entry.py).
    Before that the interpreter itself is starting, and a signal there is the OS's business."""
    wanted = (1 << (signal.SIGINT - 1)) | (1 << (signal.SIGTERM - 1))
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            status = Path(f"/proc/{proc.pid}/status").read_text()
        except OSError:
            return
        caught = int(next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), 16)
        if caught & wanted == wanted:
            return
        time.sleep(0.002)


def _live_members(group: int) -> list[str]:
    """Processes of ``group`` still alive (zombies waiting for init to reap them are not)."""
    out = subprocess.run(["ps", "-o", "pid=,stat=,args=", "-g", str(group)], capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if line.split()[1][0] != "Z"]


def _outcome(proc: subprocess.Popen, folder: Path, segments_before: set[str]) -> str:
    """Wait for ``proc``; assert one of the two clean outcomes; which one ("nothing" / "run")."""
    _, err = proc.communicate(timeout=120)
    deadline = time.monotonic() + 10.0
    while _live_members(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _live_members(proc.pid) == [], "a child process outlived the command"
    assert leaked_segments(set(leftover_segments()) - segments_before) == set()
    assert "Traceback" not in err, err
    files = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))
    run = folder / "run"
    if not run.exists():
        assert files == [], files  # nothing staged or hidden left behind
        return "nothing"
    assert {SCENARIO_FILE, TRACE_FILE, METRICS_FILE, RECORDING_FILE} <= {p.name for p in run.iterdir()}
    assert not [p.name for p in run.iterdir() if p.name.startswith(".")]  # nothing half-written inside
    assert [f for f in files if not f.startswith("run/")] == ["run"]  # no hidden staging beside it
    metrics = json.loads((run / METRICS_FILE).read_text())
    trace = pq.read_table(run / TRACE_FILE)
    assert trace.num_rows > 0 or metrics["sim_time_s"] == 0.0
    assert (run / RECORDING_FILE).stat().st_size > 0
    if proc.returncode == 0:
        assert metrics["status"] == "complete"
        return "complete"
    assert metrics["status"] == "interrupted" and metrics["stop_reason"].startswith(("SIGINT", "SIGTERM"))
    return "run"


@pytest.fixture(scope="module")
def time_scale(tmp_path_factory, scenario) -> float:
    """[s] a clean run's wall time from start-up to the last write (the ten moments spread over
    it). Measured once per session: the suite's workers share it through a locked file in their
    common temporary folder (the first to need it runs the clean run, the others read it)."""
    import fcntl

    base = tmp_path_factory.getbasetemp()
    # under xdist each worker's folder sits in the session's; without it the folder is the session's
    shared = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "signals_time_scale.txt"
    with open(shared.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if shared.exists():
            return float(shared.read_text())
        folder = tmp_path_factory.mktemp("clean")
        before = set(leftover_segments())
        started = time.monotonic()
        clean = _start(folder / "clean", scenario)
        assert _outcome(clean, folder / "clean", before) == "complete", clean.returncode
        scale = time.monotonic() - started
        shared.write_text(repr(scale))
        return scale


def signal_at_moment(k: int, time_scale: float, tmp_path: Path, scenario: Path) -> None:
    """SIGINT (even ``k``) or SIGTERM (odd) at moment ``k`` of ten evenly spread over a clean
    run's time: the first comes before the run begins (nothing left), the middle one while it
    runs (a whole run directory, interrupted), any other leaves one of the two."""
    before = set(leftover_segments())
    at, sig = time_scale * (k + 0.5) / MOMENTS, (signal.SIGINT, signal.SIGTERM)[k % 2]
    t0 = time.monotonic()
    proc = _start(tmp_path / f"m{k}", scenario)
    _wait_until_started(proc)
    if k == 0:  # the first moment: as soon as the command catches signals, long before any run
        at = time.monotonic() - t0
    elif k == MOMENTS // 2:  # the middle one: once the twin is running (it says so)
        _wait_until_running(proc)
        at = time.monotonic() - t0 + 0.2
    time.sleep(max(0.0, t0 + at - time.monotonic()))
    sent = time.time()
    proc.send_signal(sig)
    outcome = _outcome(proc, tmp_path / f"m{k}", before)
    if outcome == "complete":
        # a late moment may come after the run directory was in place (a loaded machine runs
        # faster or slower than the clean run did): the command then ends as a complete run,
        # exit 0; never a complete run the signal should have stopped
        done = (tmp_path / f"m{k}" / "run").stat()
        assert max(done.st_ctime, done.st_mtime) <= sent + 0.01, (k, "a signal before the end was not acted on")
    else:
        assert proc.returncode == 128 + int(sig), (k, proc.returncode)
    if k == 0:
        assert outcome == "nothing", f"at {at:.2f} s the run had already begun"
    if k == MOMENTS // 2:
        assert outcome == "run", f"at {at:.2f} s: {outcome}"


# The ten moments are two classes of tests, so that two workers share them (loadscope keeps a
# class on one worker; the clean run is made once, by the first to need it).
class TestSigintMoments:
    @pytest.mark.parametrize("k", range(0, MOMENTS, 2))
    def test_a_signal_at_ten_moments_leaves_nothing_or_a_whole_run(self, k, time_scale, tmp_path, scenario):
        signal_at_moment(k, time_scale, tmp_path, scenario)


class TestSigtermMoments:
    @pytest.mark.parametrize("k", range(1, MOMENTS, 2))
    def test_a_signal_at_ten_moments_leaves_nothing_or_a_whole_run(self, k, time_scale, tmp_path, scenario):
        signal_at_moment(k, time_scale, tmp_path, scenario)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_the_moment_the_cli_starts_ends_it_in_one_line(sig, tmp_path, scenario):
    """The earliest moment: as soon as the program's first lines run, before its imports. One
    line, 130 / 143, nothing written (not a KeyboardInterrupt traceback, not a death by SIGTERM)."""
    before = set(leftover_segments())
    proc = _start(tmp_path / "early", scenario)
    _wait_until_started(proc)
    proc.send_signal(sig)
    assert _outcome(proc, tmp_path / "early", before) == "nothing"
    assert proc.returncode == 128 + int(sig)


def test_a_signal_inside_an_extension_module_import_is_the_interruption(monkeypatch, tmp_path, capsys):
    """A signal while an extension module initialises (seen in CI: SIGINT during `import mujoco`)
    surfaces as an ImportError caused by the interruption; the CLI reports the interruption in
    one line with its exit code, not the import's traceback."""
    import cnc_twin.cli as cli
    from cnc_twin.run.signals import Interrupted
    from cnc_twin.studies import run_command

    def interrupted_import(*args, **kwargs):
        try:
            raise Interrupted("SIGINT")
        except Interrupted as exc:
            raise ImportError("initialization failed") from exc

    monkeypatch.setattr(run_command, "check_writable_parent", interrupted_import)
    code = cli.main(["run", str(SCENARIO), "--out", str(tmp_path / "run"), "--no-rrd"])
    err = capsys.readouterr().err
    assert code == 130 and err.strip() == "interrupted by SIGINT before the run began; nothing was written"
    assert not (tmp_path / "run").exists()


def test_a_signal_that_an_extension_module_loses_in_its_import_error_is_still_the_interruption(
        monkeypatch, tmp_path, capsys):
    """Seen while testing: SIGINT while numpy's C core imports ``datetime`` through
    PyCapsule_Import, which replaces the interruption by its own ImportError, and numpy's "Importing
    the numpy C-extensions failed" carries no trace of it. The guard received the signal, so the
    failed import is the interruption: one line, exit 130, nothing written."""
    import signal as signals

    import cnc_twin.cli as cli
    from cnc_twin.studies import run_command

    def import_losing_the_signal(*args, **kwargs):
        try:
            signals.raise_signal(signals.SIGINT)  # the guard's handler raises Interrupted here
        except BaseException:
            pass  # what PyCapsule_Import does with it
        raise ImportError("PyCapsule_Import could not import module \"datetime\"")

    monkeypatch.setattr(run_command, "check_writable_parent", import_losing_the_signal)
    code = cli.main(["run", str(SCENARIO), "--out", str(tmp_path / "run"), "--no-rrd"])
    err = capsys.readouterr().err
    assert code == 130 and err.strip() == "interrupted by SIGINT before the run began; nothing was written"
    assert not (tmp_path / "run").exists()


def test_a_signal_inside_importlibs_lock_callback_is_noted_and_stops_the_run_at_once():
    """Seen in CI: SIGTERM inside importlib's module-lock weakref callback (``cb``), where a raised
    Interrupted is printed as "Exception ignored ... Traceback" and lost. There the guard only notes
    the signal; the run that follows stops at once (one of the two clean outcomes)."""
    from cnc_twin.run.signals import Interrupted, SignalGuard

    namespace: dict = {}
    exec(compile("import sys\ndef cb():\n    return sys._getframe()\n", "<frozen importlib._bootstrap>", "exec"),
         namespace)
    frame = namespace["cb"]()  # a frame as importlib's callback has it

    guard = SignalGuard()
    guard._handle(signal.SIGTERM, frame)  # no Interrupted raised
    assert guard.received == "SIGTERM"
    target = StopTarget()
    with guard.stopping(target):
        assert target.stopped == "SIGTERM"
    with pytest.raises(Interrupted):  # anywhere else before the run: the interruption itself
        SignalGuard()._handle(signal.SIGINT, sys._getframe())


def test_a_signal_while_a_first_run_compiles_ends_it_at_once(tmp_path, scenario):
    """Seen in CI: SIGINT during a fresh install's first run, while numba compiled the twin's
    kernels (half a minute, minutes on a loaded machine), was only acted on after the compiling.
    The run has not begun then: the signal ends the command at once, nothing written. An empty
    numba cache (NUMBA_CACHE_DIR) makes this run a first one; the signal goes once the command
    says it is compiling. Bound: 20 s, well under what the compiling alone takes (28 s idle)."""
    before = set(leftover_segments())
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba_cache"))
    proc = _start(tmp_path / "cold", scenario, env=env)
    for line in proc.stderr:
        if "compiling" in line:
            break
    else:
        pytest.fail(f"the command never said it was compiling (exit {proc.wait()})")
    proc.send_signal(signal.SIGINT)
    sent = time.monotonic()
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()  # its group is reaped by _outcome below
        pytest.fail("the command was still compiling 20 s after SIGINT")
    finally:
        took = time.monotonic() - sent
        assert _outcome(proc, tmp_path / "cold", before) == "nothing"
    assert proc.returncode == 130, (proc.returncode, took)


def test_a_signal_before_a_twin_has_begun_is_the_interruption():
    """Within :meth:`SignalGuard.stopping`, a target whose ``begun`` is still False (compiling,
    starting its planner) is not asked to stop: the signal raises Interrupted. Once it has begun,
    the signal asks it to stop and raises nothing."""
    from cnc_twin.run.signals import Interrupted, SignalGuard

    target, guard = StopTarget(begun=False), SignalGuard()
    with pytest.raises(Interrupted), guard.stopping(target):
        guard._handle(signal.SIGINT, sys._getframe())
    assert target.stopped is None
    target, guard = StopTarget(begun=True), SignalGuard()
    with guard.stopping(target):
        guard._handle(signal.SIGTERM, sys._getframe())
    assert target.stopped == "SIGTERM"


def test_an_interruption_python_can_only_drop_is_not_printed_and_stops_the_twin(capsys):
    """Seen in CI: SIGINT while numba compiled, inside llvmlite's object-cache callback (C calling
    back into Python), where Python prints "Exception ignored ... Traceback" and drops the
    exception. Under the guard nothing is printed, and a twin still compiling is asked to stop
    (it stops at its first period: a whole run directory, marked interrupted). Reproduced with a
    finaliser, which Python drops the same way (sys.unraisablehook)."""
    import gc

    from cnc_twin.run.signals import SignalGuard

    guard, target = SignalGuard(), StopTarget(begun=False)

    class Finalised:
        def __del__(self):
            guard._handle(signal.SIGINT, sys._getframe())  # raises Interrupted inside __del__

    with guard, guard.stopping(target):
        Finalised()
        gc.collect()
    assert guard.received == "SIGINT" and target.stopped == "SIGINT"
    assert capsys.readouterr().err == ""
    assert sys.unraisablehook != guard._unraisable  # the hook before the guard is back


def test_the_debris_of_an_interruption_is_not_printed_after_the_guard(capsys):
    """Seen in CI (newest llvmlite): SIGINT while numba compiled left an llvmlite object half built,
    and its finaliser failed with AttributeError as the process ended, after the guard: Python
    printed "Exception ignored ... Traceback" below the command's one line. A guard whose process
    ends next (restore=False) keeps its hook after an interruption, and the hook drops what
    follows a signal; without a signal, an error in a finaliser is still reported."""
    import gc

    from cnc_twin.run.signals import SignalGuard

    class Broken:
        def __del__(self):
            raise AttributeError("half built")

    before, reported = sys.unraisablehook, []
    try:
        sys.unraisablehook = lambda report: reported.append(str(report.exc_value))  # as Python's prints
        quiet = SignalGuard(restore=False)
        with pytest.raises(BaseException):  # the interruption
            with quiet:
                quiet._handle(signal.SIGINT, sys._getframe())
        Broken()
        gc.collect()
        assert reported == [] and capsys.readouterr().err == ""
        sys.unraisablehook = lambda report: reported.append(str(report.exc_value))
        with SignalGuard(restore=False):
            Broken()
            gc.collect()
        assert reported == ["half built"]  # no signal: reported to the hook that was in place
    finally:
        sys.unraisablehook = before
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def test_an_error_after_the_signal_is_the_interruption():
    """Seen in CI: the dropped interruption had cut numba's object-code callback short, and numba
    then failed to cache the function ("no compiled object yet"). An error that comes after the
    signal, without it in its chain, ends the command as the interruption (one line, 130), not
    as a traceback; before any signal the error is the error."""
    from cnc_twin.run.signals import Interrupted, SignalGuard

    with pytest.raises(RuntimeError):
        with SignalGuard():
            raise RuntimeError("no signal: a bug is a bug")
    guard = SignalGuard()
    with pytest.raises(Interrupted):
        with guard:
            guard.received = "SIGINT"  # as _handle notes it where it cannot raise
            raise RuntimeError("no compiled object yet")

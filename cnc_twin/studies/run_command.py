"""``cnc-twin run`` and ``cnc-twin serve``: one run, from the command line to its run directory.

The run directory is claimed (made, empty) as soon as the scenario is read, so a second run on the
same name is refused at once; before the clock starts, the folder must have room for what the run
will write (:func:`~cnc_twin.run.run_dir.check_room`); a write that still fails keeps
``metrics.json`` with the run's status and why, removes what is partial, and ends the command with
:data:`~cnc_twin.core.errors.EXIT_RESOURCE`. SIGINT / SIGTERM: nothing left behind before the run
begins, the run written whole (marked interrupted) after (:mod:`cnc_twin.run.signals`).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from cnc_twin.core.errors import EXIT_FAULT, EXIT_OK, ResourceError, ScenarioError
from cnc_twin.core.phases import mark
from cnc_twin.run.run_claim import taken
from cnc_twin.run.signals import SignalGuard, exit_code
from cnc_twin.scenario.resources import BUNDLED_MACHINES, default_scenario


def run_command(args: argparse.Namespace) -> int:
    """``cnc-twin run`` or ``serve`` (``args.command``) with the parsed ``args``: its exit status."""
    with SignalGuard(restore=not args.whole_process) as guard:
        return _run_guarded(args, guard)


def _beside(path: Path, scenario: Path) -> str:
    """``path`` as the scenario names a file: its bare name where it lies in the scenario's (or
    program's) folder (the run directory then keeps it beside the program), else absolute."""
    path, folder = path.resolve(), scenario.resolve().parent
    return path.name if path.parent == folder else str(path)


def _check_destinations(args: argparse.Namespace) -> None:
    """Where the run and its recording will be written, checked before any process starts or
    anything runs: a run's work is never lost to a folder that cannot be written, and a mistyped
    path costs a fraction of a second, not a run's start."""
    if args.rrd is not None and not args.rrd.parent.is_dir():
        raise ScenarioError(args.rrd, "", "--rrd: the folder for the recording does not exist")
    check_writable_parent(args.out if args.out is not None else args.runs_dir / "run", "--out" if args.out else "--runs-dir")
    if args.out is not None and taken(args.out):
        raise ScenarioError(args.out, "", "run directory already exists; choose another --out")
    attach = getattr(args, "attach", None)
    if attach is not None and (attach.exists() or attach.is_symlink() or not attach.parent.is_dir()):
        raise ScenarioError(attach, "", "--attach: must be a new folder (the twin makes it) in an existing one")


def _run_guarded(args: argparse.Namespace, guard: SignalGuard) -> int:
    _check_destinations(args)
    from cnc_twin.planner.launch import PlannerPool

    # The planner process and the recording process start first: their start-up (0.2 - 0.6 s,
    # about 1 s) overlaps the imports below.
    from cnc_twin.view.viewer import display_available

    if args.rerun and not display_available():
        # A viewer cannot open here, and the recording would wait ~10 s for it to connect.
        print("warning: --rerun: no display (DISPLAY and WAYLAND_DISPLAY unset), no viewer opened; "
              "serve the run to a browser afterwards with `cnc-twin view RUN_DIR --web`", file=sys.stderr)
        args.rerun = False
    if args.command == "serve":  # the PC side is the user's program, which attaches by itself
        from cnc_twin.run.external_pc import ExternalPc

        planners = ExternalPc(args.attach, announce=_say_where_to_attach)
    else:
        planners = PlannerPool()
        planners.prestart()
    with planners:
        recorder = None
        if not args.no_rrd or args.rrd is not None or args.rerun:
            from cnc_twin.view.rerun_stream import RecordingProcess

            recorder = RecordingProcess()
        try:
            return _run_with(args, planners, recorder, guard)
        finally:
            if recorder is not None:
                recorder.close()


def _say_where_to_attach(folder: Path) -> None:
    """The line a served run's PC program (or the script that starts it) waits for: its attach folder."""
    print(f"attach: {folder}", flush=True)


def _run_with(args: argparse.Namespace, planners, recorder, guard: SignalGuard) -> int:
    """One run; ``recorder`` (a :class:`~cnc_twin.view.rerun_stream.RecordingProcess`, or None when
    no recording is wanted) records it while it runs."""
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.run.run_claim import claim_run_dir, release_run_dir
    from cnc_twin.run.run_dir import new_run_dir  # the scenario's config, pyarrow...: after the helpers started

    mark("imported")

    source = args.scenario or default_scenario()
    overrides = dict(BUNDLED_MACHINES[args.machine]) if args.machine is not None else {}
    if args.tool_table is not None:  # as the scenario key would say it (a G-code program's)
        overrides.update({"program.tool_table": _beside(args.tool_table, source), "program.tool_units": args.tool_units})
    if args.in_air is not None:
        overrides["program.in_air"] = args.in_air
    if getattr(args, "replay", None) is not None:
        overrides["planner.replay"] = _beside(args.replay, source)
    if getattr(args, "wait", None) is not None:
        overrides["planner.start_timeout"] = args.wait
    if args.subroutine_path:  # as the scenario key would say it (a G-code program's)
        overrides["program.subroutine_path"] = [_beside(folder, source) for folder in args.subroutine_path]
    scenario = load_scenario(source, overrides=overrides or None)
    mark("loaded")
    # claimed now (made, empty): a second run on the same name is refused at once, not after its run
    try:
        run_dir = claim_run_dir(args.out) if args.out else new_run_dir(args.runs_dir, scenario.name, claim=True)
    except FileExistsError:
        raise ScenarioError(args.out, "", "run directory already exists; choose another --out") from None
    try:
        return _run_claimed(args, scenario, source, run_dir, planners, recorder, guard)
    finally:
        release_run_dir(run_dir)  # still empty: the run never got written (an error, a signal)


def _run_claimed(args: argparse.Namespace, scenario, source: Path, run_dir: Path, planners, recorder,
                 guard: SignalGuard) -> int:
    from cnc_twin.run.run_dir import check_room
    from cnc_twin.run.twin import Twin

    twin = Twin(scenario)
    mark("twin")
    twin.trace_file = run_dir.parent / f".{run_dir.name}.trace-{os.getpid()}.parquet"  # a long run's, moved in
    for notice in twin.notices:  # before any motion, once (metrics.json keeps them too)
        print(f"note: {source}: {notice}", file=sys.stderr)
    from cnc_twin.run.progress import ProgressBar

    # no progress bar (not a terminal): one line says when the run has begun (compiled, planner started)
    bar = ProgressBar(scenario.name, period=scenario.timing.interpolation_period,
                      stream=None if not args.quiet else NullStream(),
                      start_line=f"{scenario.name}: running ({scenario.timing.mode}) ...")
    # The recording goes to the run directory (staged beside it, moved in when the run is
    # written), or only to --rrd with --no-rrd; --rerun also shows it live in a viewer.
    staged = None
    if recorder is not None:
        if args.no_rrd:
            target = args.rrd
        else:
            run_dir.parent.mkdir(parents=True, exist_ok=True)
            target = staged = run_dir.parent / f".{run_dir.name}.recording-{os.getpid()}.rrd"
        recorder.open(scenario, rrd=target, spawn=args.rerun)
    # before the clock starts, once the program's length is known: room for what the run writes
    twin.before_clock = lambda planned: check_room(run_dir, twin, planned, recording=staged is not None)
    try:
        return _run_and_write(args, twin, bar, run_dir, recorder, staged, planners, guard)
    finally:
        if staged is not None:  # not moved in (still there): the run stopped with an error
            recorder.close()  # first: a signal before the run began can find it still creating the file
            _remove(staged)
        _remove(twin.trace_file)  # likewise


def _run_and_write(args, twin, bar, run_dir: Path, recorder, staged: Path | None, planners,
                   guard: SignalGuard) -> int:
    with guard.stopping(twin):
        if not args.quiet and twin.kernel is not None:
            from cnc_twin.run.period_kernel import kernels_cached

            if not kernels_cached():
                print("compiling the twin's kernels for this machine (once after installing, about 15 s) ...",
                      file=sys.stderr, flush=True)
        result = twin.run(progress=bar, planners=planners, observer=None if recorder is None else recorder.observe)
    with guard.deferred():  # a signal now is noted: the run directory is written whole first
        try:
            _write(args, result, run_dir, recorder, staged)
        except OSError as exc:  # disk full, read-only, removed...: what could be kept is, and why
            from cnc_twin.run.run_dir import keep_after_failed_write

            if staged is not None:  # partial files first: their room may hold metrics.json
                recorder.close()
                _remove(staged)
            _remove(twin.trace_file)
            raise ResourceError(run_dir, keep_after_failed_write(run_dir, result.metrics, exc)) from None
    mark("written")
    # read once: a signal after this only ends the command's printing, the run being whole and marked
    signalled = twin.stop_reason or guard.received
    if signalled is not None and twin.stop_reason is None:  # it came while writing
        from cnc_twin.run.run_dir import mark_interrupted

        mark_interrupted(run_dir, result.metrics, f"{signalled} while the run directory was written "
                                                  "(the run had ended; everything in it is whole)")
    if not args.quiet:
        from cnc_twin.run.summary import summary_table

        print(summary_table(result.metrics))
    print(f"run directory: {run_dir}")
    if signalled is not None:
        print(f"interrupted by {signalled} at {result.metrics['sim_time_s']:.3f} s simulated; the run directory "
              "holds everything recorded up to then", file=sys.stderr)
        return exit_code(signalled)
    if result.status == "fault":
        fault = result.metrics["fault"]
        rest = fault.get("at_rest_s")
        stop = f"{fault['stop']} stop" + (f", at rest at {rest:.3f} s" if rest is not None else ", not yet at rest")
        print(f"fault {fault['code']} at {fault['time_s']:.3f} s ({stop}): {fault['message']}", file=sys.stderr)
        return EXIT_FAULT
    return EXIT_OK


def _write(args, result, run_dir: Path, recorder, staged: Path | None) -> None:
    """The run directory (with the recording, when one was made), and the ``--rrd`` copy."""
    if recorder is None:  # neither the run directory nor --rrd nor --rerun wants a recording
        result.write(run_dir, recording=False, claimed=True)
    else:
        # The recording process closes the recording while this process writes the trace.
        recorder.hand_over(result)

        def finished_recording() -> Path | None:
            from cnc_twin.view.rerun_stream import RecordingError

            try:
                return recorder.wait()
            except RecordingError as exc:  # the run is whole: export it here instead
                print(f"warning: {exc}; exporting the recording after the run instead", file=sys.stderr)
                if args.no_rrd and args.rrd is not None:
                    result.export_rerun(rrd=args.rrd)
                return None

        if staged is not None:
            result.write(run_dir, recording=finished_recording, claimed=True)
        else:  # --no-rrd: the recording went to --rrd and/or a viewer only
            result.write(run_dir, recording=False, claimed=True)
            finished_recording()
    if args.rrd is not None and not args.no_rrd:
        import shutil

        from cnc_twin.run.run_dir import RECORDING_FILE

        shutil.copyfile(run_dir / RECORDING_FILE, args.rrd)


def check_writable_parent(path: Path, option: str) -> None:
    """Refuse (exit 2) a ``path`` whose folder cannot be created or written into: the folder is
    made (as the run would make it) and a file is created and removed in it."""
    import tempfile

    parent = path.absolute().parent
    if parent.exists() and not parent.is_dir():
        raise ScenarioError(path, "", f"{option}: {parent} is a file, not a folder")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=parent, prefix=".cnc-twin-write-check-"):
            pass
    except OSError as exc:
        raise ScenarioError(path, "", f"{option}: cannot write in {parent}: {exc.strerror or exc}") from None


class NullStream:
    """Where a quiet run's progress goes."""

    def write(self, _text: str) -> None:
        pass

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


def _remove(path: Path) -> None:
    """Remove a staged file if it is there (on a folder turned read-only it stays: the one-line
    error says so already)."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass

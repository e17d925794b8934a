"""``cnc-twin`` command line: run | view | validate | tune | sweep | bench | gcode | list | server.

Exit codes: 0 ok; 2 bad input (one line on stderr naming file and key); 3 the run ended by a
fault (the run directory is complete and says which); 130 interrupted by SIGINT (Ctrl-C), 143 by
SIGTERM. An interrupted run stops at the next interpolation period and
still writes its run directory, marked ``"status": "interrupted"`` in ``metrics.json``.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path

from cnc_twin.core.errors import ScenarioError
from cnc_twin.core.phases import mark
from cnc_twin.run.signals import Interrupted, SignalGuard, Terminated, exit_code, interruption_in, terminate
from cnc_twin.scenario.resources import BUNDLED_MACHINES, bundled_tool_table, default_scenario, folder_list, input_path

EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_FAULT = 3
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143
EXIT_BROKEN_PIPE = 128 + signal.SIGPIPE
SUB_HELP = "folders of an NC program's subroutine files (o<name> call: name.ngc), after its own (SUBROUTINE_PATH)"
"""the reader of stdout went away (``cnc-twin gcode part.ngc --canon | head``): the status a C
tool killed by SIGPIPE ends with"""


class _Parser(argparse.ArgumentParser):
    """argparse that exits with 2 and one line, like every other input error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: {message}\n")


def _run_options(parser: argparse.ArgumentParser) -> None:
    """The options ``run`` and ``serve`` share: the scenario, where the run goes, what it shows."""
    parser.add_argument("scenario", nargs="?", type=input_path,
                        help="scenario YAML or NC program (.ngc): a path, or a bundled one by name (cnc-twin list); "
                             "default: jog_axes")
    parser.add_argument("--out", type=Path, default=None,
                        help="run directory to create (default: runs/<name>-<UTC time>)")
    parser.add_argument("--runs-dir", type=Path, default=Path("runs"), help="parent of the default run directory")
    parser.add_argument("--quiet", action="store_true", help="no progress bar and no summary table")
    parser.add_argument("--rerun", action="store_true", help="show the run in a spawned rerun viewer as it runs")
    parser.add_argument("--rrd", type=Path, default=None, help="also save the rerun recording to this path")
    parser.add_argument("--no-rrd", action="store_true", help="do not write recording.rrd into the run directory")
    parser.add_argument("--tool-table", type=Path, default=None,
                        help="an NC program's LinuxCNC tool table, for G43 H (a scenario's program.tool_table)")
    parser.add_argument("--tool-units", choices=("mm", "inch"), default="mm", help="the tool table's length unit")
    parser.add_argument("--subroutine-path", type=folder_list, default=(), metavar="DIR[:DIR]", help=SUB_HELP)
    parser.add_argument("--in-air", type=float, default=None, metavar="MM",
                        help="prove an NC program in the air: run it this far above where it is written, the pad never "
                             "reaching the work (a scenario's program.in_air)")
    parser.add_argument("--machine", choices=list(BUNDLED_MACHINES), default=None,
                        help="run on this bundled machine instead of the one the scenario names (its model and "
                             "parameter file; the scenario's own axes: keys still apply)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="cnc-twin", description="Digital twin of a six-axis PC + DSP polishing machine.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="run a scenario and write a run directory")
    serve = sub.add_parser("serve", help="run a scenario with your own PC program as the card's PC side")
    for parser_ in (run, serve):
        _run_options(parser_)
    run.add_argument("--replay", type=Path, default=None, metavar="PC_STREAM",
                     help="the PC side writes this recorded stream again (a served run's pc_stream.bin) instead of "
                          "the twin's planner planning the program (a scenario's planner.replay)")
    serve.add_argument("--attach", type=Path, default=None, metavar="DIR",
                       help="make the attach folder your program opens here (default: a new one in the temporary "
                            "directory, printed)")
    serve.add_argument("--wait", type=float, default=None, metavar="S",
                       help="how long to wait for the program to attach [s] (default: the scenario's "
                            "planner.start_timeout, 60)")

    sweep = sub.add_parser("sweep", help="run a scenario over a grid (or random set) of overrides")
    sweep.add_argument("scenario", type=input_path, help="scenario: a path, or a bundled one by name")
    sweep.add_argument("--param", action="append", required=True,
                       help="PATH=start:stop:step | PATH=a,b,c | PATH=value (repeatable), e.g. servo.X.kp=20:80:20")
    sweep.add_argument("--random", type=int, default=None, help="draw N random cases within the ranges instead")
    sweep.add_argument("--seed", type=int, default=0, help="seed for --random")
    sweep.add_argument("--workers", type=int, default=None, help="local worker processes (default 2)")
    sweep.add_argument("--scheduler", default=None, help="Dask scheduler address (default: local processes)")
    sweep.add_argument("--out", type=Path, default=None, help="folder for sweep.parquet and sweep.csv")
    sweep.add_argument("--yes", action="store_true", help="run a sweep of more than 1000 cases without asking")
    sweep.add_argument("--minimize", default=None,
                       help="column to pick the best row by (default contour_rms_um for curves, else ferr_rms_xyz_mm)")

    tune = sub.add_parser("tune", help="propose an axis's PID gains from its linear loop and check them")
    tune.add_argument("scenario", type=input_path, help="scenario: a path, or a bundled one by name")
    tune.add_argument("--axis", required=True, choices=list("XYZABC"))
    tune.add_argument("--phase-margin", type=float, default=45.0, help="[deg]")
    tune.add_argument("--gain-margin", type=float, default=6.0, help="[dB]")
    tune.add_argument("--step", type=float, default=1.0, help="verification step [mm | deg]")
    tune.add_argument("--out", type=Path, default=None, help="folder for the Bode and step plots (PNG)")
    tune.add_argument("--machine", choices=list(BUNDLED_MACHINES), default=None,
                      help="tune on this bundled machine instead of the one the scenario names")

    view = sub.add_parser("view", help="open a run directory's recording in the rerun viewer")
    view.add_argument("run_dir", type=Path, help="a run directory, or a .rrd recording")
    view.add_argument("--web", action="store_true",
                      help="serve the run to a browser on this machine instead (no display needed)")
    view.add_argument("--port", type=int, default=9090, help="--web: the web viewer's port on 127.0.0.1")

    sub.add_parser("list", help="list the bundled scenarios and NC programs, which run by name from anywhere")

    validate = sub.add_parser("validate", help="check scenario files without running them")
    validate.add_argument("scenarios", nargs="+", type=input_path, help="scenarios: paths, or bundled ones by name")

    gcode = sub.add_parser("gcode", help="read an NC program as LinuxCNC reads it and list what it makes")
    gcode.add_argument("program", type=input_path, help="RS274/NGC program (.ngc): a path, or a bundled one by name")
    gcode.add_argument("--canon", action="store_true", help="print the canonical calls as LinuxCNC's rs274 -g prints them")
    gcode.add_argument("--tool-table", type=Path, default=None, help="LinuxCNC tool table (default: the machine's)")
    gcode.add_argument("--tool-units", choices=("mm", "inch"), default="mm", help="the tool table's length unit")
    gcode.add_argument("--subroutine-path", type=folder_list, default=(), metavar="DIR[:DIR]", help=SUB_HELP)
    gcode.add_argument("--max-calls", type=int, metavar="N", help="calls before a program counts as endless (2000000)")

    bench = sub.add_parser("bench", help="twin wall time against bare MuJoCo stepping, in one process")
    bench.add_argument("scenario", nargs="?", type=input_path,
                       help="scenario: a path, or a bundled one by name (default: jog_axes)")
    bench.add_argument("--repeat", type=int, default=3, help="measurements of each side; the best counts")
    bench.add_argument("--json", type=Path, default=None, help="also write the figures to this JSON file")
    bench.add_argument("--no-whiteboard", action="store_true",
                       help="skip the whiteboard figures (exchange round trip, streaming throughput)")
    bench.add_argument("--machine", choices=list(BUNDLED_MACHINES), default=None,
                       help="measure on this bundled machine instead of the one the scenario names")
    bench.add_argument("--startup", action="store_true",
                       help="time whole `cnc-twin run` and `validate` processes beside the floor (python importing "
                            "numpy, mujoco, numba), with where the time outside the run went; the scenarios: the one "
                            "given, or jog_axes, nurbs_circle, gcode_cam_raster and freeform_polish")

    server = sub.add_parser("server", help="the warm server that runs run, validate, gcode and list without a new "
                                           "interpreter's start-up: its state, or start or stop it")
    what = server.add_mutually_exclusive_group()
    what.add_argument("--start", action="store_true", help="start one for this environment now; wait until ready")
    what.add_argument("--stop", action="store_true", help="end this installation's servers (their commands finish)")
    return parser


QUICK_EXIT = ("run", "serve", "validate", "gcode", "list")
"""commands that, run as the program, end without the interpreter's teardown once they are done
(their files closed, their helper processes ended): freeing every module's objects costs a run
0.3 - 0.7 s after its last file is written"""


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    args.whole_process = argv is None  # run as the program (not called from Python): see SignalGuard
    code = _main(args)
    if args.whole_process and args.command in QUICK_EXIT:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (BrokenPipeError, OSError):  # the reader is gone: nothing more to tell it
                pass
        os._exit(code)
    return code


def _main(args: argparse.Namespace) -> int:
    handlers = {"run": _run, "serve": _run, "validate": _validate, "bench": _bench, "view": _view, "sweep": _sweep, "tune": _tune,
                "gcode": _gcode, "list": _list, "server": _server}
    if args.whole_process and args.command not in ("run", "serve", "sweep"):
        # The start handlers (cnc_twin/entry.py) end the program at once; from here Ctrl-C is a KeyboardInterrupt
        # and SIGTERM ends these commands as Ctrl-C does: through the runs' cleanup (planners, shared memory).
        # run and sweep keep the start handlers until their SignalGuard takes over (nothing to clean before).
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, terminate)
    try:
        try:
            return handlers[args.command](args)
        except ImportError as exc:
            # a signal while an extension module initialises (mujoco, numpy...) surfaces as that
            # import failing, the interruption its cause: it is the interruption
            cause = interruption_in(exc)
            if cause is None:
                raise
            raise cause from None
    except ScenarioError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Interrupted as exc:
        print(f"interrupted by {exc.name} before the run began; nothing was written", file=sys.stderr)
        return exit_code(exc.name)
    except Terminated:
        print("terminated (SIGTERM)", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # The reader took what it wanted: end quietly. Python's flush of stdout at exit would raise again: to /dev/null
        if args.whole_process:
            with open(os.devnull, "w") as devnull:
                os.dup2(devnull.fileno(), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


def _list(args: argparse.Namespace) -> int:
    from cnc_twin.scenario.catalogue import catalogue_lines

    print("\n".join(catalogue_lines()))
    return EXIT_OK


def _run(args: argparse.Namespace) -> int:
    # SIGINT / SIGTERM from here on: nothing left behind before the run begins, the run written
    # whole (marked interrupted) after (cnc_twin/run/signals.py)
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
    if args.out is not None and args.out.exists():
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
    from cnc_twin.run.run_dir import new_run_dir  # the scenario's config (numpy...): not for gcode / list
    from cnc_twin.run.twin import Twin

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
    run_dir = args.out or new_run_dir(args.runs_dir, scenario.name)
    if run_dir.exists():
        raise ScenarioError(run_dir, "", "run directory already exists; choose another --out")
    twin = Twin(scenario)
    mark("twin")
    twin.trace_file = run_dir.parent / f".{run_dir.name}.trace-{os.getpid()}.parquet"  # a long run's, moved in
    for notice in twin.notices:  # before any motion, once (metrics.json keeps them too)
        print(f"note: {source}: {notice}", file=sys.stderr)
    from cnc_twin.run.progress import ProgressBar

    # no progress bar (not a terminal): one line says when the run has begun (compiled, planner started)
    bar = ProgressBar(scenario.name, period=scenario.timing.interpolation_period,
                      stream=None if not args.quiet else _NullStream(),
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
    try:
        return _run_and_write(args, twin, bar, run_dir, recorder, staged, planners, guard)
    finally:
        if staged is not None:  # not moved in (still there): the run stopped with an error
            recorder.close()  # first: a signal before the run began can find it still creating the file
            staged.unlink(missing_ok=True)
        twin.trace_file.unlink(missing_ok=True)  # likewise


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
        _write(args, result, run_dir, recorder, staged)
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
        result.write(run_dir, recording=False)
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
            result.write(run_dir, recording=finished_recording)
        else:  # --no-rrd: the recording went to --rrd and/or a viewer only
            result.write(run_dir, recording=False)
            finished_recording()
    if args.rrd is not None and not args.no_rrd:
        import shutil

        from cnc_twin.run.run_dir import RECORDING_FILE

        shutil.copyfile(run_dir / RECORDING_FILE, args.rrd)


def _sweep(args: argparse.Namespace) -> int:
    from cnc_twin.studies.sweep_command import sweep_command

    return sweep_command(args)


def _tune(args: argparse.Namespace) -> int:
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.studies.tune_command import tune_axis
    from cnc_twin.studies.tuning import check_margins

    try:
        check_margins(args.phase_margin, args.gain_margin)
    except ValueError as exc:
        raise ScenarioError(args.scenario, "", str(exc)) from None
    overrides = dict(BUNDLED_MACHINES[args.machine]) if args.machine is not None else None
    tune_axis(args.scenario, load_scenario(args.scenario, overrides=overrides), args.axis,
              phase_margin=args.phase_margin, gain_margin=args.gain_margin, step=args.step, out=args.out,
              overrides=overrides)
    return EXIT_OK


def _view(args: argparse.Namespace) -> int:
    import subprocess

    from cnc_twin.run.run_dir import RECORDING_FILE

    from cnc_twin.view.viewer import display_available, rerun_command, serve_web, viewer_environment

    path = args.run_dir / RECORDING_FILE if args.run_dir.is_dir() else args.run_dir
    if not path.is_file():
        raise ScenarioError(path, "", "no rerun recording here (runs write recording.rrd unless --no-rrd)")
    if args.web:
        return serve_web(path, args.port)
    if not display_available():
        raise ScenarioError(args.run_dir, "", "no display to open the viewer on (DISPLAY and WAYLAND_DISPLAY "
                            f"unset); serve it to a browser with `cnc-twin view {args.run_dir} --web`, or open "
                            f"{path} with `rerun` on a machine with a display")
    with viewer_environment() as env:
        return subprocess.call(rerun_command() + [str(path)], env=env)


def _validate(args: argparse.Namespace) -> int:
    from cnc_twin.run.program_kinds import kind_of
    from cnc_twin.scenario.load import load_scenario

    mark("imported")
    # every file is checked and each bad one reported, so one pass finds all of them
    bad = 0
    for path in args.scenarios:
        try:
            scenario = load_scenario(path)
            mark("loaded")
        except ScenarioError as exc:
            print(f"error: {exc}", file=sys.stderr)
            bad += 1
            continue
        print(f"{path}: ok ({scenario.name}, {kind_of(scenario.program).describe(scenario.program)})")
    if bad and len(args.scenarios) > 1:
        print(f"{bad} of {len(args.scenarios)} scenarios refused", file=sys.stderr)
    return EXIT_BAD_INPUT if bad else EXIT_OK


def _gcode(args: argparse.Namespace) -> int:
    from cnc_twin.gcode.listing import LineWriter, list_program

    out = LineWriter(sys.stdout)  # a long program's listing written as it is read, never held
    lines, error = list_program(args.program, args.tool_table or bundled_tool_table(),  # as run reads them
                                args.tool_units if args.tool_table else "mm", args.canon, args.subroutine_path,
                                max_calls=args.max_calls, out=out)
    out.finish(lines)
    code = EXIT_OK if not error else EXIT_BAD_INPUT
    if error:
        print(f"error: {error}", file=sys.stderr)
    return code  # run as the program, it ends without the teardown freeing every call (QUICK_EXIT)


def _server(args: argparse.Namespace) -> int:
    from cnc_twin.core.server_control import server_command

    return server_command(start=args.start, stop=args.stop)


def _bench(args: argparse.Namespace) -> int:
    from cnc_twin.studies.bench_command import bench_command

    return bench_command(args)


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


class _NullStream:
    def write(self, _text: str) -> None:
        pass

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False

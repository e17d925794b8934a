"""``cnc-twin`` command line: run | view | validate | tune | sweep | bench | gcode | list | schema | server.

Exit codes: 0 ok; 2 bad input (one line on stderr naming file and key); 3 the run ended by a
fault (the run directory is complete and says which); 4 the machine could not give the run what it
needs (disk space, shared memory: one line; what could be kept is); 130 interrupted by SIGINT (Ctrl-C), 143 by
SIGTERM. An interrupted run stops at the next interpolation period and
still writes its run directory, marked ``"status": "interrupted"`` in ``metrics.json``.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path

from cnc_twin.core.errors import EXIT_BAD_INPUT, EXIT_OK, EXIT_RESOURCE, ResourceError, ScenarioError
from cnc_twin.core.phases import mark
from cnc_twin.run.signals import Interrupted, Terminated, exit_code, interruption_in, terminate
from cnc_twin.scenario.resources import BUNDLED_MACHINES, bundled_tool_table, folder_list, input_path

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
    """The ``cnc-twin`` command line: its subcommands and their options."""
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
                       help="column to pick the best row by (default ballbar_G_um for a circular test, contour_rms_um "
                            "for curves, else ferr_rms_xyz_mm)")

    tune = sub.add_parser("tune", help="propose an axis's PID gains from its linear loop and check them")
    tune.add_argument("scenario", type=input_path, help="scenario: a path, or a bundled one by name")
    tune.add_argument("--axis", required=True, choices=list("XYZABC"))
    tune.add_argument("--phase-margin", type=float, default=45.0, help="[deg]")
    tune.add_argument("--gain-margin", type=float, default=6.0, help="[dB]")
    tune.add_argument("--step", type=float, default=1.0, help="verification step [mm | deg]")
    tune.add_argument("--out", type=Path, default=None, help="folder for the Bode and step plots (PNG)")
    tune.add_argument("--machine", choices=list(BUNDLED_MACHINES), default=None,
                      help="tune on this bundled machine instead of the one the scenario names")

    commission = sub.add_parser("commission", help="commission a machine parameter file on the circular tests: "
                                                   "matched dynamics, feed-forward, the tip's deflection, reversal and "
                                                   "backlash compensation, a report")
    commission.add_argument("parameters", nargs="?", type=Path, default=None,
                            help="machine parameter file (default: the bundled polisher_uncommissioned.yaml)")
    commission.add_argument("--out", type=Path, default=None,
                            help="folder for the commissioned file, report.md and the polar plots "
                                 "(default runs/commission-<UTC time>)")

    view = sub.add_parser("view", help="open a run directory's recording in the rerun viewer")
    view.add_argument("run_dir", type=Path, help="a run directory, or a .rrd recording")
    view.add_argument("--web", action="store_true",
                      help="serve the run to a browser on this machine instead (no display needed)")
    view.add_argument("--port", type=int, default=9090, help="--web: the web viewer's port on 127.0.0.1")

    sub.add_parser("list", help="list the bundled scenarios and NC programs, which run by name from anywhere")

    schema = sub.add_parser("schema", help="write the JSON Schema of a scenario file, for editors' completion and "
                                           "checks as one types (scenarios/scenario.schema.json is its copy)")
    schema.add_argument("--out", type=Path, default=None, metavar="FILE", help="write it to FILE (default: stdout)")

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


QUICK_EXIT = ("run", "serve", "validate", "gcode", "list", "schema")
"""commands that, run as the program, end without the interpreter's teardown once they are done
(their files closed, their helper processes ended): freeing every module's objects costs a run
0.3 - 0.7 s after its last file is written"""


def main(argv: list[str] | None = None) -> int:
    """Run the ``cnc-twin`` command ``argv`` (None: this program's own arguments) and return its
    exit code."""
    args = build_parser().parse_args(argv)
    args.whole_process = argv is None  # run as the program (not called from Python): see SignalGuard
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the command as given, kept with bench's figures
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
                "commission": _commission,
                "gcode": _gcode, "list": _list, "schema": _schema, "server": _server}
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
    except ResourceError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_RESOURCE
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


def _schema(args: argparse.Namespace) -> int:
    from cnc_twin.scenario.json_schema import schema_text

    text = schema_text()
    if args.out is None:
        sys.stdout.write(text)
        return EXIT_OK
    try:
        args.out.write_text(text, encoding="ascii")
    except OSError as exc:  # no such folder, a folder of that name, no permission, disk full
        raise ScenarioError(args.out, "", f"--out: cannot write: {exc.strerror or exc}") from None
    return EXIT_OK


def _run(args: argparse.Namespace) -> int:
    from cnc_twin.studies.run_command import run_command

    return run_command(args)


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


def _commission(args: argparse.Namespace) -> int:
    from cnc_twin.studies.commission_command import commission_command

    return commission_command(args.parameters, args.out)


def _view(args: argparse.Namespace) -> int:
    import subprocess

    from cnc_twin.run.run_dir import RECORDING_FILE

    from cnc_twin.view.viewer import display_available, rerun_command, serve_web, viewer_environment

    path = args.run_dir / RECORDING_FILE if args.run_dir.is_dir() else args.run_dir
    if not path.is_file():
        raise ScenarioError(path, "", "no rerun recording here (runs write recording.rrd unless --no-rrd)")
    from cnc_twin.view.recording_check import check_recording

    check_recording(path)  # a damaged one is refused here, not shown as rerun's error in the viewer
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

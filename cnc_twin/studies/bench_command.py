"""``cnc-twin bench``: the twin against bare MuJoCo stepping in one process
(:mod:`cnc_twin.studies.bench`, with the whiteboard's figures), or with ``--startup`` whole
commands timed beside the floor (:mod:`cnc_twin.studies.bench_startup`)."""

from __future__ import annotations

import sys

from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.resources import BUNDLED_MACHINES, default_scenario


def bench_command(args) -> int:
    """``cnc-twin bench``: the figures printed (and written to ``--json``); the exit code."""
    if args.repeat < 1:
        raise ScenarioError("--repeat", "", f"expected a whole number >= 1, got {args.repeat}")
    if args.startup:
        return _startup(args)
    from cnc_twin.studies.bench import bench_scenario, format_bench

    scenario_file = args.scenario or default_scenario()
    print(f"bench: {scenario_file.name}, the twin and bare MuJoCo stepping, best of {args.repeat} each "
          "(compiling the kernels first if this is the first run) ...", file=sys.stderr, flush=True)
    overrides = dict(BUNDLED_MACHINES[args.machine]) if args.machine is not None else None
    figures = bench_scenario(scenario_file, repeat=args.repeat, overrides=overrides)
    if not args.no_whiteboard:
        from cnc_twin.studies.bench_whiteboard import whiteboard_figures

        figures.update(whiteboard_figures())
    print(format_bench(figures))
    _write_json(args, figures)
    return 0


def _startup(args) -> int:
    from cnc_twin.studies.bench_startup import SCENARIOS, bench_startup, format_startup

    scenarios = SCENARIOS if args.scenario is None else (args.scenario.stem,)
    if args.scenario is not None and args.scenario.parent.resolve() != default_scenario().parent.resolve():
        raise ScenarioError(args.scenario, "", "--startup measures bundled scenarios: give one by name")

    def said(text: str) -> None:
        print(f"\rbench --startup: {text:<60}", end="", file=sys.stderr, flush=True)

    figures = bench_startup(scenarios, repeat=args.repeat, progress=said)
    print(file=sys.stderr)
    print(format_startup(figures))
    _write_json(args, figures)
    return 0


def _write_json(args, figures: dict) -> None:
    """The figures as JSON at ``args.json`` (nothing when None), with what they were measured on
    under ``measured`` (:func:`~cnc_twin.studies.bench_context.measurement_context`)."""
    if args.json is None:
        return
    import json

    from cnc_twin.studies.bench_context import measurement_context

    record = {"measured": measurement_context(["cnc-twin", *args.argv]), **figures}
    args.json.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")

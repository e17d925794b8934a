"""``cnc-twin sweep``: a grid (or random draws) of overrides run on local processes or a Dask
cluster (:mod:`cnc_twin.studies.sweep`), stopped cleanly by SIGINT / SIGTERM."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from cnc_twin.core.errors import ScenarioError
from cnc_twin.run.signals import SignalGuard


def sweep_command(args) -> int:
    """``cnc-twin sweep``: the runs, their table written, the best printed; the exit code (0, or
    130 / 143 when SIGINT / SIGTERM stopped it: the finished runs still make the table)."""
    from contextlib import closing

    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.studies.sweep import (CONFIRM_CASES, DEFAULT_WORKERS, INTERRUPTED, MAX_CASES, best_row, case_count,
                                        cases, parse_param, run_dask, run_local, write_table)
    from cnc_twin.studies.sweep_stop import SweepStop

    params = []
    for text in args.param:
        try:
            params.append(parse_param(text))
        except ValueError as exc:
            raise ScenarioError("--param", text, str(exc)) from None
    count = case_count(params, random=args.random)
    workers = args.workers or DEFAULT_WORKERS
    sized_by = "--random" if args.random else "--param"
    if count < 1 or count > MAX_CASES:
        raise ScenarioError(sized_by, "", f"the sweep has {count} cases; expected 1 to {MAX_CASES}")
    if count > CONFIRM_CASES and not args.yes:
        raise ScenarioError(sized_by, "",
                            f"the sweep has {count} cases (about {count * 2.0 / 3600 / workers:.3g} h at 2 s a run on "
                            f"{workers} workers); pass --yes to run it, or narrow the ranges")
    print(f"sweep: {count} cases on {f'the Dask cluster {args.scheduler}' if args.scheduler else f'{workers} workers'}",
          file=sys.stderr, flush=True)
    todo = cases(params, random=args.random, seed=args.seed)
    # From here SIGINT and SIGTERM stop the sweep: the cases finished by then still make a table.
    with closing(SweepStop()) as stop, SignalGuard() as guard, guard.stopping(stop):
        for overrides in {tuple(sorted((k, type(v).__name__) for k, v in c.items())): c for c in todo}.values():
            load_scenario(args.scenario, overrides=overrides)  # bad paths or types fail here, before any run
        from cnc_twin.run.progress import ProgressBar

        bar = ProgressBar(f"sweep {args.scenario.stem}", period=1.0)
        started = time.perf_counter()
        if args.scheduler:
            rows = run_dask(str(args.scenario), todo, scheduler=args.scheduler, progress=bar, stop=stop)
        else:
            rows = run_local(str(args.scenario), todo, workers=args.workers, progress=bar, stop=stop)
        seconds = time.perf_counter() - started
        stamp = time.strftime('%Y%m%d-%H%M%S', time.gmtime())
        parquet, csv = write_table(rows, args.out or Path("runs") / f"sweep-{args.scenario.stem}-{stamp}")
    if stop.reason is not None:
        finished = sum(r.get("status") != INTERRUPTED for r in rows)
        newline = "\n" if bar.enabled else ""  # the progress bar's line is not finished
        print(f"{newline}interrupted ({stop.reason}) after {finished} of {len(rows)} runs; "
              f"partial table, the other runs marked {INTERRUPTED}: {parquet}, {csv}", file=sys.stderr)
        return 143 if stop.reason == "SIGTERM" else 130
    minimize = args.minimize or next((c for c in ("ballbar_G_um", "contour_rms_um") if any(c in r for r in rows)),
                                     "ferr_rms_xyz_mm")
    best = best_row(rows, minimize)
    lost = [r for r in rows if r.get("status") == "lost"]
    print(f"{len(rows)} runs in {seconds:.1f} s ({len(rows) / seconds * 60:.1f} runs/min); table: {parquet}, {csv}")
    if lost:
        print(f"lost runs: {len(lost)} ({', '.join(str({k: r[k] for k in (p.path for p in params)}) for r in lost)})")
    if best is not None:
        shown = {p.path: best[p.path] for p in params}
        print(f"best by {minimize}: {best[minimize]:.6g} with {shown}")
    return 0

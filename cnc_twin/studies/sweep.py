"""Parameter sweeps: many runs of one scenario with overrides, on local processes or a Dask cluster.

    cnc-twin sweep scenarios/jog_axes.yaml --param servo.X.kp=20:80:20 --param servo.X.ki=0,400

A parameter is ``PATH=start:stop:step`` (inclusive grid), ``PATH=a,b,c`` or ``PATH=value``;
paths are override paths (:mod:`cnc_twin.scenario.overrides`). The cases are the grid's cartesian
product, or ``random`` cases drawn uniformly within each parameter's range (seeded).

Each case is one complete twin run (its own planner process) in a worker process. Runs are
lockstep-deterministic, so the table does not depend on where or in which order cases ran
(wall-clock columns aside). A worker that dies takes its runs with it: they are retried once in
a fresh pool, then reported as ``lost``; the rest of the sweep completes.

A sweep stopped (:class:`~cnc_twin.studies.sweep_stop.SweepStop`: the CLI's SIGINT or SIGTERM)
starts no new case and stops the running ones at their next period; its table has every case,
those that did not finish with status ``interrupted``.
"""

from __future__ import annotations

import itertools
import math
import multiprocessing
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core.helpers import can_fork
from cnc_twin.studies.sweep_stop import (SweepStop, exit_on_sigterm, init_worker, sigint_held, stop_requested,
                                         stoppable)

WALL_CLOCK_COLUMNS = ("wall_time_s", "real_time_factor")
"""columns that vary from run to run of the same case"""
INTERRUPTED = "interrupted"
"""the status of a case that a stopped sweep did not finish"""
POLL_S = 0.2
"""how often the sweep's loop looks at its stop while cases run [s]"""


@dataclass(frozen=True)
class Param:
    """One swept parameter: an override path and its values (grid) or range (random)."""

    path: str
    values: tuple[Any, ...]

    @property
    def low(self) -> float:
        return float(min(self.values))

    @property
    def high(self) -> float:
        return float(max(self.values))


def parse_param(text: str) -> Param:
    """``"servo.X.kp=20:200:10"`` (inclusive), ``"a=1,2,5"`` or ``"a=3"``.

    Raises
    ------
    ValueError
        With a message saying what was expected.
    """
    if "=" not in text:
        raise ValueError(f"expected PATH=VALUES in {text!r}, e.g. servo.X.kp=20:200:10")
    path, spec = (part.strip() for part in text.split("=", 1))
    if not path or not spec:
        raise ValueError(f"expected PATH=VALUES in {text!r}")
    if ":" in spec:
        try:
            start, stop, step = (float(x) for x in spec.split(":"))
        except ValueError:
            raise ValueError(f"expected start:stop:step numbers in {text!r}") from None
        if step <= 0 or stop < start:
            raise ValueError(f"expected start <= stop and step > 0 in {text!r}")
        n = int(math.floor((stop - start) / step + 1e-9)) + 1
        if n > MAX_CASES:
            raise ValueError(f"{n} values in {text!r}; a sweep runs at most {MAX_CASES} cases")
        values = tuple(float(x) for x in np.round(start + step * np.arange(n), 12))
    else:
        values = tuple(_number(x.strip()) for x in spec.split(","))
    return Param(path=path, values=values)


def _number(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


DEFAULT_WORKERS = 2
"""local worker processes when none are asked for"""
MAX_CASES = 1_000_000
"""most cases a sweep runs (a larger grid is an error, not a week of computing)"""
CONFIRM_CASES = 1000
"""a sweep of more cases than this runs only when asked to (``--yes``)"""


def case_count(params: Sequence[Param], *, random: int | None = None) -> int:
    """How many cases :func:`cases` makes, without making them."""
    return int(random) if random else math.prod(len(p.values) for p in params)


def cases(params: Sequence[Param], *, random: int | None = None, seed: int = 0) -> list[dict[str, Any]]:
    """The sweep's override sets: grid product, or ``random`` uniform draws (seeded)."""
    if random:
        rng = np.random.default_rng(seed)
        return [{p.path: float(rng.uniform(p.low, p.high)) for p in params} for _ in range(random)]
    return [dict(zip((p.path for p in params), combo)) for combo in itertools.product(*(p.values for p in params))]


def flatten_metrics(metrics: dict[str, Any]) -> dict[str, Any]:
    """One flat row of a run's metrics, each figure's unit at the end of its name (:func:`column_unit`):
    following errors in mm or deg as the CLI prints them, path figures in um, force tracking in %
    of the setpoint and the removal map's figures for a polishing run, the circular test's G per
    direction and the larger (``ballbar_G_um``), the largest reversal spike per direction (signed:
    outward positive) and H for a circular test."""
    row: dict[str, Any] = {k: metrics.get(k) for k in ("status", "final_state", "sim_time_s", *WALL_CLOCK_COLUMNS)}
    linear_squares = 0.0
    for axis, fe in metrics["following_error"].items():
        row[f"ferr_max_{axis}_{fe['unit']}"] = fe["max"]
        row[f"ferr_rms_{axis}_{fe['unit']}"] = fe["rms"]
        if fe["unit"] == "mm":
            linear_squares += fe["rms"] ** 2
        row[f"dac_sat_{axis}_ticks"] = metrics["dac_saturation_ticks"][axis]
    # the RMS length of the X / Y / Z following-error vector: one figure of like units (never a
    # sum of millimetres and degrees)
    row["ferr_rms_xyz_mm"] = math.sqrt(linear_squares)
    path = metrics.get("path")
    if path and "contour_error_um" in path:
        row["contour_max_um"] = path["contour_error_um"]["max"]
        row["contour_rms_um"] = path["contour_error_um"]["rms"]
        row["feed_fluctuation_max"] = path["feed_fluctuation"]["max"]
    ballbar = metrics.get("ballbar")
    if ballbar:  # the circular test's figures, so a sweep over gains or compensations shows the trade-off
        directions = [d for d in ("ccw", "cw") if d in ballbar]
        for d in directions:
            f = ballbar[d]
            row[f"ballbar_G_{d}_um"] = f["circular_deviation_um"]
            row[f"ballbar_spike_{d}_um"] = max(f["reversal_spikes_um"].values(), key=abs)
        if directions:
            row["ballbar_G_um"] = max(ballbar[d]["circular_deviation_um"] for d in directions)
        row["ballbar_H_um"] = ballbar.get("hysteresis_um")
    polish = metrics.get("polish")
    if polish:
        force = polish.get("force") or {}  # None: a G-code program with a workpiece but no M100
        tracking = force.get("tracking") or {}
        row["force_rms_pct"] = tracking.get("rms_error_pct")
        row["force_max_pct"] = tracking.get("max_error_pct")
        row["force_overshoot_pct"] = (force.get("first_contact") or {}).get("overshoot_pct")
        row["reduced_feed_s"] = force.get("reduced_feed_s")
        removal = polish["removal"]
        row["removal_volume_mm3"] = removal["volume_mm3"]
        row["preston_by_hand_mm3"] = removal.get("preston_by_hand_mm3")
        band = removal.get("middle_band") or {}
        row["band_mean_um"] = band.get("mean_um")
        row["band_pv_um"] = band.get("pv_um")
    row["fault"] = (metrics.get("fault") or {}).get("code")
    return row


_WORKER_PLANNERS = None
"""the worker process's planner pool: its cases after the first reuse one planner process"""


def run_case(scenario_file: str, overrides: dict[str, Any]) -> dict[str, Any]:
    """Run one case (in a worker); returns its overrides and flattened metrics, or its error.

    After a SIGINT in a local worker (:mod:`cnc_twin.studies.sweep_stop`) a case is not run, and
    the one running stops at its next period: both are ``interrupted`` (the latter with its
    figures up to ``sim_time_s``)."""
    global _WORKER_PLANNERS
    from cnc_twin.core.errors import ScenarioError
    from cnc_twin.planner.launch import PlannerPool
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.run.twin import Twin

    exit_on_sigterm()
    if stop_requested():
        return interrupted_row(overrides)
    if _WORKER_PLANNERS is None:
        _WORKER_PLANNERS = PlannerPool()
    with sigint_held():  # the run takes this planner: one that a Ctrl-C cannot kill while it starts
        _WORKER_PLANNERS.prestart()
    try:
        twin = Twin(load_scenario(scenario_file, overrides=overrides))
        with stoppable(twin):
            result = twin.run(planners=_WORKER_PLANNERS)
    except ScenarioError as exc:
        return {**overrides, "status": "invalid", "error": str(exc)}
    if result.status == INTERRUPTED and not result.metrics.get("sim_time_s"):
        return interrupted_row(overrides)  # stopped before its first period: its zeros would read as figures
    return {**overrides, **flatten_metrics(result.metrics)}


def interrupted_row(overrides: dict[str, Any]) -> dict[str, Any]:
    """The row of a case that a stopped sweep never ran: its overrides and its status."""
    return {**overrides, "status": INTERRUPTED}


ProgressCallback = Callable[[int, int], None]


def run_local(scenario_file: str, todo: list[dict[str, Any]], *, workers: int | None = None,
              progress: ProgressCallback | None = None, case_fn=run_case,
              stop: SweepStop | None = None) -> list[dict[str, Any]]:
    """Run the cases on a local process pool; one row per case, in ``todo``'s order.

    A worker that dies breaks the pool and fails every case in flight with it: the cases not yet
    started go on in a fresh pool, and those that failed are retried one at a time, each in a
    fresh single-worker pool: only a case that kills its worker again is reported ``lost``.

    ``stop``: once requested (the CLI requests it on SIGINT or SIGTERM), no case starts, the
    running ones stop at their next period, and every case not finished is ``interrupted``. A
    KeyboardInterrupt here stops the workers the same way before it propagates.
    """
    own_stop = stop is None
    stop = SweepStop() if stop is None else stop
    rows: list[dict[str, Any] | None] = [None] * len(todo)
    finished = 0

    def done() -> None:
        nonlocal finished
        finished += 1
        if progress is not None:
            progress(finished, len(todo))

    try:
        queue, failed = deque(range(len(todo))), []
        while queue and stop.reason is None:
            failed += _run_pool(scenario_file, todo, queue, rows, workers or DEFAULT_WORKERS, case_fn, stop, done)
        for i in sorted(failed):
            if stop.reason is not None:
                break
            if _run_pool(scenario_file, todo, deque([i]), rows, 1, case_fn, stop, done):
                rows[i] = {**todo[i], "status": "lost", "error": "its worker process died (twice)"}
                done()
    finally:
        if own_stop:
            stop.close()
    return [row if row is not None else interrupted_row(case) for row, case in zip(rows, todo)]


def _run_pool(scenario_file: str, todo: list[dict[str, Any]], queue: deque[int], rows: list[dict[str, Any] | None],
              workers: int, case_fn, stop: SweepStop, done: Callable[[], None]) -> list[int]:
    """Run cases from the front of ``queue`` (indices into ``todo``) on a pool of ``workers``
    processes into ``rows`` until the queue is empty, the pool breaks or ``stop`` is requested;
    returns the cases that were in flight when a worker died."""
    # A warm process (the warm server's command) forks its workers: they start with everything
    # loaded, in milliseconds; any other starts new interpreters (a fork of a script's process
    # could copy a thread's held lock, and would import nothing less).
    context = multiprocessing.get_context("fork" if can_fork() else "spawn")
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=init_worker,
                               initargs=stop.worker_args)
    # Cases are handed out as workers free up (two per worker in flight keeps them busy), so a
    # stop has few to call back and a broken pool leaves the rest of the queue untouched.
    in_flight: dict[Future, int] = {}
    failed: list[int] = []
    broken = False  # a worker died: the pool takes no more cases
    try:
        while True:
            while queue and stop.reason is None and not failed and len(in_flight) < 2 * workers:
                i = queue.popleft()
                try:
                    with sigint_held():  # a submit may start a worker
                        in_flight[pool.submit(case_fn, scenario_file, todo[i])] = i
                except BrokenProcessPool:
                    queue.appendleft(i)
                    broken = True
                    break
            if not in_flight:
                return failed
            finished, _ = wait(in_flight, timeout=POLL_S, return_when=FIRST_COMPLETED)
            stop.pass_on()
            for future in finished:
                i = in_flight.pop(future)
                try:
                    rows[i] = future.result()
                except BrokenProcessPool:
                    failed.append(i)
                    broken = True
                    continue
                except (KeyboardInterrupt, SystemExit):  # a signal ended it in its worker
                    continue
                except Exception:
                    if stop.reason is None:
                        raise
                    continue  # e.g. an import that a signal cut short in the worker: interrupted too
                done()
    except BaseException as exc:
        stop.request_stop(type(exc).__name__)  # e.g. Ctrl-C in a script: the runs stop before the wait below
        stop.pass_on()
        raise
    finally:
        if broken:  # its other workers end now, not when the pool gets round to it
            stop.end_workers()
        pool.shutdown(wait=True, cancel_futures=True)
        stop.forget_workers()


def run_dask(scenario_file: str, todo: list[dict[str, Any]], *, scheduler: str,
             progress: ProgressCallback | None = None, retries: int = 1,
             stop: SweepStop | None = None) -> list[dict[str, Any]]:
    """Run the cases on a Dask cluster at ``scheduler``; a case whose worker died is retried,
    then reported ``lost``. Workers must be non-daemonic (each run starts a planner process).

    Once ``stop`` is requested the cases not finished are cancelled and ``interrupted`` (a case
    already running on the cluster runs to its end there; its result is dropped)."""
    from distributed import Client, as_completed as dask_completed

    rows: list[dict[str, Any] | None] = [None] * len(todo)
    with Client(scheduler) as client:
        futures = {client.submit(run_case, scenario_file, todo[i], pure=False, retries=retries): i
                   for i in range(len(todo))}
        pending = dask_completed(futures)
        done = 0
        while not pending.is_empty():
            if stop is not None and stop.reason is not None:
                client.cancel([f for f, i in futures.items() if rows[i] is None])
                break
            if not pending.has_ready():  # polled, so that a stop is seen while cases run
                time.sleep(POLL_S)
                continue
            for future in pending.next_batch(block=False):
                i = futures[future]
                try:
                    rows[i] = future.result()
                except Exception as exc:  # KilledWorker after the retries, or a crash in the case
                    rows[i] = {**todo[i], "status": "lost", "error": f"{type(exc).__name__}: {exc}"}
                done += 1
                if progress is not None:
                    progress(done, len(todo))
    return [row if row is not None else interrupted_row(case) for row, case in zip(rows, todo)]


def write_table(rows: list[dict[str, Any]], out_dir: Path) -> tuple[Path, Path]:
    """``sweep.parquet`` and ``sweep.csv`` in ``out_dir``, one row per case."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    out_dir.mkdir(parents=True, exist_ok=True)
    columns = list(dict.fromkeys(k for row in rows for k in row))
    table = pa.Table.from_pylist([{k: row.get(k) for k in columns} for row in rows])
    table = table.cast(pa.schema([field.with_metadata({"unit": column_unit(field.name)}) for field in table.schema]))
    parquet, csv = out_dir / "sweep.parquet", out_dir / "sweep.csv"
    pq.write_table(table, parquet)
    pacsv.write_csv(table, csv)
    return parquet, csv


UNIT_SUFFIXES = {"_mm": "mm", "_deg": "deg", "_um": "um", "_s": "s", "_pct": "%", "_mm3": "mm^3", "_ticks": "ticks"}
"""a sweep column's unit, by the end of its name"""


def column_unit(name: str) -> str:
    """The unit of the sweep table's column ``name`` (``1`` for counts, ratios, states and the
    swept parameters, which are in the scenario's own units)."""
    return next((unit for suffix, unit in UNIT_SUFFIXES.items() if name.endswith(suffix)), "1")


def best_row(rows: list[dict[str, Any]], minimize: str) -> dict[str, Any] | None:
    """The completed row with the smallest ``minimize`` column."""
    ok = [r for r in rows if r.get("status") == "complete" and r.get(minimize) is not None]
    return min(ok, key=lambda r: r[minimize]) if ok else None


def timed(fn, *args, **kwargs) -> tuple[Any, float]:
    """``fn(*args, **kwargs)`` and its wall time [s]."""
    started = time.perf_counter()
    return fn(*args, **kwargs), time.perf_counter() - started

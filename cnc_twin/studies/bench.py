"""Speed figures measured in one process run: the full twin against bare MuJoCo stepping.

``bare``: a Python loop of ``mujoco.mj_step(model, data)`` on the same MJCF at the same
timestep, for the same number of physics steps the twin takes, drives at 0 V.
``replay``: the same number of physics steps on the run's own model (workpiece included), with
the drive voltages the run recorded replayed open loop, tick by tick: the fair denominator for a
run in contact (:mod:`cnc_twin.studies.bench_replay`), with the mean contact count of both
denominators (``replay_contacts_mean``, ``bare_contacts_mean``).
``twin``: the simulated clock of ``Twin.run()`` (exchanges with the planner process, DSP task,
plant, recording), the loop the ratio is about; ``twin_startup_s`` is the rest of ``run()``
(spawning and attaching the planner process, metrics, teardown), a fixed cost per run;
``twin_build_s`` is building the twin before that (the plant's model: for a polishing run the
workpiece's solid, its collision tiles and the MJCF compile; the removal map; the card), and
``twin_build_kept_s`` the same when an earlier run of the process built that workpiece (a sweep's
later runs: :mod:`cnc_twin.run.workpiece_cache`);
``twin_startup_pooled_s`` the same as ``twin_startup_s`` when the planner process is kept warm between runs
(:class:`~cnc_twin.planner.launch.PlannerPool`, as a sweep's workers do).
``twin_no_record``: the same with every tick written to a one-period scratch buffer, so
``recording_overhead`` is what keeping the trace costs. ``twin_python_servo``: the same with the
pure-Python reference servo instead of the compiled one (:mod:`cnc_twin.run.servo_kernel`).
Each variant is measured ``repeat`` times, alternating, and the fastest of each is kept, so all
see the same machine state; quote the ratios, not the absolute times.

``rerun_export_over_run``: :func:`~cnc_twin.view.rerun_export.export_run` of the finished run (what
``RunResult.write`` does from Python) over the run's clock; ``rerun_streamed_tail_over_run``:
the wait after the run for a recording made during it by a recording process (what ``cnc-twin
run`` does, :mod:`cnc_twin.view.rerun_stream`) over the same clock; ``rerun_streamed_run_slowdown``:
the run's clock with that process feeding beside it over the clock without (both reporting
progress as the CLI does).

``trace_held_over_raw``: memory the run's trace keeps alive over the raw bytes of the recorded
signals (each at its natural width, :data:`cnc_twin.trace.layout.TICK_BYTES` per tick plus the
per-period signals).
"""

from __future__ import annotations

import resource
import time
from pathlib import Path
from typing import Any

import mujoco

from cnc_twin.planner.launch import PlannerPool
from cnc_twin.machine.model_file import load_model
from cnc_twin.machine.plant import Plant
from cnc_twin.scenario.load import load_scenario
from cnc_twin.run.twin import Twin


def time_bare_steps(model_file: Path, *, timestep: float, steps: int, drives=None) -> float:
    """Wall time [s] of ``steps`` calls of ``mj_step`` on a fresh plant at home (``drives``: the
    scenario's, :attr:`~cnc_twin.core.config.Scenario.drives`, for a machine with current-mode drives)."""
    plant = Plant(load_model(model_file), timestep=timestep, drives=drives)
    model, data, mj_step = plant.model, plant.data, mujoco.mj_step
    start = time.perf_counter()
    for _ in range(steps):
        mj_step(model, data)
    return time.perf_counter() - start


def time_twin_build(scenario_file: Path, *, kept: bool = False, overrides: dict | None = None) -> float:
    """Wall time [s] of building a run's twin from its loaded scenario: the plant's model (for a
    polishing run the workpiece's solid, its convex collision tiles and the MJCF compile), the
    removal map, the card, the compiled servo's set-up. ``kept``: with the workpiece an earlier
    run of the process built (:mod:`cnc_twin.run.workpiece_cache`, a sweep's later runs); else
    built from scratch. ``overrides``: as :func:`~cnc_twin.scenario.load.load_scenario` takes them."""
    from cnc_twin.run import workpiece_cache

    scenario = load_scenario(scenario_file, overrides=overrides)
    if kept:
        Twin(scenario)
    else:
        workpiece_cache.forget()
    start = time.perf_counter()
    Twin(scenario)
    return time.perf_counter() - start


def time_twin_run(scenario_file: Path, planners: PlannerPool | None = None, *, overrides: dict | None = None,
                  **options) -> tuple[float, float, Any]:
    """One twin run (``options`` for :class:`~cnc_twin.run.twin.Twin`, the planner from ``planners``
    if given): clock wall time [s], whole run() wall time [s], the result."""
    twin = Twin(load_scenario(scenario_file, overrides=overrides), **options)
    start = time.perf_counter()
    result = twin.run(planners=planners)
    total = time.perf_counter() - start
    return result.metrics["wall_time_s"], total, result


def time_rerun_export(scenario_file: Path, *, repeat: int = 1, overrides: dict | None = None) -> tuple[float, float]:
    """(rerun export wall [s] with rerun already imported, import time [s]): the export of one
    run, the fastest of ``repeat``."""
    import sys
    import tempfile

    started = time.perf_counter()
    already = "rerun" in sys.modules
    import rerun  # noqa: F401  (one-time cost, measured apart)

    import_s = 0.0 if already else time.perf_counter() - started
    from cnc_twin.view.rerun_export import export_run  # noqa: F401

    result = Twin(load_scenario(scenario_file, overrides=overrides)).run()
    exports = []
    with tempfile.TemporaryDirectory() as folder:
        for i in range(max(1, repeat)):
            started = time.perf_counter()
            result.export_rerun(rrd=Path(folder) / f"recording{i}.rrd")
            exports.append(time.perf_counter() - started)
    return min(exports), import_s


def bench_scenario(scenario_file: Path, *, repeat: int = 3, overrides: dict | None = None) -> dict[str, Any]:
    """Measure twin and bare stepping for ``scenario_file`` (with ``overrides``, e.g. another
    bundled machine's, :data:`~cnc_twin.scenario.resources.BUNDLED_MACHINES`); returns figures
    as a flat dict."""
    scenario = load_scenario(scenario_file, overrides=overrides)
    twin_times, bare_times, totals, pooled, no_record, python_servo = [], [], [], [], [], []
    planners = PlannerPool()
    time_twin_run(scenario_file, planners, overrides=overrides)  # starts the planner the pool keeps
    for _ in range(repeat):
        wall, total, result = time_twin_run(scenario_file, overrides=overrides)
        steps = result.metrics["physics_steps"]
        twin_times.append(wall)
        totals.append(total - wall)
        wall, total, _ = time_twin_run(scenario_file, planners, overrides=overrides)
        pooled.append(total - wall)
        bare_times.append(time_bare_steps(scenario.model_file, timestep=scenario.timing.physics_timestep, steps=steps,
                                          drives=scenario.drives))
        no_record.append(time_twin_run(scenario_file, record=False, overrides=overrides)[0])
        python_servo.append(time_twin_run(scenario_file, compiled=False, overrides=overrides)[0])
    planners.close()
    trace = result.trace
    twin_s, bare_s = min(twin_times), min(bare_times)
    ticks = steps // scenario.timing.substeps_per_tick
    sim_time = ticks * scenario.timing.servo_period
    return {
        "scenario": scenario.name,
        "model": scenario.model_file.name,
        "physics_steps": steps,
        "servo_ticks": ticks,
        "sim_time_s": sim_time,
        "bare_mj_step_s": bare_s,
        "twin_s": twin_s,
        "ratio_twin_over_bare": twin_s / bare_s,
        **_replay_figures(scenario, trace, repeat, twin_s),
        "ratio_python_servo_over_bare": min(python_servo) / bare_s,
        "recording_overhead": twin_s / min(no_record) - 1.0,
        "bare_us_per_step": bare_s / steps * 1e6,
        "twin_us_per_tick": twin_s / ticks * 1e6,
        "twin_overhead_us_per_tick": (twin_s - bare_s) / ticks * 1e6,
        "real_time_factor": sim_time / twin_s,
        "twin_build_s": min(time_twin_build(scenario_file, overrides=overrides) for _ in range(max(1, repeat))),
        "twin_build_kept_s": min(time_twin_build(scenario_file, kept=True, overrides=overrides)
                                 for _ in range(max(1, repeat))),
        "twin_startup_s": min(totals),
        "twin_startup_pooled_s": min(pooled),
        "trace_bytes": trace.nbytes(),
        "trace_held_over_raw": trace.held_nbytes() / trace.raw_nbytes(),
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        **_rerun_figures(scenario_file, repeat, twin_s, overrides),
        "repeat": repeat,
    }


def _replay_figures(scenario, trace, repeat: int, twin_s: float) -> dict[str, Any]:
    """The run's recorded drive voltages replayed open loop into the run's own model
    (:mod:`cnc_twin.studies.bench_replay`), best of ``repeat``, and the contact counts of both
    denominators; empty for step-pulse output (no voltages to replay)."""
    if scenario.command_output != "analog":
        return {}
    from cnc_twin.studies.bench_replay import contacts_at_rest, run_model, time_replayed_steps

    model = run_model(scenario)
    timing = scenario.timing
    replays = [time_replayed_steps(model, trace.dac, timestep=timing.physics_timestep, substeps=timing.substeps_per_tick,
                                   drives=scenario.drives)
               for _ in range(max(1, repeat))]
    replay_s = min(r.seconds for r in replays)
    return {"replay_mj_step_s": replay_s, "ratio_twin_over_replay": twin_s / replay_s,
            "replay_us_per_step": replay_s / (len(trace.dac) * timing.substeps_per_tick) * 1e6,
            "replay_contacts_mean": replays[0].contacts_mean, "bare_contacts_mean": contacts_at_rest(scenario)}


def time_streamed_recording(scenario_file: Path, *, repeat: int = 1, overrides: dict | None = None) -> dict[str, float]:
    """A run recorded while it runs by a :class:`~cnc_twin.view.rerun_stream.RecordingProcess`, as
    ``cnc-twin run`` records: the run's clock, the wait after it until the recording is closed
    (the tail), and, alternating, the same run's clock without the recording process. Both runs
    report progress as the CLI's (so their batches stop at the same periods). Best of ``repeat``."""
    import tempfile

    from cnc_twin.view.rerun_stream import RecordingProcess

    scenario = load_scenario(scenario_file, overrides=overrides)
    clocks, tails, alone = [], [], []
    with tempfile.TemporaryDirectory() as folder:
        for i in range(max(1, repeat)):
            with RecordingProcess() as recorder:
                recorder.wait_ready()  # in the CLI its imports overlap the twin's start-up
                recorder.open(scenario, rrd=Path(folder) / f"streamed{i}.rrd")
                result = Twin(scenario).run(observer=recorder.observe, progress=_no_progress)
                started = time.perf_counter()
                recorder.finish(result)
                tails.append(time.perf_counter() - started)
                clocks.append(result.metrics["wall_time_s"])
            alone.append(Twin(scenario).run(progress=_no_progress).metrics["wall_time_s"])
    return {"rerun_streamed_tail_s": min(tails), "rerun_streamed_run_s": min(clocks),
            "rerun_streamed_run_alone_s": min(alone), "rerun_streamed_run_slowdown": min(clocks) / min(alone) - 1.0}


def _no_progress(done: int, total: int) -> None:
    """A progress callback that shows nothing (the CLI's bar when stderr is not a terminal)."""


def _rerun_figures(scenario_file: Path, repeat: int, twin_s: float, overrides: dict | None) -> dict[str, float]:
    """The in-process export's best of ``repeat`` over the run loop's best (``twin_s``, measured
    above), and the streamed recording's figures."""
    export, import_s = time_rerun_export(scenario_file, repeat=repeat, overrides=overrides)
    streamed = time_streamed_recording(scenario_file, repeat=repeat, overrides=overrides)
    # Over the plain run's clock (no progress reports, no recording process): the strictest base.
    return {"rerun_export_s": export, "rerun_export_over_run": export / twin_s, "rerun_import_s": import_s,
            "rerun_streamed_tail_s": streamed["rerun_streamed_tail_s"],
            "rerun_streamed_tail_over_run": streamed["rerun_streamed_tail_s"] / twin_s,
            "rerun_streamed_run_slowdown": streamed["rerun_streamed_run_slowdown"]}


def format_bench(figures: dict[str, Any]) -> str:
    """Figures as an aligned two-column table."""
    width = max(len(k) for k in figures)
    lines = []
    for key, value in figures.items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        lines.append(f"{key:<{width}}  {text}")
    return "\n".join(lines)

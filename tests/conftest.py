"""Shared fixtures: paths and a helper that writes scenario files for a test."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parent.parent

# no prepared programs kept between loads in the tests (each load prepares its program, as a
# patched function or a changed file expects); tests/test_program_cache.py turns the cache on
os.environ["CNC_TWIN_CACHE"] = "off"
# every command in its own process, and no warm server left behind by the suite's many commands;
# tests/test_warm_server.py starts its own, in a private folder, and ends it
os.environ["CNC_TWIN_SERVER"] = "off"
# a runtime folder of the suite's own (each process's), so that no command of the suite ever
# reaches a warm server its user has running (in $XDG_RUNTIME_DIR/cnc-twin), nor leaves a socket
# there; short, as a socket's path has room for 107 bytes
_RUNTIME = tempfile.mkdtemp(prefix="cnc-rt-")
os.environ["XDG_RUNTIME_DIR"] = _RUNTIME
atexit.register(shutil.rmtree, _RUNTIME, True)


@pytest.fixture
def write_scenario(tmp_path):
    """Write a scenario mapping (or raw text) to a YAML file in tmp_path; returns its path."""

    def _write(content, name: str = "scenario.yaml") -> Path:
        path = tmp_path / name
        text = content if isinstance(content, str) else yaml.safe_dump(content, sort_keys=False)
        path.write_text(text, encoding="utf-8")
        return path

    return _write


def single_move(axis: str, target: float, *, settle: float = 0.5, **extra) -> dict:
    """A minimal scenario mapping: one point-to-point move of one axis."""
    return {"name": f"move_{axis}", "program": {"type": "point_to_point", "moves": [{axis: target}], "settle": settle},
            **extra}


def run_cli(*args: str) -> tuple[int, str, str]:
    """``cnc-twin ARGS`` called in this process: (exit code, stdout, stderr)."""
    import contextlib
    import io

    from cnc_twin.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(arg) for arg in args])
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="session")
def warm_planners():
    """One planner pool for the session's runs in this process: a run takes the planner the last
    clean run left (start-up and teardown 0.9 -> 0.12 s a run; pooled runs give the traces of
    fresh planners, tests/test_planner_pool.py)."""
    from cnc_twin.planner.launch import PlannerPool

    with PlannerPool() as pool:
        yield pool


@pytest.fixture(autouse=True)
def shared_planner_pool(request, warm_planners, monkeypatch):
    """Runs that name no pool of their own use :func:`warm_planners`; a test marked
    ``fresh_planner`` (it checks a planner's start or a pool's bookkeeping) gets fresh ones."""
    if request.node.get_closest_marker("fresh_planner") is None:
        from cnc_twin.run.twin import Twin

        run = Twin.run

        def pooled(self, *args, planners=None, **kwargs):
            return run(self, *args, planners=warm_planners if planners is None else planners, **kwargs)

        monkeypatch.setattr(Twin, "run", pooled)
    yield


@pytest.fixture(autouse=True)
def no_leftover_segments_or_processes(warm_planners):
    """Every test must leave no whiteboard segment in /dev/shm and no child process behind (the
    session pool's idle planner aside)."""
    import multiprocessing

    from cnc_twin.whiteboard.block import leaked_segments, leftover_segments

    before = set(leftover_segments())
    yield
    # segments of other live processes (say a second test run on this machine) are not ours
    assert leaked_segments(set(leftover_segments()) - before) == set(), "shared-memory segment left behind"
    assert multiprocessing.active_children() == [], "child process left behind"
    pooled = warm_planners.idle_pids()
    assert [pid for pid in _planner_children() if pid not in pooled] == [], "planner process left behind"


def _planner_children() -> list[int]:
    """Live (not zombie) child processes of this one running the planner module."""
    import os
    from pathlib import Path

    me, out = os.getpid(), []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            stat = (proc / "stat").read_text().rsplit(")", 1)[1].split()
            cmd = (proc / "cmdline").read_bytes()
        except OSError:
            continue
        if int(stat[1]) == me and stat[0] != "Z" and b"cnc_twin.planner.process" in cmd:
            out.append(int(proc.name))
    return out


def pytest_xdist_auto_num_workers(config):
    """`-n auto`: one worker more than the cores this process may use. The suite's tests spend
    part of their time waiting on subprocesses (planner start-up, CLI runs, the signal tests'
    moments), and a third worker fills those gaps on two cores (measured: 2 workers 183 s,
    3 workers 164 s for the whole suite, 2026-11-24)."""
    import os

    return len(os.sched_getaffinity(0)) + 1


HEAVIEST_FIRST = ("test_signals.py", "test_view_web.py", "test_getting_started.py", "test_polish_batch.py",
                  "test_examples.py", "test_rerun_stream.py",
                  "test_sweep.py", "test_polish_twin.py", "test_sweep_interrupt.py", "test_linearize.py",
                  "test_docs.py", "test_cam_raster.py", "test_twin.py", "test_hostile_inputs.py",
                  "test_scenario.py", "test_whiteboard.py", "test_gcode_twin.py", "test_fault_catalog.py")
"""The modules that take the workers longest (--durations, 2026-11-26: 130 down to 30 s each of the
suite's 1200 worker-seconds), costliest first."""


def _order_costliest_first(items):
    """The costliest modules first, the rest in their own order after them: xdist's loadscope hands
    out modules in this order, and a long module handed out last keeps one worker busy after the
    others ran dry (longest-first scheduling)."""
    rank = {name: place for place, name in enumerate(HEAVIEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


SLOW_MODULES = frozenset({
    "test_bench_replay.py", "test_bench_startup.py", "test_compensation.py", "test_gcode_force.py", "test_trace_pieces.py",
    "test_gcode_expressions.py", "test_heap.py",
    "test_ballbar.py", "test_cam_raster.py", "test_commissioning.py", "test_compliant_model.py",
    "test_contour_twin.py", "test_docs.py", "test_docs_site.py", "test_drive_tuning.py",
    "test_environment_faults.py", "test_examples.py", "test_fault_catalog.py", "test_fit.py",
    "test_fuzz_scenarios.py", "test_gcode_arcs.py", "test_gcode_corpus.py", "test_gcode_cycles.py",
    "test_gcode_interpreter.py", "test_gcode_line_fit.py", "test_gcode_modal.py", "test_gcode_nurbs.py",
    "test_gcode_probe.py", "test_gcode_setup.py", "test_gcode_speed_paths.py", "test_gcode_twin.py",
    "test_getting_started.py", "test_hostile_inputs.py", "test_linearize.py", "test_machines.py",
    "test_motion_chip_twin.py", "test_nurbs.py", "test_nurbs_twin.py", "test_outside_corpus.py",
    "test_outside_runs.py", "test_paths_ahead.py", "test_plan_cache.py", "test_planner_pool.py",
    "test_polish_batch.py", "test_polish_twin.py", "test_probing_twin.py", "test_program_cache.py",
    "test_program_streaming.py", "test_published_curves.py", "test_removal_kernel.py", "test_rerun.py",
    "test_rerun_stream.py", "test_runaway_programs.py", "test_scenario.py", "test_serve.py",
    "test_servo_kernel.py", "test_signals.py", "test_soak.py", "test_sweep.py", "test_sweep_interrupt.py",
    "test_trace_streaming.py", "test_twin.py", "test_view_web.py", "test_warm_server.py",
    "test_whiteboard.py"
})
"""Modules marked ``slow`` whole: each took over 8 worker-seconds in a ``--durations=0`` run of the
whole suite (3 workers on 2 cores; ``test_layout.py``, 16 s of quick rules, kept in the loop), or
runs a whole twin, LinuxCNC or a whole program in a test of a few seconds (the first two lines). They
run whole twins, start ``cnc-twin`` processes, read the G-code corpora or build pages; what is left
(``python -m pytest -m "not slow"``) is the edit-test loop of the blocks, the geometry, the reader,
the whiteboard and the layout rules, under a minute on 2 cores. A new module of whole runs joins
this list (or marks its slow tests ``@pytest.mark.slow``)."""


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(session, config, items):
    """Marks the tests of :data:`SLOW_MODULES` ``slow`` before ``-m`` selects (tryfirst: the mark
    plugin's own hook deselects after this one)."""
    for item in items:
        if item.path.name in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)
    _order_costliest_first(items)



def pytest_configure(config):
    """With workers (xdist), the controller has numba compile the twin's kernels once before the
    workers start, when a fresh install has none cached: otherwise every worker compiles them at
    once (about 15 s of CPU each, on the same cores)."""
    if getattr(config, "workerinput", None) is not None or not config.getoption("numprocesses", None):
        return
    from cnc_twin.studies.kernel_warmup import warm_kernels

    warm_kernels()

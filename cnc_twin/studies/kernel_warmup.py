"""Compile the twin's numba kernels into numba's on-disk cache ahead of the runs that use them.

A fresh install has none cached: its first run compiles them (about 60 s of one core). Test
workers or sweep processes that all start at once would each compile them, on the same cores; one
process that warms the cache first lets them load the machine code instead. Used by the test
suite's controller and by CI (``python -m cnc_twin.studies.kernel_warmup`` prints its time).
"""

from __future__ import annotations

WARMUP_SCENARIOS = ("jog_axes.yaml", "nurbs_circle.yaml", "flat_plate_polish.yaml")
"""bundled scenarios whose first half second reaches every kernel: the point and curve paths and
the polishing ones (force loop, removal map)"""


def warm_kernels() -> bool:
    """Run the first 0.5 s of each of :data:`WARMUP_SCENARIOS` if the kernels are not cached yet.
    Returns True if it compiled (False: nothing to do)."""
    from cnc_twin.run.period_kernel import kernels_cached

    if kernels_cached():
        return False
    from cnc_twin.run.twin import run_scenario
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.scenario.resources import scenarios_dir

    for name in WARMUP_SCENARIOS:
        run_scenario(load_scenario(scenarios_dir() / name, overrides={"max_time": 0.5}))
    return True


if __name__ == "__main__":
    import time

    started = time.perf_counter()
    compiled = warm_kernels()
    print(f"kernels {'compiled' if compiled else 'already cached'} in {time.perf_counter() - started:.1f} s")

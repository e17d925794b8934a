"""cnc-twin: a digital twin of a six-axis "PC + DSP motion card" polishing machine.

Public entry points::

    from cnc_twin import load_scenario, run_scenario
    scenario = load_scenario("scenarios/jog_axes.yaml")
    result = run_scenario(scenario)          # no files written
    result.metrics["following_error"]["X"]["max"]

Also here: ``Twin`` (one run, built from a scenario), ``RunResult``, ``PlannerPool`` (keeps a
planner process warm between runs), ``RecordingProcess`` (records a rerun file during a run),
``analyse`` (the linear loop of an axis), ``sweep`` (grids of overrides), ``Scenario``,
``ScenarioError``. The package's parts and how they import each other: README, Architecture.

The names are imported lazily so that light processes (the planner) import only what they use.
"""

from __future__ import annotations

import importlib
import os
from typing import Any

# The twin draws with rerun, never with MuJoCo's OpenGL. Left unset, `import mujoco` imports
# glfw, whose import starts a Python subprocess to ask the GLFW library its version: 20-30 ms in
# each of a run's processes, and a child that prints an EOFError traceback into the command's
# stderr when a signal ends the command during its start-up. A MUJOCO_GL the user sets is kept
# (e.g. egl, to render with mujoco.Renderer beside the twin).
os.environ.setdefault("MUJOCO_GL", "disable")

__all__ = ["PlannerPool", "RecordingProcess", "RunResult", "Scenario", "ScenarioError", "Twin", "analyse",
           "load_scenario", "run_scenario", "sweep"]
__version__ = "0.1.0"

_EXPORTS = {
    "Scenario": "cnc_twin.core.config",
    "ScenarioError": "cnc_twin.core.errors",
    "load_scenario": "cnc_twin.scenario.load",
    "Twin": "cnc_twin.run.twin",
    "RunResult": "cnc_twin.run.result",
    "run_scenario": "cnc_twin.run.twin",
    "PlannerPool": "cnc_twin.planner.launch",
    "RecordingProcess": "cnc_twin.view.rerun_stream",
    "analyse": "cnc_twin.studies.linearize",
}
_MODULES = {"sweep": "cnc_twin.studies.sweep"}
"""names that are modules: ``from cnc_twin import sweep`` then ``sweep.run_local(...)``"""


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    if name in _MODULES:
        return importlib.import_module(_MODULES[name])
    raise AttributeError(f"module 'cnc_twin' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)

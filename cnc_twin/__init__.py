"""cnc-twin: a digital twin of a six-axis "PC + DSP motion card" polishing machine.

Public entry points::

    from cnc_twin import load_scenario, run_scenario
    scenario = load_scenario("scenarios/jog_axes.yaml")
    result = run_scenario(scenario)          # no files written
    result.metrics["following_error"]["X"]["max"]

The names are imported lazily so that light processes (the planner) import only what they use.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["Scenario", "ScenarioError", "RunResult", "load_scenario", "run_scenario"]
__version__ = "0.1.0"

_EXPORTS = {
    "Scenario": "cnc_twin.core.config",
    "ScenarioError": "cnc_twin.core.errors",
    "load_scenario": "cnc_twin.scenario.load",
    "RunResult": "cnc_twin.run.twin",
    "run_scenario": "cnc_twin.run.twin",
}


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'cnc_twin' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)

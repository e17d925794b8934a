"""cnc-twin: a digital twin of a six-axis "PC + DSP motion card" polishing machine.

Public entry points::

    from cnc_twin import load_scenario, run_scenario
    scenario = load_scenario("scenarios/jog_axes.yaml")
    result = run_scenario(scenario)          # no files written
    result.metrics["following_error"]["X"]["max_mm"]
"""

from cnc_twin.errors import ScenarioError
from cnc_twin.scenario import Scenario, load_scenario
from cnc_twin.twin import RunResult, run_scenario

__all__ = ["Scenario", "ScenarioError", "RunResult", "load_scenario", "run_scenario"]
__version__ = "0.1.0"

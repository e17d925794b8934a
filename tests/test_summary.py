"""The terminal summary says what the figures are: no signed zeros."""

from __future__ import annotations

import copy

from conftest import single_move
from cnc_twin.run.summary import summary_table
from cnc_twin.run.twin import run_scenario
from cnc_twin.scenario.load import load_scenario


def _axis_row(table: str, axis: str) -> list[str]:
    return next(line for line in table.splitlines() if line.startswith(f"{axis} ")).split()


def test_a_final_following_error_too_small_to_show_prints_as_zero_and_a_real_one_keeps_its_sign(write_scenario):
    metrics = run_scenario(load_scenario(write_scenario(single_move("A", 1.0, settle=0.1)))).metrics
    tiny, real = copy.deepcopy(metrics), copy.deepcopy(metrics)
    tiny["final_following_error"]["A"]["value"] = -0.00004
    real["final_following_error"]["A"]["value"] = -0.0012
    assert _axis_row(summary_table(tiny), "A")[5] == "0.0000"
    assert _axis_row(summary_table(real), "A")[5] == "-0.0012"


def test_the_summary_names_the_machine_the_run_ran_on(write_scenario):
    """Its model and parameter file, as metrics.json keeps them: the compliant default here, and a
    machine line exactly once."""
    metrics = run_scenario(load_scenario(write_scenario(single_move("X", 1.0, settle=0.1)))).metrics
    lines = [line for line in summary_table(metrics).splitlines() if line.startswith("machine: ")]
    assert lines == ["machine: scene.xml with polisher.yaml"]

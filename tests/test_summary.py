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


def test_a_program_path_line_names_the_line_of_the_path_with_the_largest_contour_error():
    """Whether the program has one feed path or several (a CAM program's only one is often its
    plunge, whose error the reader must be able to place)."""
    from cnc_twin.run.summary import path_line

    def path(*paths):
        worst = max(p["contour_error_um"] for p in paths)
        return {"feed_paths": len(paths), "length_mm": 10.0, "paths": [dict(p) for p in paths],
                "contour_error_um": {"max": worst, "rms": 1.0}, "encoder_contour_error_um": {"max": worst},
                "chord_error_um": {"max": 0.0}, "feed_fluctuation": {"max": 0.0}}

    assert "line 8" in path_line(path({"line": 8, "contour_error_um": 221.9}), {})
    several = path_line(path({"line": 8, "contour_error_um": 3.0}, {"line": 40, "contour_error_um": 9.0}), {})
    assert "line 40" in several and "line 8" not in several

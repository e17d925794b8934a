"""The circular test (ISO 230-4): its figures against the geometry they name (analytic shapes),
and a run of the test program measured from the trace as a ballbar would."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import REPO, run_cli
from cnc_twin.core.config import BallbarTest
from cnc_twin.run.ballbar import BallbarPass, hysteresis, least_squares_circle, pass_figures

R = 0.05
TEST = BallbarTest("XY", (0.0, 0.0, 0.0), R, np.radians(45))


def a_pass(deviation_of, direction="ccw", n=3600) -> BallbarPass:
    """A pass whose radius is R + deviation_of(angle) [m], about the nominal centre."""
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    radius = R + deviation_of(angle)
    points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    return BallbarPass(direction, angle if direction == "ccw" else angle[::-1], (radius - R) if direction == "ccw"
                       else (radius - R)[::-1], points if direction == "ccw" else points[::-1], 0.05)


def test_an_ellipse_from_mismatched_gains_is_twice_its_half_difference_wide():
    """r = R + a cos 2(theta - 45 deg): F = +-a, G = 2a, no radius error, no centre offset."""
    a = 8e-6
    f = pass_figures(a_pass(lambda t: a * np.cos(2 * (t - np.pi / 4))), TEST)
    assert f["radial_deviation_um"]["max"] == pytest.approx(8.0, abs=0.01)
    assert f["radial_deviation_um"]["min"] == pytest.approx(-8.0, abs=0.01)
    assert f["circular_deviation_um"] == pytest.approx(16.0, abs=0.05)
    assert abs(f["radius_error_um"]) < 0.01 and np.abs(f["centre_offset_um"]).max() < 0.01
    assert f["data_arc_deg"] == pytest.approx(360.0, abs=0.2)


def test_an_offset_circle_shows_as_its_centre_offset_not_as_circular_deviation():
    """A circle of radius R about (12, -5) um: F = +-13 um (the offset's length), the fitted centre
    is the offset, G nil."""
    dx, dy = 12e-6, -5e-6
    angle = np.linspace(0, 2 * np.pi, 3600, endpoint=False)
    points = np.column_stack([dx + R * np.cos(angle), dy + R * np.sin(angle)])
    theta = np.mod(np.arctan2(points[:, 1], points[:, 0]), 2 * np.pi)
    p = BallbarPass("ccw", theta, np.hypot(*points.T) - R, points, 0.05)
    f = pass_figures(p, TEST)
    assert f["centre_offset_um"] == pytest.approx([12.0, -5.0], abs=1e-3)
    assert f["radial_deviation_um"]["max"] == pytest.approx(13.0, abs=0.01)
    assert f["circular_deviation_um"] < 0.01 and abs(f["radius_error_um"]) < 0.01
    centre, radius = least_squares_circle(points)
    assert radius == pytest.approx(R, abs=1e-12)


def test_a_reversal_spike_is_measured_at_its_quadrant_above_the_path_beside_it():
    """A 6 um bump 2 deg after 90 deg on a 1 um ellipse: the spike at 90 is 6 um (to the ellipse's
    change over the window), the other quadrants' are the ellipse's own small steps."""
    def shape(t):
        return 1e-6 * np.cos(2 * t) + 6e-6 * np.exp(-0.5 * ((t - np.radians(92)) / np.radians(0.8)) ** 2)

    spikes = pass_figures(a_pass(shape), TEST)["reversal_spikes_um"]
    assert spikes["90"] == pytest.approx(6.0, abs=0.4)
    assert all(abs(spikes[q]) < 0.3 for q in ("0", "180", "270"))


def test_hysteresis_is_the_largest_difference_between_directions_at_one_angle():
    ccw = a_pass(lambda t: 3e-6 * np.sin(t))
    cw = a_pass(lambda t: -2e-6 * np.sin(t), direction="cw")
    assert hysteresis(ccw, cw) * 1e6 == pytest.approx(5.0, abs=0.01)


def _program_maker():
    spec = importlib.util.spec_from_file_location("make_ballbar_programs", REPO / "scripts" / "make_ballbar_programs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("plane, centre", [("xy", [0, 0, 20]), ("xz", [0, 0, 70])])
def test_a_run_of_the_test_program_is_measured_from_the_tip_as_run(tmp_path, write_scenario, plane, centre):
    """A short test (R 20 mm, F 4800, 30 deg overshoot): both passes found with their data arcs,
    the figures equal the tip's distance from the pivot read back from trace.parquet, the
    polar plot is in the run directory and the recording."""
    maker = _program_maker()
    (tmp_path / "test.ngc").write_text(maker.program(plane, radius=20.0, feed=4800.0, overshoot=30.0))
    path = write_scenario({"name": f"ballbar_{plane}", "program": {"type": "gcode", "file": "test.ngc", "settle": 0.1},
                           "ballbar": {"plane": plane.upper(), "centre": centre, "radius": 20, "overshoot": 30}})
    code, _, err = run_cli("run", path, "--out", tmp_path / "run", "--quiet")
    assert code == 0, err
    run = tmp_path / "run"
    figures = json.loads((run / "metrics.json").read_text())["ballbar"]
    assert figures["passes"] == 2 and "hysteresis_um" in figures
    for direction in ("ccw", "cw"):
        f = figures[direction]
        assert f["data_arc_deg"] > 359.0 and f["feed_mm_min"] == pytest.approx(4800, rel=0.01)
        assert f["radial_deviation_um"]["max"] >= f["radial_deviation_um"]["min"]
    # from the file, as a reader would: the tip's distance from the pivot over the passes' data arcs
    table = pq.read_table(run / "trace.parquet").to_pandas()
    across, up = {"xy": ("x", "y"), "xz": ("x", "z")}[plane]
    per_period = table.groupby("period").last()
    from cnc_twin.geometry.kinematics import HeadGeometry
    from cnc_twin.machine.model_file import load_model
    from cnc_twin.scenario.load import load_scenario

    origin = np.asarray(HeadGeometry.from_model(load_model(load_scenario(path).model_file)).workpiece_origin)
    pivot = np.asarray(centre) * 1e-3 + origin
    a = per_period[f"tip_{across}"].to_numpy() - pivot["xyz".index(across)]
    b = per_period[f"tip_{up}"].to_numpy() - pivot["xyz".index(up)]
    on = (per_period["path_u"].to_numpy() >= 0) & (np.abs(np.hypot(a, b) - 0.02) < 0.001)
    deviation_um = (np.hypot(a, b)[on] - 0.02) * 1e6
    measured = [figures[d]["radial_deviation_um"] for d in ("ccw", "cw")]
    # the data arcs are inside what this reads (it keeps the lead-in and lead-out too)
    assert max(m["max"] for m in measured) <= deviation_um.max() + 1e-6
    assert min(m["min"] for m in measured) >= deviation_um.min() - 1e-6
    assert (run / "ballbar.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from rrd_read import rrd_rows

    assert rrd_rows(run / "recording.rrd")[1].get("/figures/ballbar") == 1

"""The published benchmark curves (Lo Valvo & Drago, as LinuxCNC ships them): bundled as written,
planned at every period the card supports, refused at load when too long for the card, and any
limit the trace shows broken is reported, not passed over."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin import ScenarioError, load_scenario
from cnc_twin.cli import summary_table
from cnc_twin.planner.curve_program import curve_setup
from cnc_twin.planner.feed import plan_feed
from cnc_twin.scenario.load import scenario_from_text
from cnc_twin.scenario.resources import scenarios_dir

PUBLISHED = sorted((scenarios_dir() / "published").glob("*.yaml"))


def test_the_published_curves_are_bundled_with_their_source():
    assert {p.stem for p in PUBLISHED} >= {"farfalla", "delfino", "chitarra", "stella", "mazatrol"}
    for path in PUBLISHED:
        text = path.read_text()
        assert "Lo Valvo" in text and "LinuxCNC" in text and "nc_files/nurbs/G6" in text, path
        assert load_scenario(path).program.limits.feed == pytest.approx(2400 / 60e3)


def test_the_butterfly_is_transcribed_as_published():
    """Spot values of 'Curva_Farfalla #1=1.ngc': order 5, 51 points, weights 1.2 / 2 / 5 / 3, knots 0^5 1..46 47^5."""
    prog = load_scenario(scenarios_dir() / "published" / "farfalla.yaml").program
    assert prog.degree == 4 and len(prog.control_points) == 51
    assert prog.knots == tuple([0.0] * 5 + [float(k) for k in range(1, 47)] + [47.0] * 5)
    assert [prog.weights[i] for i in (3, 11, 14, 15)] == [1.2, 2.0, 5.0, 3.0]


def test_the_planner_converges_on_the_butterfly_at_a_quarter_millisecond():
    """It used to give up after 200 rounds (the planner process died: PLANNER_LOST). The plan covers
    the curve from rest to rest, and no block is faster than the feed limit at any sample."""
    prog = load_scenario(scenarios_dir() / "published" / "farfalla.yaml").program
    curve = curve_setup(prog)[0]
    plan = plan_feed(curve, prog.limits, period=0.25e-3, window=0.05)
    assert sum(b.length for b in plan.blocks) == pytest.approx(plan.length, rel=1e-9)
    assert plan.length == pytest.approx(0.358055, abs=1e-6)  # [m]; a 4-million-point polyline: 358.05470 mm
    assert plan.blocks[0].v0 == 0.0 and plan.blocks[-1].v1 == 0.0
    start = 0.0
    for block in plan.blocks:  # the block's speed at the samples it covers, from its own motion law
        t = np.linspace(0.0, block.duration, 2000)
        s_v = np.array([block.state(x)[:2] for x in t])
        inside = (plan.s >= start) & (plan.s <= start + block.length)
        v = np.interp(plan.s[inside] - start, s_v[:, 0], s_v[:, 1])
        assert np.all(v <= plan.limit[inside] * (1 + 1e-6)), f"block at s = {start * 1e3:.3f} mm"
        start += block.length


def test_a_curve_too_long_for_one_record_is_refused_at_load():
    n = 300
    points = "\n".join(f"    - [{i * 0.5}, {10 * np.sin(i / 10):.4f}, 10]" for i in range(n))
    knots = [0] * 4 + list(range(1, n - 3)) + [n - 3] * 4
    text = (f"name: long\nprogram:\n  type: nurbs_curve\n  degree: 3\n  control_points:\n{points}\n"
            f"  knots: {knots}\n  feed: 2400\n")
    with pytest.raises(ScenarioError) as err:
        scenario_from_text(text)
    assert "program.control_points" in str(err.value) and "one record" in str(err.value)


def test_the_summary_warns_on_a_limit_broken_in_the_trace():
    metrics = {
        "scenario": "x", "sim_time_s": 1.0, "wall_time_s": 0.1, "real_time_factor": 10.0, "physics_steps": 4000,
        "following_error": {}, "final_following_error": {}, "dac_saturation_ticks": {},
        "path": {"limit_violations": [{"axis": "Y", "quantity": "jerk", "peak": 881.0, "limit": 50.0,
                                       "ratio": 17.62, "time_s": 13.028}]},
    }
    text = summary_table(metrics)
    assert "WARNING: commanded Y jerk 17.62x its limit" in text and "13.028 s" in text
    metrics["path"]["limit_violations"] = []
    assert "WARNING" not in summary_table(metrics)

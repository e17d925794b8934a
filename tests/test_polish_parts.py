"""Parts of surface polishing without a run: kinematics, tool paths, records, the force loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_twin.core.config import ForceControl, SurfaceDef
from cnc_twin.dsp.force import ForceController, ForceState
from cnc_twin.geometry.kinematics import HeadGeometry, UnreachablePose, pose_to_axes
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.geometry.surface import NurbsSurface
from cnc_twin.geometry.surface_path import SurfacePath, tool_axes
from cnc_twin.planner.toolpath import ToolpathError, raster, spiral
from cnc_twin.machine.model_file import load_model
from cnc_twin.scenario.resources import resolve_model_file
from cnc_twin.whiteboard.codec import decode, encode
from cnc_twin.whiteboard.records import ForceControlRecord, SurfaceCurve, SurfaceGeometry

HEAD = HeadGeometry.from_model(load_model(resolve_model_file("scene_rigid.xml", None)))
KNOTS = [0, 0, 0, 0, 0.4, 1, 1, 1, 1]


def dome() -> NurbsSurface:
    """A doubly curved bicubic patch 160 x 120 mm (m, world frame above the table)."""
    x, y = np.meshgrid(np.linspace(-0.08, 0.08, 5), np.linspace(-0.06, 0.06, 5), indexing="ij")
    z = 0.07 - x**2 / 1.0 - y**2 / 0.6
    return NurbsSurface(np.stack([x, y, z], axis=-1), None, KNOTS, KNOTS, 3, 3)


def force_params(**kw) -> ForceControl:
    base = dict(setpoint=20.0, profile=(), ramp_time=0.1, seek_speed=2e-3, standoff=2e-3, contact_threshold=2.0,
                kp=5e-6, ki=3e-3, max_depth=8e-3, retract_speed=1e-2, adapt_threshold=0.1, adapt_feed=0.5,
                adapt_hold=0.02)
    base.update(kw)
    return ForceControl(**base)


def test_inverse_kinematics_round_trips():
    rng = np.random.default_rng(3)
    tips = HEAD.world_from_workpiece(rng.uniform([-0.1, -0.07, 0.0], [0.1, 0.07, 0.05], size=(500, 3)))
    axes = rng.normal(size=(500, 3)) * [0.4, 0.4, 0.0] + [0, 0, 1.0]
    q = HEAD.inverse(tips, axes)
    tip, axis = HEAD.forward(q)
    np.testing.assert_allclose(tip, tips, atol=1e-9, rtol=0)
    np.testing.assert_allclose(axis, axes / np.linalg.norm(axes, axis=1, keepdims=True), atol=1e-9, rtol=0)
    # the card's scalar IK agrees with the vectorised one
    for k in range(0, 500, 50):
        np.testing.assert_allclose(pose_to_axes(tips[k], axes[k], HEAD.pivot_home, HEAD.tool_offset), q[k],
                                   atol=1e-12)


def test_inverse_kinematics_refuses_unreachable_poses():
    tips = np.array([[0.0, 0.0, 0.1]] * 3)
    with pytest.raises(UnreachablePose, match="upward component") as info:
        HEAD.inverse(tips, np.array([[0, 0, 1.0], [1.0, 0, 0.0], [0, 0, 1.0]]))
    assert info.value.index == 1
    travel = [(-0.4, 0.4), (-0.3, 0.3), (-0.4, 0.0), None, None]
    with pytest.raises(UnreachablePose, match="Z would be .* outside its travel"):
        HEAD.inverse(np.array([[0.0, 0.0, 0.9]]), np.array([[0, 0, 1.0]]), travel=travel)


def test_raster_passes_keep_the_step_over_and_margin():
    surface = dome()
    sections = raster(surface, step_over=10e-3, margin=25e-3)
    # cut at pass ends: each section's passes within MAX_SECTION_LENGTH (0.3 m, scaled)
    assert len(sections) > 1
    for c in sections:
        assert SurfacePath(surface, NurbsCurve(c.control_points, c.weights, c.knots, c.degree)).arc_length() < 0.45
    uv = NurbsCurve(*(lambda c: (c.control_points, c.weights, c.knots, c.degree))(sections[0]))
    path = SurfacePath(surface, uv)
    t = np.linspace(*path.domain, 200001)
    q = uv.point(t)
    assert q[:, 0].min() >= 0 and q[:, 0].max() <= 1 and q[:, 1].min() >= 0 and q[:, 1].max() <= 1
    # pass rows: constant v; neighbours no further apart on the surface than the step-over
    vs = np.unique(np.round(np.asarray(sections[0].control_points)[:, 1], 12))
    passes = vs[::2] if len(vs) > 2 else vs
    u_mid = np.full(len(passes), 0.5)
    pts = surface.point(u_mid, passes)
    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    assert gaps.max() <= 10e-3 * 1.01 and gaps.min() > 7e-3
    # the path is G1: no corner anywhere (tangent turns little from one sample to the next)
    d = path.derivatives(t, 1)[1]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.min(np.sum(d[1:] * d[:-1], axis=1)) > 0.99
    # its length by quadrature matches the sampled polyline
    poly = np.sum(np.linalg.norm(np.diff(path.point(t), axis=0), axis=1))
    assert path.arc_length() == pytest.approx(poly, rel=1e-6)


def test_raster_too_wide_a_margin_is_refused():
    with pytest.raises(ToolpathError, match="no area") as info:
        raster(dome(), step_over=7e-3, margin=0.09)
    assert info.value.key == "margin"


def test_long_rasters_split_into_sections_that_join():
    surface = dome()
    sections = raster(surface, step_over=1e-3, margin=25e-3)
    assert len(sections) > 1
    ends = [NurbsCurve(c.control_points, c.weights, c.knots, c.degree) for c in sections]
    for a, b in zip(ends[:-1], ends[1:]):
        np.testing.assert_allclose(a.point([a.domain[1]]), b.point([b.domain[0]]), atol=1e-12)
    for c in sections:
        assert len(encode(SurfaceCurve(c), 1)) < 2100


def test_spiral_grows_by_the_step_over():
    surface = dome()
    sections = spiral(surface, step_over=6e-3, margin=20e-3)
    curves = [NurbsCurve(c.control_points, c.weights, c.knots, c.degree) for c in sections]
    t = np.concatenate([np.linspace(*c.domain, 4000) for c in curves])
    q = np.concatenate([c.point(np.linspace(*c.domain, 4000)) for c in curves])
    assert q.min() >= 0 and q.max() <= 1
    pts = surface.point(q[:, 0], q[:, 1])
    r = np.linalg.norm(pts[:, :2] - surface.point([0.5], [0.5])[0, :2], axis=1)
    assert r[-1] > r[0] + 0.03
    del t


def test_tool_axis_leans_by_lead_and_tilt():
    n = np.array([[0.0, 0.0, 1.0]])
    f = np.array([[1.0, 0.0, 0.0]])
    a = tool_axes(n, f, math.radians(10), 0.0)[0]
    assert a == pytest.approx([math.sin(math.radians(10)), 0, math.cos(math.radians(10))])
    b = tool_axes(n, f, 0.0, math.radians(5))[0]
    assert b[1] == pytest.approx(math.sin(math.radians(5)))  # towards the side n x f = +y
    assert np.linalg.norm(tool_axes(n, f, 0.3, -0.2)[0]) == pytest.approx(1.0)


def test_surface_path_evaluator_matches_the_vectorised_path():
    surface = dome()
    c = raster(surface, step_over=7e-3, margin=25e-3)[0]
    path = SurfacePath(surface, NurbsCurve(c.control_points, c.weights, c.knots, c.degree))
    ev = path.span_evaluator()
    for t in np.linspace(*path.domain, 37):
        c0, c1, c2 = ev.evaluate(float(t))
        ref = path.derivatives([t], 2)
        np.testing.assert_allclose(c0, ref[0][0], atol=1e-12)
        np.testing.assert_allclose(c1, ref[1][0], atol=1e-9 * np.abs(ref[1]).max())
        np.testing.assert_allclose(c2, ref[2][0], atol=1e-8 * np.abs(ref[2]).max())
        np.testing.assert_allclose(ev.tool_axis(0.1, 0.05), path.axes([t], 0.1, 0.05)[0], atol=1e-12)


def test_surface_records_round_trip():
    surface = dome()
    c = raster(surface, step_over=7e-3, margin=25e-3)[0]
    sdef = SurfaceDef(degree_u=3, degree_v=3, knots_u=tuple(KNOTS), knots_v=tuple(KNOTS),
                      weights=tuple(tuple(r) for r in surface.weights.tolist()),
                      control_net=tuple(tuple(tuple(p) for p in row) for row in surface.control_net.tolist()))
    geo = SurfaceGeometry(surface=sdef, lead=0.01, tilt=-0.02, pivot=(0.0, 0.0, 1.2), offset=(0.0, 0.0, -0.25))
    for record in (geo, SurfaceCurve(c), ForceControlRecord(on=True, params=force_params(profile=((0.0, 20.0), (0.1, 25.0)))),
                   ForceControlRecord(on=False, params=force_params())):
        words = encode(record, 7)
        assert decode(words) == (7, record)
        bad = words.copy()
        bad[len(bad) // 2] ^= 0x10
        with pytest.raises(ValueError):
            decode(bad)


class _Pad:
    """A pad spring of k [N/m] under a first-order position loop (tau [s]): the force loop's plant."""

    def __init__(self, k=5000.0, tau=0.02, gap=2e-3, period=1e-3):
        self.k, self.tau, self.gap, self.period, self.x = k, tau, gap, period, -gap

    def step(self, depth: float) -> float:
        self.x += (depth - self.x) * self.period / self.tau
        return max(0.0, self.x) * self.k


def test_force_loop_seeks_ramps_tracks_and_retracts():
    fc = ForceController(1e-3)
    fc.start(force_params())
    pad, force, states, forces = _Pad(), 0.0, [], []
    for _ in range(3000):
        force = pad.step(fc.update(force, 0.0))
        states.append(fc.state)
        forces.append(force)
        if fc.state == ForceState.TRACK and not fc.path_gate and len(states) > 2500:
            break
    assert ForceState.SEEK in states and ForceState.RAMP in states and fc.state == ForceState.TRACK
    tail = np.array(forces[-300:])
    assert abs(tail.mean() - 20.0) < 0.05 and np.max(forces) < 24.0
    fc.stop()
    for _ in range(3000):
        force = pad.step(fc.update(force, 0.0))
        if fc.state == ForceState.OFF:
            break
    assert fc.state == ForceState.OFF and fc.depth == pytest.approx(-2e-3)


def test_force_profile_and_feed_adaptation():
    fc = ForceController(1e-3)
    fc.start(force_params(profile=((0.0, 10.0), (0.1, 30.0))))
    assert fc.setpoint_at(0.05) == pytest.approx(20.0)
    assert fc.setpoint_at(1.0) == 30.0 and fc.setpoint_at(-1.0) == 10.0
    fc.record["state"], fc.record["target"] = ForceState.TRACK, 20.0  # the loop's record, written as a test bench
    fc.update(10.0, 0.05)  # 50 % error: feed cut
    assert fc.feed_factor == 0.5
    for _ in range(10):
        fc.update(fc.target, 0.05)  # calm for 10 ms: not yet (hold 20 ms)
    assert fc.feed_factor == 0.5
    for _ in range(15):
        fc.update(fc.target, 0.05)
    assert fc.feed_factor == 1.0


def test_force_loop_anti_windup_holds_the_clamp():
    fc = ForceController(1e-3)
    fc.start(force_params(max_depth=1e-3))
    fc.record["state"] = ForceState.TRACK
    for _ in range(2000):  # no contact ever: the loop pushes to the clamp and no further
        fc.update(0.0, 0.0)
    assert fc.depth == pytest.approx(1e-3)
    fc.update(40.0, 0.0)  # contact at last: the loop backs off at once, no wound-up integral
    assert fc.depth < 1e-3


def _surface_scenario(**program_changes) -> dict:
    import yaml

    from cnc_twin.scenario.resources import scenarios_dir

    raw = yaml.safe_load((scenarios_dir() / "flat_plate_polish.yaml").read_text())
    for path, value in program_changes.items():
        node = raw["program"]
        keys = path.split(".")
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value
    return raw


@pytest.mark.parametrize("change, key, message", [
    ({"surface.control_net": [[[-80, -60, 0], [-80, 60, 0]], [[80, -60, 0]]]}, "program.surface.control_net",
     "rectangular grid"),
    ({"surface.knots_u": [0, 0.5, 1, 1]}, "program.surface.knots_u", "clamped"),
    ({"surface.weights": [[1, 1], [1, -1]]}, "program.surface.weights", "> 0"),
    ({"path.margin": 70.0}, "program.path.margin", "no area"),
    ({"surface.control_net": [[[-80, -60, 500], [-80, 60, 500]], [[80, -60, 500], [80, 60, 500]]]},
     "program.path", "outside its travel"),
    ({"spindle": 5000.0}, "program.spindle", "exceeds"),
    ({"force.profile": [[0, 20], [0, 25]]}, "program.force.profile", "increase"),
])
def test_bad_surface_programs_are_refused_with_the_key(change, key, message):
    from cnc_twin.core.errors import ScenarioError
    from cnc_twin.scenario.load import scenario_from_dict

    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(_surface_scenario(**change))
    assert info.value.key_path == key
    assert message in str(info.value)


def test_a_face_tilted_beyond_the_head_is_refused_before_motion():
    """A wall (normals horizontal) cannot be reached with |B| < 90 deg: refused at load."""
    from cnc_twin.core.errors import ScenarioError
    from cnc_twin.scenario.load import scenario_from_dict

    wall = [[[-80, 0, -30], [-80, 0, 30]], [[80, 0, -30], [80, 0, 30]]]
    with pytest.raises(ScenarioError, match="unreachable: tool axis") as info:
        scenario_from_dict(_surface_scenario(**{"surface.control_net": wall, "path.margin": 20.0}))
    assert info.value.key_path == "program.path"


def test_a_surface_too_large_for_the_cards_geometry_memory_is_refused():
    from cnc_twin.core.errors import ScenarioError
    from cnc_twin.scenario.load import scenario_from_dict

    n = 40
    net = [[[-80 + 160 * i / (n - 1), -60 + 120 * j / (n - 1), 0] for j in range(n)] for i in range(n)]
    knots = [0, 0] + [k / (n - 1) for k in range(1, n - 1)] + [1, 1]
    change = {"surface.control_net": net, "surface.knots_u": knots, "surface.knots_v": knots}
    with pytest.raises(ScenarioError, match="exceeds the card's geometry memory") as info:
        scenario_from_dict(_surface_scenario(**change))
    assert info.value.key_path == "program.surface.control_net"

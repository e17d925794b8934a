"""The card's span evaluation (cnc_twin/geometry/span_eval.py) on surface paths, against scipy's
B-splines (:class:`SurfacePath`, :class:`NurbsSurface`: points, derivatives, tangents, tool
axes), on a rational multi-patch surface and on the freeform scenario's face; and the stepper on
a surface path, compiled and from its Python source, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin import load_scenario
from cnc_twin.dsp.curve_stepper import CurveStepper
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.geometry.surface import NurbsSurface
from cnc_twin.geometry.surface_path import SurfacePath, SurfacePathEvaluator, tool_axis_at
from cnc_twin.scenario.resources import scenarios_dir


def _rational_surface(rng) -> NurbsSurface:
    """Bicubic-by-quadratic, 3 x 3 patches, a repeated knot, weights 0.5-2: every branch of the
    patch lookup and of the quotient rule."""
    nu, nv = 6, 5
    u, v = np.meshgrid(np.linspace(0, 0.1, nu), np.linspace(0, 0.08, nv), indexing="ij")
    net = np.stack([u, v, 0.01 * rng.standard_normal((nu, nv))], axis=-1)
    weights = rng.uniform(0.5, 2.0, (nu, nv))
    return NurbsSurface(net, weights, [0, 0, 0, 0, 0.3, 0.7, 1, 1, 1, 1], [0, 0, 0, 0.4, 0.4, 1, 1, 1], 3, 2)


def _uv_curve(rng) -> NurbsCurve:
    """A wiggly (u, v) curve of degree 3 inside the unit square, rational, 4 spans."""
    points = np.column_stack([np.linspace(0.05, 0.95, 7), 0.5 + 0.3 * rng.uniform(-1, 1, 7)])
    return NurbsCurve(points, rng.uniform(0.7, 1.4, 7), [0, 0, 0, 0, 0.2, 0.5, 0.6, 1, 1, 1, 1], 3)


def _freeform_surface() -> NurbsSurface:
    program = load_scenario(scenarios_dir() / "freeform_polish.yaml").program
    return NurbsSurface.from_def(program.surface)


@pytest.mark.parametrize("seed", range(4))
def test_the_path_evaluation_is_scipys(seed):
    rng = np.random.default_rng(seed)
    surface = _rational_surface(rng) if seed else _freeform_surface()
    uv = _uv_curve(rng)
    ev, path = SurfacePathEvaluator(surface.span_evaluator(), uv.span_evaluator()), SurfacePath(surface, uv)
    ts = np.concatenate([rng.uniform(0, 1, 200), [0.0, 0.2, 0.5, 0.6, 1.0]])
    ref = path.derivatives(ts, 2)
    scale = [np.abs(r).max() for r in ref]
    for k, t in enumerate(ts):
        c, c1, c2 = ev.evaluate(float(t))
        np.testing.assert_allclose(c, ref[0][k], rtol=0, atol=1e-12 * scale[0])
        np.testing.assert_allclose(c1, ref[1][k], rtol=0, atol=1e-10 * scale[1])
        np.testing.assert_allclose(c2, ref[2][k], rtol=0, atol=1e-8 * scale[2])
        assert ev.speed(float(t)) == pytest.approx(np.linalg.norm(ref[1][k]), rel=1e-10)
        u, v = uv.point([t])[0]
        d = surface.derivatives([u], [v], 1)
        np.testing.assert_allclose(ev.last_su, d[1, 0][0], rtol=0, atol=1e-10 * np.abs(d[1, 0]).max())
        np.testing.assert_allclose(ev.last_sv, d[0, 1][0], rtol=0, atol=1e-10 * np.abs(d[0, 1]).max())
        for lead, tilt in ((0.0, 0.0), (0.05, -0.02)):
            np.testing.assert_allclose(ev.tool_axis(lead, tilt), path.axes([t], lead, tilt)[0], atol=1e-9)
    # outside the domain: clamped to its ends
    assert ev.evaluate(-0.1)[0] == ev.evaluate(0.0)[0] and ev.evaluate(1.1)[0] == ev.evaluate(1.0)[0]


@pytest.mark.parametrize("seed", range(3))
def test_the_stepper_walks_a_surface_path_compiled_as_from_its_source(seed):
    """Steps of 0.01-2 mm, as a feed ramp gives them, to the path's end; the kept tangents and
    the tool axis from them, with lead and tilt; and on the freeform face each step's length,
    against scipy's. (The rational surface's v knots repeat 0.4, a crease: a step across it is off
    by up to 0.2 % of its length, since the stepper splits its Simpson rule at the (u, v) curve's
    knots only, not where the path crosses the surface's knot lines.)"""
    rng = np.random.default_rng(10 + seed)
    surface = _rational_surface(rng) if seed else _freeform_surface()
    uv = _uv_curve(rng)
    ev, path = SurfacePathEvaluator(surface.span_evaluator(), uv.span_evaluator()), SurfacePath(surface, uv)
    python, compiled = CurveStepper(ev, 0.0, compiled=False), CurveStepper(ev, 0.0)
    steps = 0
    while python.u < python.u_end:
        ds = float(rng.choice([1e-5, 2e-4, 2e-3])) * rng.uniform(0.5, 1.0)
        u0 = compiled.u
        assert compiled.step(ds) == python.step(ds)
        assert compiled.u == python.u and compiled.tangents() == python.tangents()
        if seed == 0 and compiled.u < compiled.u_end:  # the rational surface has a crease (below)
            assert path.arc_length(u0, compiled.u) == pytest.approx(ds, rel=1e-6)
        su, sv, c1 = compiled.tangents()
        for lead, tilt in ((0.0, 0.0), (0.05, -0.02)):
            np.testing.assert_allclose(tool_axis_at(su, sv, c1, lead, tilt), path.axes([compiled.u], lead, tilt)[0],
                                       atol=1e-9)
        steps += 1
    assert compiled.u == compiled.u_end and steps > 50

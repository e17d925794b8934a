"""The compiled surface-path evaluation and stepper (cnc_twin/dsp/span_kernel.py, curve_kernel.py)
against the Python evaluators and stepper: the same points, derivatives, tangents and tool axes,
bit for bit, on a rational multi-patch surface and on the freeform scenario's face."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin import load_scenario
from cnc_twin.dsp import span_kernel
from cnc_twin.dsp.curve_kernel import CompiledCurveStepper, path_args
from cnc_twin.dsp.curve_stepper import CurveStepper
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.geometry.surface import NurbsSurface
from cnc_twin.geometry.surface_path import SurfacePathEvaluator, tool_axis_at
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
def test_the_compiled_path_evaluation_is_the_python_one_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    surface = _rational_surface(rng) if seed else _freeform_surface()
    ev = SurfacePathEvaluator(surface.span_evaluator(), _uv_curve(rng).span_evaluator())
    args = path_args(ev)
    w, c, c1, c2, tangents = np.zeros(span_kernel.WORK), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(6)
    for t in np.concatenate([rng.uniform(0, 1, 300), [0.0, 0.2, 0.5, 0.6, 1.0, -0.1, 1.1]]):
        want = ev.evaluate(t)
        span_kernel.path_evaluate(args, t, w, c, c1, c2, tangents)
        assert [c.tolist(), c1.tolist(), c2.tolist()] == [list(x) for x in want]
        assert tangents.tolist() == [*ev.last_su, *ev.last_sv]
        assert span_kernel.path_speed(args, t, w) == ev.speed(t)
        assert span_kernel.next_break(args, t) == ev.next_break(t)
    # the surface alone: the numpy block sum and the compiled one
    sev = surface.span_evaluator()
    s = np.zeros(18)
    for u, v in rng.uniform(-0.05, 1.05, (200, 2)):
        span_kernel.surface_evaluate(sev.starts_u, sev.starts_v, sev.patches, sev.degree_u, sev.degree_v,
                                     args[-1], u, v, w, s)
        assert s.tolist() == [x for part in sev.evaluate(u, v) for x in part]


@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_stepper_walks_a_surface_path_as_the_python_one(seed):
    """Steps of 0.01-2 mm, as a feed ramp gives them, to the path's end; and the tool axis from the
    kept tangents, with lead and tilt."""
    rng = np.random.default_rng(10 + seed)
    surface = _rational_surface(rng) if seed else _freeform_surface()
    ev = SurfacePathEvaluator(surface.span_evaluator(), _uv_curve(rng).span_evaluator())
    python, compiled = CurveStepper(ev, 0.0), CompiledCurveStepper(ev, 0.0)
    steps = 0
    while python.u < python.u_end:
        ds = float(rng.choice([1e-5, 2e-4, 2e-3])) * rng.uniform(0.5, 1.0)
        assert compiled.step(ds) == python.step(ds)
        assert compiled.u == python.u
        su, sv, c1 = compiled.tangents()
        assert (su, sv, c1) == (list(ev.last_su), list(ev.last_sv), list(ev.last_c1))
        for lead, tilt in ((0.0, 0.0), (0.05, -0.02)):
            assert tool_axis_at(su, sv, c1, lead, tilt) == ev.tool_axis(lead, tilt)
        steps += 1
    assert compiled.u == compiled.u_end and steps > 50

"""A tool path on a NURBS surface: a (u, v) curve composed with the surface, and its tool axis.

A path section is a 2-D NURBS ``Q(t) = (u(t), v(t))`` in the surface's parameter space; the tool
tip runs on ``C(t) = S(Q(t))``. Its derivatives follow from the chain rule (``'`` is d/dt)::

    C'  = S_u u' + S_v v'
    C'' = S_uu u'^2 + 2 S_uv u' v' + S_vv v'^2 + S_u u'' + S_v v''

so a surface path offers what the feed planner and the card's curve stepper use of a curve
(points, first and second derivatives, arc length, knot breaks) without ever being converted to
a space curve: the card interpolates on the surface itself.

Tool axis (unit vector from the tip up the tool): the surface normal ``n`` (pointing out of the
material), leaned by ``lead`` towards the feed direction ``f`` (the unit tangent) and by ``tilt``
towards the side ``s = n x f``::

    axis = (n cos(lead) + f sin(lead)) cos(tilt) + s sin(tilt)

``n``, ``f`` and ``s`` are orthonormal, so ``axis`` is a unit vector for any angles.
Units: whatever the surface is in (the twin uses metres, world frame); angles in rad.
"""

from __future__ import annotations

import math

import numpy as np

from cnc_twin.geometry.nurbs import NurbsCurve, SpanEvaluator, gauss_length
from cnc_twin.geometry.surface import NurbsSurface, SurfaceSpanEvaluator


def tool_axes(normal: np.ndarray, tangent: np.ndarray, lead: float, tilt: float) -> np.ndarray:
    """Tool axes (m, 3) from surface normals and path tangents (both (m, 3)); see the module doc."""
    n = normal / np.linalg.norm(normal, axis=-1, keepdims=True)
    f = tangent - np.sum(tangent * n, axis=-1, keepdims=True) * n
    f = f / np.linalg.norm(f, axis=-1, keepdims=True)
    s = np.cross(n, f)
    return (n * math.cos(lead) + f * math.sin(lead)) * math.cos(tilt) + s * math.sin(tilt)


class SurfacePath:
    """One path section on a surface, with the curve interface the feed planner uses.

    Parameters
    ----------
    surface : the surface.
    uv : the section as a 2-D NURBS curve in (u, v); its parameter ``t`` is the path's.
    """

    def __init__(self, surface: NurbsSurface, uv: NurbsCurve):
        if uv.dim != 2:
            raise ValueError("a surface path's (u, v) curve must be 2-D")
        self.surface = surface
        self.uv = uv
        self.knots = uv.knots
        self.degree = uv.degree

    @property
    def domain(self) -> tuple[float, float]:
        return self.uv.domain

    def derivatives(self, t, order: int = 2) -> list[np.ndarray]:
        """``[C, C', C'']`` (up to ``order`` <= 2) at parameters ``t`` (m,), each (m, 3)."""
        if order > 2:
            raise ValueError("surface paths give derivatives up to second order")
        q = self.uv.derivatives(np.atleast_1d(np.asarray(t, dtype=np.float64)), order)
        d = self.surface.derivatives(q[0][:, 0], q[0][:, 1], order)
        out = [d[(0, 0)]]
        if order >= 1:
            u1, v1 = q[1][:, :1], q[1][:, 1:]
            out.append(d[(1, 0)] * u1 + d[(0, 1)] * v1)
        if order >= 2:
            u2, v2 = q[2][:, :1], q[2][:, 1:]
            out.append(d[(2, 0)] * u1 * u1 + 2.0 * d[(1, 1)] * u1 * v1 + d[(0, 2)] * v1 * v1
                       + d[(1, 0)] * u2 + d[(0, 1)] * v2)
        return out

    def point(self, t) -> np.ndarray:
        """Tip points (m, 3)."""
        return self.derivatives(t, 0)[0]

    def normals(self, t) -> np.ndarray:
        """Unit surface normals under the path (m, 3), pointing out of the material."""
        q = self.uv.point(np.atleast_1d(np.asarray(t, dtype=np.float64)))
        return self.surface.normal(q[:, 0], q[:, 1])

    def axes(self, t, lead: float = 0.0, tilt: float = 0.0) -> np.ndarray:
        """Tool axes (m, 3) along the path."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        return tool_axes(self.normals(t), self.derivatives(t, 1)[1], lead, tilt)

    def arc_length(self, t0: float | None = None, t1: float | None = None) -> float:
        """Length between parameters (the whole section by default): Gauss-Legendre per knot span."""
        a, b = self.domain
        t0 = a if t0 is None else float(t0)
        t1 = b if t1 is None else float(t1)
        if t1 < t0:
            return -self.arc_length(t1, t0)
        # Each knot span in 16 pieces: the surface's own knot lines cross the spans, and |C'|
        # is only C1 there, which a single Gauss rule per span would integrate to ~1e-5.
        return gauss_length(lambda t: self.derivatives(t, 1)[1], self.knots, t0, t1, pieces=16)

    def span_evaluator(self) -> "SurfacePathEvaluator":
        return SurfacePathEvaluator(self.surface.span_evaluator(), self.uv.span_evaluator())


class SurfacePathEvaluator:
    """Scalar ``C, C', C''`` of a surface path for the card's per-period stepper.

    Same interface as :class:`~cnc_twin.geometry.nurbs.SpanEvaluator` (``path``, ``dim``,
    ``domain``, ``evaluate``, ``speed``, ``next_break``); the compiled functions of
    :mod:`cnc_twin.geometry.span_eval` do the work. :meth:`evaluate` also keeps the surface
    tangents of the point it evaluated (``last_su``, ``last_sv``, ``last_c1``), for the tool axis
    of that point.
    """

    dim = 3
    """the points' dimension"""

    def __init__(self, surface: SurfaceSpanEvaluator, uv: SpanEvaluator):
        self.surface = surface
        self.uv = uv
        self.domain = uv.domain
        self.path = (*uv.path[:5], *surface.patch_args)
        """the path as :mod:`~cnc_twin.geometry.span_eval`'s ``ev`` tuple"""
        self.last_su = self.last_sv = self.last_c1 = (0.0, 0.0, 0.0)

    def next_break(self, t: float) -> float:
        return self.uv.next_break(t)

    def evaluate(self, t: float) -> tuple[list[float], list[float], list[float]]:
        """``(C, C', C'')`` at scalar ``t`` as float lists of length 3."""
        from cnc_twin.geometry.span_eval import WORK, path_evaluate

        c, c1, c2, tangents = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(6)
        path_evaluate(self.path, float(t), np.zeros(WORK), c, c1, c2, tangents)
        tangents = tangents.tolist()
        self.last_su, self.last_sv, self.last_c1 = tangents[:3], tangents[3:], c1.tolist()
        return c.tolist(), self.last_c1, c2.tolist()

    def speed(self, t: float) -> float:
        """``|C'(t)|``; leaves the kept tangents alone (the stepper calls it between points)."""
        from cnc_twin.geometry.span_eval import WORK, path_speed

        return float(path_speed(self.path, float(t), np.zeros(WORK)))

    def tool_axis(self, lead: float, tilt: float) -> tuple[float, float, float]:
        """The tool axis at the last evaluated point (see the module docstring)."""
        return tool_axis_at(self.last_su, self.last_sv, self.last_c1, lead, tilt)


def tool_axis_at(su, sv, c1, lead: float, tilt: float) -> tuple[float, float, float]:
    """The tool axis (unit, 3 floats) from the surface tangents ``su``, ``sv`` and the path's
    ``c1 = C'`` at a point (3 floats each), with ``lead`` and ``tilt`` [rad] (module docstring)."""
    leaned = lead != 0.0 or tilt != 0.0
    return tool_axis_leaned(su, sv, c1, math.cos(lead), math.sin(lead), math.cos(tilt), math.sin(tilt), leaned)


def tool_axis_leaned(su, sv, c1, cos_lead: float, sin_lead: float, cos_tilt: float, sin_tilt: float,
                     leaned: bool) -> tuple[float, float, float]:
    """:func:`tool_axis_at` with the lead's and tilt's cosines and sines given (the batch kernel
    computes them once per path and compiles this function: one implementation); ``leaned``
    False gives the normal itself."""
    nx, ny, nz = su[1] * sv[2] - su[2] * sv[1], su[2] * sv[0] - su[0] * sv[2], su[0] * sv[1] - su[1] * sv[0]
    if nz < 0.0:  # out of the material: up
        nx, ny, nz = -nx, -ny, -nz
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx * inv, ny * inv, nz * inv
    if not leaned:
        return nx, ny, nz
    dot = c1[0] * nx + c1[1] * ny + c1[2] * nz
    fx, fy, fz = c1[0] - dot * nx, c1[1] - dot * ny, c1[2] - dot * nz
    inv = 1.0 / math.sqrt(fx * fx + fy * fy + fz * fz)
    fx, fy, fz = fx * inv, fy * inv, fz * inv
    sx, sy, sz = ny * fz - nz * fy, nz * fx - nx * fz, nx * fy - ny * fx
    cl, sl, ct, st = cos_lead, sin_lead, cos_tilt, sin_tilt
    return ((nx * cl + fx * sl) * ct + sx * st, (ny * cl + fy * sl) * ct + sy * st,
            (nz * cl + fz * sl) * ct + sz * st)

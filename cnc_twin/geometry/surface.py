"""NURBS surfaces: validated construction, points, partial derivatives, normals, area, meshes.

A NURBS surface of degrees ``(p, q)`` with a control net ``P_ij`` (shape ``(nu, nv, 3)``),
weights ``w_ij > 0`` and clamped knot vectors ``U`` (``nu + p + 1`` knots) and ``V``
(``nv + q + 1`` knots) is the projection of the tensor-product B-spline
``A(u, v) = sum_ij N_i,p(u) M_j,q(v) [w_ij P_ij, w_ij]`` in homogeneous coordinates. The basis
functions come from scipy's B-spline machinery; the rational partials follow from the quotient
rule (subscripts are partial derivatives)::

    S    = A / w
    S_u  = (A_u - w_u S) / w
    S_v  = (A_v - w_v S) / w
    S_uu = (A_uu - 2 w_u S_u - w_uu S) / w
    S_uv = (A_uv - w_u S_v - w_v S_u - w_uv S) / w
    S_vv = (A_vv - 2 w_v S_v - w_vv S) / w

Normal convention: :meth:`NurbsSurface.normal` is the unit ``S_u x S_v`` flipped where needed
so that its z component is non-negative, i.e. it points "up", away from the material, for a
surface given as a height field over the table. A normal whose z component is zero up to
rounding (``|n_z| <= 1e-12``, a vertical wall) keeps the sign of ``S_u x S_v``, so rounding
noise cannot flip it. At a degenerate point (``S_u x S_v = 0``, e.g. a collapsed edge) the
normal is undefined and returned as nan.

For the DSP's per-period work, :class:`SurfaceSpanEvaluator` holds each patch's power-basis
coefficients of ``A`` and its five partials in one block, so a point with its first and second
partials costs one pass over the block's rows (compiled: :mod:`cnc_twin.geometry.span_eval`).

Units are whatever the control net is in (the twin uses metres).
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from cnc_twin.geometry.nurbs import NurbsError

# (i, j) = orders of differentiation in (u, v), in the order evaluate() returns them
_PARTIALS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
_FLAT_Z = 1e-12  # |n_z| of a unit normal below which the normal counts as horizontal


def _check_knots(key: str, knots, n: int, p: int) -> np.ndarray:
    U = np.asarray(knots, dtype=np.float64)
    if U.shape != (n + p + 1,):
        raise NurbsError(key, f"expected n + degree + 1 = {n} + {p} + 1 = {n + p + 1} knots, got {U.size}")
    if not np.all(np.isfinite(U)) or np.any(np.diff(U) < 0):
        raise NurbsError(key, "knots must be finite and non-decreasing")
    if np.any(U[: p + 1] != U[0]) or np.any(U[-(p + 1):] != U[-1]):
        raise NurbsError(key, f"knot vector must be clamped: first and last {p + 1} knots equal")
    if not U[-1] > U[0]:
        raise NurbsError(key, "knot vector spans no parameter range")
    interior = U[p + 1:n]
    if interior.size and np.max(np.unique(interior, return_counts=True)[1]) > p:
        raise NurbsError(key, f"an interior knot repeats more than degree = {p} times")
    return U


def _orient_up(n: np.ndarray) -> np.ndarray:
    """Unit normals ``(m, 3)`` from ``S_u x S_v``, flipped to ``z >= 0`` (module docstring)."""
    length = np.linalg.norm(n, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / length
    return np.where(n[:, 2:3] < -_FLAT_Z, -n, n)


PLANAR_TOLERANCE = 1e-9
"""[m] how far from their best-fitting plane control points may lie for a surface to count as flat"""


def control_net_is_planar(control_net, tolerance: float = PLANAR_TOLERANCE) -> bool:
    """Whether a NURBS surface with this control net (shape ``(nu, nv, 3)`` [m]) is a piece of a
    plane: every control point within ``tolerance`` [m] of the points' best-fitting plane (the
    surface lies in its control points' convex hull, whatever the weights)."""
    points = np.asarray(control_net, dtype=np.float64).reshape(-1, 3)
    centred = points - points.mean(axis=0)
    normal = np.linalg.svd(centred)[2][-1]  # the direction the points spread least along
    return bool(np.max(np.abs(centred @ normal)) <= tolerance)


class NurbsSurface:
    """A clamped tensor-product NURBS surface in 3-D.

    Parameters
    ----------
    control_net
        shape ``(nu, nv, 3)``, a rectangular grid of points; ``u`` runs along axis 0.
    weights
        shape ``(nu, nv)``, all > 0; None for a non-rational B-spline surface (all 1).
    knots_u, knots_v
        shapes ``(nu + degree_u + 1,)`` and ``(nv + degree_v + 1,)``;
        non-decreasing, clamped, interior multiplicity <= degree.
    degree_u, degree_v
        >= 1.

    Raises
    ------
    NurbsError
        With ``key`` one of ``degree_u``, ``degree_v``, ``control_net``, ``weights``,
        ``knots_u``, ``knots_v``.
    """

    def __init__(self, control_net, weights, knots_u, knots_v, degree_u: int, degree_v: int):
        p, q = int(degree_u), int(degree_v)
        if p < 1:
            raise NurbsError("degree_u", f"degree_u must be >= 1, got {degree_u}")
        if q < 1:
            raise NurbsError("degree_v", f"degree_v must be >= 1, got {degree_v}")
        try:
            P = np.asarray(control_net, dtype=np.float64)
        except ValueError:  # ragged nested lists
            raise NurbsError("control_net", "control net is not a rectangular grid of 3-D points") from None
        if P.ndim != 3 or P.shape[2] != 3:
            raise NurbsError("control_net", f"expected a rectangular grid of 3-D points, shape (nu, nv, 3), "
                                            f"got shape {P.shape}")
        nu, nv = P.shape[:2]
        if nu < p + 1 or nv < q + 1:
            raise NurbsError("control_net", f"degrees ({p}, {q}) need at least a {p + 1} x {q + 1} control net, "
                                            f"got {nu} x {nv}")
        if not np.all(np.isfinite(P)):
            raise NurbsError("control_net", "control points must be finite")
        try:
            W = np.ones((nu, nv)) if weights is None else np.asarray(weights, dtype=np.float64)
        except ValueError:
            raise NurbsError("weights", f"expected a {nu} x {nv} grid of weights, got a ragged list") from None
        if W.shape != (nu, nv):
            raise NurbsError("weights", f"expected a {nu} x {nv} grid of weights (one per control point), "
                                        f"got shape {W.shape}")
        if not np.all(np.isfinite(W)) or np.any(W <= 0):
            raise NurbsError("weights", "weights must be finite and > 0")
        self.knots_u = _check_knots("knots_u", knots_u, nu, p)
        self.knots_v = _check_knots("knots_v", knots_v, nv, q)
        self.degree_u, self.degree_v = p, q
        self.control_net = P
        self.weights = W
        self.domain_u = (float(self.knots_u[0]), float(self.knots_u[-1]))
        self.domain_v = (float(self.knots_v[0]), float(self.knots_v[-1]))
        self._homogeneous_net = np.concatenate([P * W[..., None], W[..., None]], axis=2)  # (nu, nv, 4)
        # Basis functions as the columns of an identity-coefficient spline. Parameters are clipped
        # to the domain first, so extrapolate=True only matters at the last knot, where it pins the
        # last span on every scipy version. __call__(x, nu=k) differentiates the polynomial piece
        # of the span holding x, so repeated interior knots are fine.
        from scipy.interpolate import BSpline  # here: importing scipy.interpolate takes 0.4 s

        self._basis_u = BSpline(self.knots_u, np.eye(nu), p, extrapolate=True)
        self._basis_v = BSpline(self.knots_v, np.eye(nv), q, extrapolate=True)

    @classmethod
    def from_def(cls, d) -> "NurbsSurface":
        """From a :class:`cnc_twin.core.config.SurfaceDef` (or anything with its six fields)."""
        return cls(d.control_net, d.weights, d.knots_u, d.knots_v, d.degree_u, d.degree_v)

    def _basis(self, which: str, x: np.ndarray, order: int) -> list[np.ndarray]:
        spline, degree = (self._basis_u, self.degree_u) if which == "u" else (self._basis_v, self.degree_v)
        n = spline.c.shape[1]
        return [spline(x, nu=k) if k <= degree else np.zeros((x.size, n)) for k in range(order + 1)]

    def derivatives(self, u, v, order: int = 2) -> dict[tuple[int, int], np.ndarray]:
        """Point and partials at paired parameters ``u``, ``v`` (shape ``(m,)``, clamped to the domain).

        Returns a dict keyed by ``(i, j)``, ``i + j <= order`` (order <= 2), holding
        ``d^(i+j) S / du^i dv^j``, each ``(m, 3)`` [unit / parameter^(i+j)].
        """
        if not 0 <= order <= 2:
            raise ValueError("derivatives up to second order")
        u = np.atleast_1d(np.asarray(u, dtype=np.float64))
        v = np.atleast_1d(np.asarray(v, dtype=np.float64))
        if u.shape != v.shape or u.ndim != 1:
            raise ValueError(f"u and v must be paired 1-D arrays, got shapes {u.shape} and {v.shape}")
        Bu = self._basis("u", np.clip(u, *self.domain_u), order)
        Bv = self._basis("v", np.clip(v, *self.domain_v), order)
        nu, nv = self._homogeneous_net.shape[:2]
        net = self._homogeneous_net.reshape(nu, nv * 4)
        A, w = {}, {}
        for i in range(order + 1):
            partial = (Bu[i] @ net).reshape(-1, nv, 4)  # contracted in u, still a row per v basis
            for j in range(order + 1 - i):
                h = np.einsum("mj,mjc->mc", Bv[j], partial)
                A[i, j], w[i, j] = h[:, :3], h[:, 3:]
        S = {(0, 0): A[0, 0] / w[0, 0]}
        inv = 1.0 / w[0, 0]
        if order >= 1:
            S[1, 0] = (A[1, 0] - w[1, 0] * S[0, 0]) * inv
            S[0, 1] = (A[0, 1] - w[0, 1] * S[0, 0]) * inv
        if order >= 2:
            S[2, 0] = (A[2, 0] - 2 * w[1, 0] * S[1, 0] - w[2, 0] * S[0, 0]) * inv
            S[1, 1] = (A[1, 1] - w[1, 0] * S[0, 1] - w[0, 1] * S[1, 0] - w[1, 1] * S[0, 0]) * inv
            S[0, 2] = (A[0, 2] - 2 * w[0, 1] * S[0, 1] - w[0, 2] * S[0, 0]) * inv
        return S

    def point(self, u, v) -> np.ndarray:
        """Points at ``(u, v)``, shape ``(m, 3)``."""
        return self.derivatives(u, v, 0)[0, 0]

    def normal(self, u, v) -> np.ndarray:
        """Unit normals at ``(u, v)``, shape ``(m, 3)``, z >= 0 (convention in the module docstring)."""
        d = self.derivatives(u, v, 1)
        return _orient_up(np.cross(d[1, 0], d[0, 1]))

    def grid(self, nu: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(U, V, P)``: parameter grids ``(nu, nv)`` evenly spaced over the domains, points ``(nu, nv, 3)``."""
        U, V = np.meshgrid(np.linspace(*self.domain_u, nu), np.linspace(*self.domain_v, nv), indexing="ij")
        return U, V, self.point(U.ravel(), V.ravel()).reshape(nu, nv, 3)

    def tessellate(self, nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
        """Triangle mesh over a ``nu x nv`` parameter grid (each >= 2).

        Returns vertices ``(nu * nv, 3)`` (vertex ``i * nv + j`` is grid point ``(i, j)``) and faces
        ``(2 (nu - 1) (nv - 1), 3)`` int32. Faces are wound like ``S_u x S_v`` and then, by the
        rule of :meth:`normal`, reversed where that face normal points down, so face normals agree
        with the vertex normals and, on any surface whose up side is consistent (a height field),
        the winding is consistent too.
        """
        if nu < 2 or nv < 2:
            raise ValueError(f"tessellate needs at least a 2 x 2 grid, got {nu} x {nv}")
        vertices = self.grid(nu, nv)[2].reshape(-1, 3)
        idx = np.arange(nu * nv).reshape(nu, nv)
        a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]  # (i,j) (i+1,j) (i+1,j+1) (i,j+1)
        faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
        tri = vertices[faces]
        face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        flip = face_n[:, 2] < -_FLAT_Z * np.linalg.norm(face_n, axis=1)
        faces[flip] = faces[flip][:, ::-1]
        return vertices, faces.astype(np.int32)

    def area(self, n: int = 64) -> float:
        """Surface area: ``n x n``-point Gauss-Legendre quadrature of ``|S_u x S_v|`` per knot-span patch."""
        nodes, weights = np.polynomial.legendre.leggauss(n)
        ku, kv = np.unique(self.knots_u), np.unique(self.knots_v)
        total = 0.0
        for u0, u1 in zip(ku[:-1], ku[1:]):
            for v0, v1 in zip(kv[:-1], kv[1:]):
                hu, hv = 0.5 * (u1 - u0), 0.5 * (v1 - v0)
                U, V = np.meshgrid(0.5 * (u0 + u1) + hu * nodes, 0.5 * (v0 + v1) + hv * nodes, indexing="ij")
                d = self.derivatives(U.ravel(), V.ravel(), 1)
                dA = np.linalg.norm(np.cross(d[1, 0], d[0, 1]), axis=1).reshape(n, n)
                total += hu * hv * float(weights @ dA @ weights)
        return total

    def span_evaluator(self) -> "SurfaceSpanEvaluator":
        return SurfaceSpanEvaluator(self)


class SurfaceSpanEvaluator:
    """Fast scalar evaluation of ``S`` and its first and second partials for the DSP.

    Each patch ``[u_i, u_i+1) x [v_j, v_j+1)`` (distinct knots) has the power-basis coefficients
    ``H[a, b, :]`` (shape ``(p + 1, q + 1, 4)``) of ``A(x, y) = sum_ab H[a, b] x^a y^b`` with
    ``x = u - u_i``, ``y = v - v_j``: the tensor product of the basis functions' right-hand Taylor
    coefficients at the patch corner, so exact. The evaluation block ``((p + 1)(q + 1), 24)``
    holds the coefficients of ``A`` and its five partials side by side (shifted and scaled
    ``H``), so one evaluation = the ``x^a y^b`` products, the block's rows scaled by them and
    summed in row order, the quotient rule on plain floats.
    """

    def __init__(self, surface: NurbsSurface):
        p, q = surface.degree_u, surface.degree_v
        self.degree_u, self.degree_v = p, q
        self.domain_u, self.domain_v = surface.domain_u, surface.domain_v
        starts_u = [float(k) for k in np.unique(surface.knots_u)[:-1]]
        starts_v = [float(k) for k in np.unique(surface.knots_v)[:-1]]

        def taylor(spline, s, degree):  # (degree + 1, n): row a = N^(a)(s) / a!, right-hand at a knot
            return np.array([spline(s, nu=a) / math.factorial(a) for a in range(degree + 1)])

        Tu = [taylor(surface._basis_u, s, p) for s in starts_u]
        Tv = [taylor(surface._basis_v, s, q) for s in starts_v]
        net = surface._homogeneous_net
        self.coefficients = [[np.einsum("ai,bj,ijc->abc", tu, tv, net) for tv in Tv] for tu in Tu]
        self.patches = np.ascontiguousarray(np.array([[self._block(H) for H in row] for row in self.coefficients]))
        """the patches' evaluation blocks, shape ``(spans_u, spans_v, (p + 1)(q + 1), 24)``"""
        self.starts_u, self.starts_v = np.array(starts_u), np.array(starts_v)
        """the patches' first parameters, shapes ``(spans_u,)`` and ``(spans_v,)``"""

    @staticmethod
    def _block(H: np.ndarray) -> np.ndarray:
        p1, q1 = H.shape[:2]
        parts = []
        for i, j in _PARTIALS:
            C = np.zeros_like(H)
            a, b = np.arange(p1 - i), np.arange(q1 - j)
            scale = np.outer([math.perm(k + i, i) for k in a], [math.perm(k + j, j) for k in b])
            C[: p1 - i, : q1 - j] = H[i:, j:] * scale[..., None]
            parts.append(C)
        return np.ascontiguousarray(np.concatenate(parts, axis=2).reshape(p1 * q1, 24))

    def evaluate(self, u: float, v: float) -> tuple[list[float], ...]:
        """``(S, S_u, S_v, S_uu, S_uv, S_vv)`` at scalar ``(u, v)`` (clamped), each a list of 3
        floats (:func:`cnc_twin.geometry.span_eval.surface_evaluate`)."""
        from cnc_twin.geometry.span_eval import surface_evaluate

        s = np.zeros(18)
        surface_evaluate(*self.patch_args, float(u), float(v), np.zeros(24), s)
        s = s.tolist()
        return tuple(s[3 * k:3 * k + 3] for k in range(6))

    @cached_property
    def patch_args(self) -> tuple:
        """The surface's part of :mod:`~cnc_twin.geometry.span_eval`'s ``ev`` tuple: patch starts,
        blocks, degrees and the domain box ``(u0, u1, v0, v1)`` (made once: every evaluation
        passes it)."""
        return (self.starts_u, self.starts_v, self.patches, self.degree_u, self.degree_v,
                np.array([*self.domain_u, *self.domain_v], dtype=np.float64))

    def normal(self, u: float, v: float) -> list[float]:
        """Unit normal at scalar ``(u, v)`` (clamped), z >= 0 as :meth:`NurbsSurface.normal`."""
        _, a, b, _, _, _ = self.evaluate(u, v)
        n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        length = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        if length == 0.0:
            return [math.nan] * 3
        if n[2] < -_FLAT_Z * length:
            length = -length
        return [c / length for c in n]


def parameter_scales(surface: NurbsSurface, n: int = 24) -> tuple[float, float, float, float]:
    """``(mean |S_u|, mean |S_v|, max |S_u|, max |S_v|)`` over an n x n parameter grid [m per unit]."""
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    u, v = np.meshgrid(np.linspace(u0, u1, n), np.linspace(v0, v1, n), indexing="ij")
    d = surface.derivatives(u.ravel(), v.ravel(), 1)
    su, sv = np.linalg.norm(d[(1, 0)], axis=1), np.linalg.norm(d[(0, 1)], axis=1)
    return float(su.mean()), float(sv.mean()), float(su.max()), float(sv.max())

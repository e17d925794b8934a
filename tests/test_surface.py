"""NURBS surfaces: evaluation against an independent reference, exact shapes, validation, meshes."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from cnc_twin.geometry.nurbs import NurbsError
from cnc_twin.geometry.surface import NurbsSurface, SurfaceSpanEvaluator
from test_nurbs import cox_de_boor  # the curves' independent reference, tensor-producted here

S2 = math.sqrt(2.0) / 2.0


def _freeform():
    """Rational bicubic 5 x 6 height-field-like net; non-uniform knots, a double interior knot in v."""
    rng = np.random.default_rng(7)
    x = np.array([0.0, 0.3, 0.9, 1.4, 2.0])
    y = np.array([0.0, 0.2, 0.5, 0.7, 1.2, 1.5])
    X, Y = np.meshgrid(x, y, indexing="ij")
    net = np.stack([X + 0.05 * rng.normal(size=X.shape), Y + 0.05 * rng.normal(size=X.shape),
                    0.3 * rng.normal(size=X.shape)], axis=-1)
    return dict(control_net=net, weights=rng.uniform(0.6, 1.6, size=(5, 6)),
                knots_u=[0, 0, 0, 0, 0.7, 2, 2, 2, 2],
                knots_v=[1, 1, 1, 1, 1.3, 1.3, 2.5, 2.5, 2.5, 2.5], degree_u=3, degree_v=3)


FREEFORM = _freeform()
LOW = dict(  # degree (2, 1), rational, 4 x 3 net
    control_net=[[[0, 0, 0], [0, 1, 0.2], [0, 2, 0.1]],
                 [[1, 0, 0.5], [1, 1, 0.8], [1, 2, 0.3]],
                 [[2, 0, -0.2], [2, 1, 0.4], [2, 2, 0.0]],
                 [[3, 0, 0.1], [3, 1, 0.0], [3, 2, 0.6]]],
    weights=[[1, 0.5, 1], [2, 1, 0.7], [0.8, 1.5, 1], [1, 1, 1.2]],
    knots_u=[0, 0, 0, 0.6, 1, 1, 1], knots_v=[0, 0, 0.4, 1, 1], degree_u=2, degree_v=1,
)
R, L = 0.05, 0.2


def cylinder(outward: bool = True):
    """Quarter cylinder of radius R about the y axis, (R, y, 0) to (0, y, R): an exact rational quadratic
    in u times linear in v. ``outward``: v runs so that S_u x S_v points away from the axis."""
    ys = [L, 0.0] if outward else [0.0, L]
    arc = [(R, 0.0), (R, R), (0.0, R)]
    return dict(control_net=[[[x, y, z] for y in ys] for x, z in arc], weights=[[1, 1], [S2, S2], [1, 1]],
                knots_u=[0, 0, 0, 1, 1, 1], knots_v=[0, 0, 1, 1], degree_u=2, degree_v=1)


PLATE = dict(control_net=[[[0, 0, 0], [0, 0.3, 0]], [[0.5, 0, 0], [0.5, 0.3, 0]]], weights=None,
             knots_u=[0, 0, 1, 1], knots_v=[0, 0, 1, 1], degree_u=1, degree_v=1)


def reference_point(spec, u: float, v: float) -> np.ndarray:
    """Tensor-product Cox-de Boor in homogeneous coordinates, then the projection."""
    P = np.asarray(spec["control_net"], float)
    W = np.ones(P.shape[:2]) if spec["weights"] is None else np.asarray(spec["weights"], float)
    Nu = np.array([cox_de_boor(i, spec["degree_u"], u, spec["knots_u"]) for i in range(P.shape[0])])
    Nv = np.array([cox_de_boor(j, spec["degree_v"], v, spec["knots_v"]) for j in range(P.shape[1])])
    B = np.outer(Nu, Nv) * W
    return np.einsum("ij,ijc->c", B, P) / B.sum()


def interior_params(spec, n, rng, margin):
    """n random parameter pairs at least ``margin`` from every knot (finite differences straddle none)."""
    out = []
    for knots in (spec["knots_u"], spec["knots_v"]):
        k = np.unique(knots)
        x = rng.uniform(k[0], k[-1], size=20 * n)
        x = x[np.min(np.abs(x[:, None] - k[None, :]), axis=1) > margin][:n]
        assert x.size == n
        out.append(x)
    return out


@pytest.mark.parametrize("spec", [FREEFORM, LOW], ids=["bicubic", "deg21"])
def test_points_match_cox_de_boor(spec):
    surf = NurbsSurface(**spec)
    ku, kv = np.unique(spec["knots_u"]), np.unique(spec["knots_v"])
    u = np.concatenate([np.linspace(ku[0], ku[-1], 13), ku])
    v = np.concatenate([np.linspace(kv[0], kv[-1], 13), kv])
    U, V = (a.ravel() for a in np.meshgrid(u, v, indexing="ij"))
    ref = np.array([reference_point(spec, a, b) for a, b in zip(U, V)])
    assert np.allclose(surf.point(U, V), ref, rtol=0, atol=1e-13)


@pytest.mark.parametrize("spec", [FREEFORM, LOW], ids=["bicubic", "deg21"])
def test_partials_match_finite_differences_of_the_reference(spec):
    surf = NurbsSurface(**spec)
    u, v = interior_params(spec, 25, np.random.default_rng(1), margin=1e-3)
    d = surf.derivatives(u, v, 2)
    f = lambda a, b: reference_point(spec, a, b)  # noqa: E731
    h1, h2 = 1e-6, 1e-4
    fd = {(1, 0): [], (0, 1): [], (2, 0): [], (1, 1): [], (0, 2): []}
    for a, b in zip(u, v):
        c = f(a, b)
        fd[1, 0].append((f(a + h1, b) - f(a - h1, b)) / (2 * h1))
        fd[0, 1].append((f(a, b + h1) - f(a, b - h1)) / (2 * h1))
        fd[2, 0].append((f(a + h2, b) - 2 * c + f(a - h2, b)) / h2**2)
        fd[0, 2].append((f(a, b + h2) - 2 * c + f(a, b - h2)) / h2**2)
        fd[1, 1].append((f(a + h2, b + h2) - f(a + h2, b - h2) - f(a - h2, b + h2) + f(a - h2, b - h2)) / (4 * h2**2))
    for key, values in fd.items():
        values = np.array(values)
        scale = max(1.0, np.max(np.abs(values)))
        tol = 1e-8 if sum(key) == 1 else 2e-6
        assert np.max(np.abs(d[key] - values)) < tol * scale, key


def test_derivatives_orders_and_shapes():
    surf = NurbsSurface(**FREEFORM)
    assert set(surf.derivatives([0.5], [1.5], 0)) == {(0, 0)}
    assert set(surf.derivatives([0.5], [1.5], 1)) == {(0, 0), (1, 0), (0, 1)}
    d = surf.derivatives(np.linspace(0, 2, 7), np.linspace(1, 2.5, 7))
    assert set(d) == {(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)}
    assert all(x.shape == (7, 3) and np.all(np.isfinite(x)) for x in d.values())
    # clamped to the domain
    assert np.allclose(surf.point([-1.0, 3.0], [0.0, 9.0]), surf.point([0.0, 2.0], [1.0, 2.5]), rtol=0, atol=0)
    with pytest.raises(ValueError):
        surf.derivatives([0.1, 0.2], [1.1], 1)
    with pytest.raises(ValueError):
        surf.derivatives([0.1], [1.1], 3)


@pytest.mark.parametrize("spec", [FREEFORM, LOW, cylinder()], ids=["bicubic", "deg21", "cylinder"])
def test_span_evaluator_equals_derivatives(spec):
    surf = NurbsSurface(**spec)
    ev = surf.span_evaluator()
    assert isinstance(ev, SurfaceSpanEvaluator)
    assert ev.domain_u == surf.domain_u and ev.domain_v == surf.domain_v
    rng = np.random.default_rng(3)
    ku, kv = np.unique(spec["knots_u"]), np.unique(spec["knots_v"])
    u = np.concatenate([rng.uniform(ku[0], ku[-1], 60), np.repeat(ku, kv.size), [ku[0] - 1, ku[-1] + 1]])
    v = np.concatenate([rng.uniform(kv[0], kv[-1], 60), np.tile(kv, ku.size), [kv[-1] + 1, kv[0] - 1]])
    d = surf.derivatives(u, v, 2)
    keys = [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]
    got = [np.array([ev.evaluate(float(a), float(b))[k] for a, b in zip(u, v)]) for k in range(6)]
    for key, g in zip(keys, got):
        scale = max(1.0, np.max(np.abs(d[key])))
        assert np.max(np.abs(g - d[key])) <= 1e-12 * scale, key
    normals = np.array([ev.normal(float(a), float(b)) for a, b in zip(u, v)])
    assert np.allclose(normals, surf.normal(u, v), rtol=0, atol=1e-12)
    assert all(isinstance(x, float) for x in ev.evaluate(0.3, 1.2)[3])


def test_cylinder_is_exact_with_radial_normals_and_area():
    surf = NurbsSurface(**cylinder())
    u, v = (a.ravel() for a in np.meshgrid(np.linspace(0, 1, 41), np.linspace(0, 1, 11), indexing="ij"))
    P = surf.point(u, v)
    radial = P[:, [0, 2]]
    assert np.max(np.abs(np.linalg.norm(radial, axis=1) - R)) < 1e-12
    assert np.allclose(P[:, 1], L * (1 - v), atol=1e-15)
    n = surf.normal(u, v)
    outward = np.stack([P[:, 0], np.zeros_like(u), P[:, 2]], axis=1) / R
    assert np.allclose(n, outward, rtol=0, atol=1e-12)
    assert surf.area() == pytest.approx(math.pi / 2 * R * L, rel=1e-9)
    # second partials: |S_uu . n| relates to the curvature 1/R along the arc
    d = surf.derivatives(u, v, 2)
    kappa = -np.einsum("mc,mc->m", d[2, 0], n) / np.einsum("mc,mc->m", d[1, 0], d[1, 0])
    assert np.allclose(kappa, 1 / R, rtol=1e-10)
    assert np.allclose(d[0, 2], 0, atol=1e-15) and np.allclose(np.einsum("mc,mc->m", d[1, 1], n), 0, atol=1e-12)


def test_normal_points_up_and_vertical_normals_keep_their_sign():
    inward = NurbsSurface(**cylinder(outward=False))  # S_u x S_v points at the axis
    u = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    n = inward.normal(u, np.full(5, 0.5))
    assert np.all(n[:, 2] >= 0)
    P = inward.point(u, np.full(5, 0.5))
    # flipped up (outward) where the normal has a z component; kept (inward) on the vertical edge u = 0
    assert np.allclose(n[1:], P[1:] * [1, 0, 1] / R, atol=1e-12)
    assert np.allclose(n[0], [-1, 0, 0], atol=1e-12)
    assert np.allclose(NurbsSurface(**cylinder()).normal([0.0], [0.5]), [[1, 0, 0]], atol=1e-12)
    ev = inward.span_evaluator()
    assert np.allclose([ev.normal(float(a), 0.5) for a in u], n, atol=1e-12)


@pytest.mark.parametrize("swap", [False, True])
def test_flat_plate(swap):
    spec = copy.deepcopy(PLATE)
    if swap:  # u along y, v along x: S_u x S_v points down, normal still up
        spec["control_net"] = np.transpose(np.asarray(spec["control_net"], float), (1, 0, 2))
    surf = NurbsSurface(**spec)
    u, v = np.random.default_rng(0).uniform(0, 1, (2, 20))
    assert np.allclose(surf.normal(u, v), [0, 0, 1], rtol=0, atol=0)
    assert surf.area() == pytest.approx(0.15, rel=1e-14)
    assert surf.span_evaluator().normal(0.3, 0.6) == [0.0, 0.0, 1.0]


def test_grid():
    surf = NurbsSurface(**FREEFORM)
    U, V, P = surf.grid(4, 7)
    assert U.shape == V.shape == (4, 7) and P.shape == (4, 7, 3)
    assert U[0, 0] == 0 and U[-1, 0] == 2 and V[0, 0] == 1 and V[0, -1] == 2.5
    net = FREEFORM["control_net"]
    for i, j in [(0, 0), (-1, 0), (0, -1), (-1, -1)]:  # clamped: corners interpolate the net
        assert np.allclose(P[i, j], net[i, j], atol=1e-14)
    assert np.allclose(P[2, 3], surf.point([U[2, 3]], [V[2, 3]])[0])


@pytest.mark.parametrize("spec", [FREEFORM, LOW, cylinder(), cylinder(outward=False), PLATE],
                         ids=["bicubic", "deg21", "cylinder", "cylinder-in", "plate"])
def test_tessellate(spec):
    surf = NurbsSurface(**spec)
    vertices, faces = surf.tessellate(9, 6)
    assert vertices.shape == (54, 3) and faces.shape == (2 * 8 * 5, 3) and faces.dtype == np.int32
    assert faces.min() == 0 and faces.max() == 53 and len(np.unique(faces)) == 54
    U, V, P = surf.grid(9, 6)
    assert np.array_equal(vertices, P.reshape(-1, 3))
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.linalg.norm(face_n, axis=1) > 0)
    vertex_n = surf.normal(U.ravel(), V.ravel())
    # the inward cylinder's vertical u = 0 edge keeps its inward normal (the seam of the "up" rule)
    tilted = np.abs(vertex_n[:, 2]) > 1e-9
    assert np.all(tilted) or spec["degree_u"] == 2
    for k in range(3):
        dots = np.einsum("fc,fc->f", face_n, vertex_n[faces[:, k]])
        assert np.all(dots[tilted[faces[:, k]]] > 0)
    assert np.all(face_n[:, 2] >= 0)  # all these surfaces have a consistent up side
    with pytest.raises(ValueError):
        surf.tessellate(1, 5)


def test_area_of_a_curved_freeform_matches_a_fine_mesh():
    surf = NurbsSurface(**FREEFORM)
    vertices, faces = surf.tessellate(400, 300)
    tri = vertices[faces]
    mesh = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    assert surf.area() == pytest.approx(mesh, rel=1e-4)
    assert surf.area(32) == pytest.approx(surf.area(), rel=1e-10)


def _bad(key, **changes):
    spec = copy.deepcopy(FREEFORM)
    spec.update(changes)
    return pytest.param(spec, key, id=f"{key}:{'+'.join(changes)}")


NET, W = FREEFORM["control_net"], FREEFORM["weights"]


@pytest.mark.parametrize("spec, key", [
    _bad("degree_u", degree_u=0),
    _bad("degree_v", degree_v=0),
    _bad("control_net", control_net=NET[..., :2]),
    _bad("control_net", control_net=NET.reshape(30, 3)),
    _bad("control_net", control_net=[[[0, 0, 0], [1, 0, 0]], [[0, 1, 0]]]),
    _bad("control_net", control_net=NET[:3]),
    _bad("control_net", control_net=np.where(np.arange(3) == 2, np.nan, NET)),
    _bad("weights", weights=W[:3]),
    _bad("weights", weights=W.T),
    _bad("weights", weights=np.where(np.arange(6) == 4, 0.0, W)),
    _bad("weights", weights=-W),
    _bad("weights", weights=np.where(np.arange(6) == 1, np.inf, W)),
    _bad("knots_u", knots_u=[0, 0, 0, 0, 0.7, 2, 2, 2]),
    _bad("knots_u", knots_u=[0, 0, 0, 0.1, 0.7, 2, 2, 2, 2]),
    _bad("knots_u", knots_u=[0, 0, 0, 0, 2.5, 2, 2, 2, 2]),
    _bad("knots_u", knots_u=[0, 0, 0, 0, np.nan, 2, 2, 2, 2]),
    _bad("knots_u", knots_u=[1] * 9),
    _bad("knots_v", knots_v=[1, 1, 1, 1, 1.3, 1.3, 2.5, 2.5, 2.5]),
    _bad("knots_v", knots_v=[1, 1, 1, 1.2, 1.3, 1.3, 2.5, 2.5, 2.5, 2.5]),
    _bad("knots_v", knots_v=[1, 1, 1, 1, 1.3, 1.3, 2.5, 2.5, 2.5, 3]),
    pytest.param({**PLATE, "control_net": [[[0, y, 0] for y in range(4)], [[1, y, 0] for y in range(4)]],
                  "knots_v": [0, 0, 0.5, 0.5, 1, 1]}, "knots_v", id="knots_v:multiplicity"),
])
def test_validation(spec, key):
    with pytest.raises(NurbsError) as info:
        NurbsSurface(**spec)
    assert info.value.key == key


def test_validation_messages_say_what_was_found():
    with pytest.raises(NurbsError, match=r"5 x 6 grid of weights .* got shape \(3, 6\)"):
        NurbsSurface(**{**FREEFORM, "weights": W[:3]})
    with pytest.raises(NurbsError, match=r"got shape \(5, 6, 2\)"):
        NurbsSurface(**{**FREEFORM, "control_net": NET[..., :2]})
    with pytest.raises(NurbsError, match="10 knots, got 9"):
        NurbsSurface(**{**FREEFORM, "knots_v": [1, 1, 1, 1, 1.3, 2.5, 2.5, 2.5, 2.5]})


def test_a_control_net_is_planar_on_any_plane_and_not_off_it():
    from cnc_twin.geometry.surface import control_net_is_planar

    u, v = np.meshgrid(np.linspace(-0.1, 0.1, 4), np.linspace(-0.05, 0.05, 3), indexing="ij")
    tilted = np.stack([u, v, 0.3 * u - 0.2 * v + 0.07], axis=-1)  # a tilted plane, off the origin
    assert control_net_is_planar(tilted)
    domed = tilted.copy()
    domed[1, 1, 2] += 1e-6  # one point a micron off the plane
    assert not control_net_is_planar(domed)

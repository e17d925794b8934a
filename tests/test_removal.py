"""Preston removal model: Winkler pad pressure, sliding speed, accumulation, stats and files."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import dblquad, quad
from scipy.optimize import brentq

from cnc_twin.polishing.removal import PrestonModel, RemovalGrid

KP = 1e-13       # Preston coefficient [1/Pa]
R = 25e-3        # pad radius [m]
K = 1e8          # foam pad: E ~ 1 MPa over 10 mm [N/m^3]
Z = np.array([0.0, 0.0, 1.0])


def plate(spacing: float, size: float = 60e-3) -> RemovalGrid:
    return RemovalGrid.plate(center=(0.0, 0.0, 0.0), size_x=size, size_y=size, spacing=spacing)


def model(grid: RemovalGrid, **kw) -> PrestonModel:
    return PrestonModel(grid, preston_k=KP, pad_radius=R, pad_modulus=K, **kw)


def sphere_cap(Rs: float, half: float, spacing: float) -> RemovalGrid:
    """Top of a sphere of radius Rs touching z = 0 at the origin, sampled on an x/y grid."""
    n = round(2 * half / spacing)
    x = -half + (np.arange(n) + 0.5) * spacing
    X, Y = np.meshgrid(x, x)
    X, Y = X.ravel(), Y.ravel()
    zc = np.sqrt(Rs**2 - X**2 - Y**2)
    pts = np.column_stack([X, Y, zc - Rs])
    normals = np.column_stack([X, Y, zc]) / Rs
    areas = spacing**2 / normals[:, 2]  # graph surface element dA = dx dy / n_z
    return RemovalGrid(pts, normals, areas, (n, n), (x[0], x[-1], x[0], x[-1]))


def delta_by_root(m: PrestonModel, tip, axis, force) -> float:
    """Independent approach solve: brentq on sum A max(0, h + delta) = F / K over the candidates."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    r = m.grid.points - np.asarray(tip, float)
    h = r @ a
    rho = np.linalg.norm(r - h[:, None] * a, axis=1)
    cand = (rho <= m.pad_radius) & (np.abs(h) <= m.slab) & (m.grid.normals @ a > 0)
    h, A = h[cand], m.grid.areas[cand]
    f = lambda d: A @ np.maximum(0.0, h + d) - force / m.pad_modulus
    return brentq(f, -h.max(), -h.min() + force / m.pad_modulus / A.sum() + 1e-3, xtol=1e-16, rtol=1e-15)


def test_flat_parallel_pad_uniform_disc():
    s = 0.5e-3
    grid = plate(s)
    m = model(grid)
    idx, p = m.pressure((0.0, 0.0, 0.0), Z, 40.0)
    assert np.ptp(p) <= 1e-12 * p.max()
    assert math.isclose(p @ grid.areas[idx], 40.0, rel_tol=1e-12)
    assert len(idx) == pytest.approx(math.pi * R**2 / s**2, rel=0.02)
    assert np.all(np.linalg.norm(grid.points[idx, :2], axis=1) <= R)
    # a pad pressed 1 mm in, or a non-unit axis: the same patch, the same uniform pressure
    idx2, p2 = m.pressure((0.0, 0.0, -1e-3), 3 * Z, 40.0)
    np.testing.assert_array_equal(np.sort(idx2), np.sort(idx))
    # (the patch's sums run term by term, as the compiled patch adds them: over ~8000 points the
    # two pressures agree to a few 1e-12, where pairwise sums agreed to 1e-12)
    np.testing.assert_allclose(p2, p[0], rtol=1e-11)


def test_plate_grid_layout():
    g = RemovalGrid.plate(center=(1.0, 2.0, 0.5), size_x=0.2, size_y=0.15, spacing=0.5e-3)
    assert g.shape == (300, 400)  # rows along y, columns along x
    img = g.points[:, 0].reshape(g.shape)
    assert np.all(np.diff(img, axis=1) > 0) and np.all(np.diff(g.points[:, 1].reshape(g.shape), axis=0) > 0)
    assert math.isclose(g.areas.sum(), 0.2 * 0.15, rel_tol=1e-12)
    assert g.extent == pytest.approx((0.90025, 1.09975, 1.92525, 2.07475))
    assert np.all(g.points[:, 2] == 0.5) and np.all(g.normals == Z)


def test_spinning_pad_volume_matches_preston_integral():
    F, dt = 30.0, 2e-3
    w = 1500 * 2 * math.pi / 60  # rad/s about the tool axis
    v = np.array([0.05, 0.02, 0.0])
    m = model(plate(0.25e-3))
    n = m.accumulate((0.0, 0.0, 0.0), Z, F, v, w * Z, dt)
    assert n == len(m.pressure((0.0, 0.0, 0.0), Z, F)[0]) and m.contact_time == dt

    def speed_r(r, th):  # |v + omega x r| * r, r = (r cos th, r sin th, 0)
        return math.hypot(v[0] - w * r * math.sin(th), v[1] + w * r * math.cos(th)) * r

    integral, _ = dblquad(speed_r, 0.0, 2 * math.pi, 0.0, R, epsabs=1e-12, epsrel=1e-10)
    expected = KP * F / (math.pi * R**2) * dt * integral
    assert m.volume() == pytest.approx(expected, rel=0.01)


def test_pure_feed_volume_exact_and_normal_component_ignored():
    F, dt = 25.0, 1e-3
    m = model(plate(0.5e-3))
    m.accumulate((0.0, 0.0, 0.0), Z, F, (0.03, 0.04, 0.5), np.zeros(3), dt)  # z part is along n
    assert m.volume() == pytest.approx(KP * F * 0.05 * dt, rel=1e-9)


def test_sphere_cap_pressure_peaks_at_centre():
    Rs, s = 0.1, 0.25e-3
    grid = sphere_cap(Rs, 30e-3, s)
    m = model(grid)
    for F in (50.0, 500.0):  # partial patch, whole disc
        idx, p = m.pressure((0.0, 0.0, 0.0), Z, F)
        assert math.isclose(p @ grid.areas[idx], F, rel_tol=1e-12)
        rho = np.linalg.norm(grid.points[idx, :2], axis=1)
        order = np.argsort(rho)
        assert np.all(np.diff(p[order]) <= 1e-9 * p.max())
        assert p.argmax() == rho.argmin() and p.max() > 1.5 * p.min()
        np.testing.assert_allclose(p, K * (grid.points[idx, 2] + delta_by_root(m, (0, 0, 0), Z, F)), rtol=1e-9)
    # F = 500 N covers the disc; F = 50 N only a circle whose radius a solves the continuum
    # F = K * int_0^a (delta - (Rs - sqrt(Rs^2 - rho^2))) dA, delta = Rs - sqrt(Rs^2 - a^2)
    def force(a):
        d = Rs - math.sqrt(Rs**2 - a**2)
        f = lambda r: (d - Rs + math.sqrt(Rs**2 - r**2)) * Rs / math.sqrt(Rs**2 - r**2) * 2 * math.pi * r
        return K * quad(f, 0.0, a)[0]

    a = brentq(lambda a: force(a) - 50.0, 1e-4, R)
    idx, _ = m.pressure((0.0, 0.0, 0.0), Z, 50.0)
    assert np.linalg.norm(grid.points[idx, :2], axis=1).max() == pytest.approx(a, abs=2 * s)
    assert a < 0.8 * R


def test_tilted_pad_partial_contact_exact_delta():
    grid = plate(0.5e-3)
    m = model(grid)
    axis = np.array([0.0, math.sin(math.radians(2)), math.cos(math.radians(2))])
    idx, p = m.pressure((0.0, 0.0, 0.0), axis, 20.0)
    assert math.isclose(p @ grid.areas[idx], 20.0, rel_tol=1e-12)
    # the face n = a dips below z = 0 where y > 0: contact there only, pressure falling to 0 at its edge
    assert np.all(grid.points[idx, 1] > 0) and p.min() < 0.01 * p.max()
    h = grid.points[idx] @ axis
    np.testing.assert_allclose(p, K * (h + delta_by_root(m, (0, 0, 0), axis, 20.0)), rtol=1e-9, atol=1e-9 * p.max())


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.01, 200.0))
def test_random_heights_force_balance(seed, F):
    rng = np.random.default_rng(seed)
    n = 200
    pts = np.column_stack([rng.uniform(-R, R, n) * 0.7, rng.uniform(-R, R, n) * 0.7, rng.uniform(-4e-3, 4e-3, n)])
    normals = np.tile(Z, (n, 1))
    grid = RemovalGrid(pts, normals, rng.uniform(1e-7, 1e-6, n), (1, n), (-R, R, -R, R))
    m = model(grid)
    idx, p = m.pressure((0.0, 0.0, 0.0), Z, F)
    assert math.isclose(p @ grid.areas[idx], F, rel_tol=1e-11)
    np.testing.assert_allclose(p, K * (pts[idx, 2] + delta_by_root(m, (0, 0, 0), Z, F)), rtol=1e-7,
                               atol=1e-9 * p.max())


def test_removal_linear_in_force_and_time():
    args = ((0.0, 0.0, 0.0), Z, None, (0.02, 0.0, 0.0), 100.0 * Z)
    grid = plate(0.5e-3)
    base, double_f, double_t = model(grid), model(grid), model(grid)
    for mdl, F, dt in ((base, 10.0, 1e-3), (double_f, 20.0, 1e-3), (double_t, 10.0, 2e-3)):
        mdl.accumulate(args[0], args[1], F, args[3], args[4], dt)
    assert base.volume() > 0
    np.testing.assert_allclose(double_f.depth, 2 * base.depth, rtol=1e-12, atol=0)
    np.testing.assert_allclose(double_t.depth, 2 * base.depth, rtol=1e-12, atol=0)


@pytest.mark.parametrize("tip, axis, force", [
    ((0.0, 0.0, 0.0), Z, 0.0),                  # no force
    ((0.0, 0.0, 0.0), Z, -5.0),                 # negative force
    ((0.5, 0.5, 0.0), Z, 10.0),                 # beside the plate
    ((0.0, 0.0, 10e-3), Z, 10.0),               # hovering beyond the slab
    ((0.0, 0.0, 0.0), -Z, 10.0),                # pad facing away from the surface
    ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 10.0),   # pad on edge: n . a = 0
])
def test_no_contact_no_removal(tip, axis, force):
    m = model(plate(1e-3))
    assert m.accumulate(tip, axis, force, (0.05, 0.0, 0.0), 150.0 * np.asarray(axis, float), 1e-3) == 0
    assert m.volume() == 0.0 and m.contact_time == 0.0 and not np.any(m.depth)
    assert len(m.pressure(tip, axis, force)[0]) == 0
    assert m.stats()["points"] == 0


def test_stats_known_depths():
    m = model(RemovalGrid.plate(center=(0, 0, 0), size_x=2e-3, size_y=2e-3, spacing=1e-3))
    m.depth[:] = [0.0, 1e-6, 2e-6, 3e-6]
    s = m.stats()
    assert s["points"] == 3
    assert s["mean_um"] == pytest.approx(2.0) and s["std_um"] == pytest.approx(math.sqrt(2 / 3))
    assert s["pv_um"] == pytest.approx(2.0) and s["max_um"] == pytest.approx(3.0)
    assert s["nonuniformity"] == pytest.approx(math.sqrt(2 / 3) / 2)
    all_pts = m.stats(np.ones(4, bool))
    assert all_pts["points"] == 4 and all_pts["mean_um"] == pytest.approx(1.5) and all_pts["pv_um"] == pytest.approx(3)
    assert m.volume() == pytest.approx(6e-6 * 1e-6)


def test_save_round_trip(tmp_path):
    m = model(plate(1e-3))
    m.accumulate((0.0, 0.0, 0.0), Z, 20.0, (0.05, 0.0, 0.0), 150.0 * Z, 5e-3)
    figs = sys.modules["matplotlib.pyplot"].get_fignums() if "matplotlib.pyplot" in sys.modules else None
    paths = m.save(tmp_path / "out")
    assert [p.name for p in paths] == ["removal.npz", "removal.png"] and all(p.stat().st_size > 0 for p in paths)
    assert paths[1].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    if figs is not None:
        assert sys.modules["matplotlib.pyplot"].get_fignums() == figs
    with np.load(paths[0]) as z:
        np.testing.assert_array_equal(z["depth"], m.depth)
        np.testing.assert_array_equal(z["points"], m.grid.points)
        np.testing.assert_array_equal(z["areas"], m.grid.areas)
        assert tuple(z["shape"]) == m.grid.shape and tuple(z["extent"]) == m.grid.extent
        assert float(z["preston_k"]) == KP and float(z["pad_radius"]) == R and float(z["pad_modulus"]) == K
        assert float(z["contact_time"]) == 5e-3
        back = RemovalGrid(z["points"], z["normals"], z["areas"], tuple(z["shape"]), tuple(z["extent"]))
    assert back.shape == m.grid.shape


def test_invalid_inputs():
    grid = plate(1e-3)
    with pytest.raises(ValueError):
        PrestonModel(grid, preston_k=KP, pad_radius=0.0, pad_modulus=K)
    with pytest.raises(ValueError):
        RemovalGrid(grid.points, grid.normals, grid.areas, (7, 7), grid.extent)
    with pytest.raises(ValueError):
        RemovalGrid(grid.points, 2 * grid.normals, grid.areas, grid.shape, grid.extent)
    with pytest.raises(ValueError):
        model(grid).accumulate((0, 0, 0), Z, 10.0, (0, 0, 0), (0, 0, 0), -1e-3)
    with pytest.raises(ValueError):
        model(grid).pressure((0, 0, 0), (0, 0, 0), 10.0)


def test_cached_neighbourhood_matches_fresh_query():
    """The ball cache (requeried only when the tip leaves its margin) finds the same patch as a fresh model."""
    grid = plate(0.5e-3)
    walker = model(grid)
    queries = []

    find = walker._ball_around

    def counting(tip):  # the model's pass over the grid, counted
        queries.append(tip)
        return find(tip)

    walker._ball_around = counting
    axis = np.array([0.1, -0.05, 1.0])
    xs = np.concatenate([np.arange(-20e-3, 20e-3, 0.7e-3), [15e-3, -25e-3, 0.0]])  # steps, then jumps
    for x in xs:
        tip = (x, 0.4 * x, -0.2e-3)
        idx, p = walker.pressure(tip, axis, 15.0)
        ref_idx, ref_p = model(grid).pressure(tip, axis, 15.0)
        o, ro = np.argsort(idx), np.argsort(ref_idx)
        np.testing.assert_array_equal(idx[o], ref_idx[ro])
        np.testing.assert_allclose(p[o], ref_p[ro], rtol=1e-12)
    assert 8 <= len(queries) < len(xs) // 2  # requeried when the walk left the margin, reused otherwise

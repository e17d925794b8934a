"""Material removal of polishing by Preston's law, accumulated on a grid of workpiece surface points.

Preston's law gives the removal depth rate at each surface point::

    dh/dt = k_p * p * V

with ``k_p`` the Preston coefficient [m^2/N = 1/Pa], ``p`` the local contact pressure [Pa] and ``V``
the local sliding speed of the pad over the surface [m/s].

Pressure: the pad is a flat disc of radius ``R`` whose face passes through the tool tip, normal to
the tool axis ``a`` (unit, from the tip up into the spindle), on a Winkler (elastic foundation)
layer of modulus ``K`` [N/m^3]. For a surface point ``q`` with ``r = q - tip``::

    h   = r . a                 how far the point sits above the undeformed pad face (into the pad)
    rho = |r - h a|             lateral distance from the pad centre

Candidates are the points with ``rho <= R``, the surface normal facing the pad (``n . a > 0``) and
``|h| <= slab`` (so the far side of a part never counts). Their pressure is::

    p_i = K * max(0, h_i + delta)

with the approach ``delta`` [m] such that ``sum_i p_i A_i = F``, ``A_i`` the point's area share and
``F`` the measured normal force. That sum is piecewise linear and increasing in ``delta``: with
``h`` sorted descending and the top ``k`` points in contact it is
``K (S_k + delta W_k)``, ``S_k = sum_{j<=k} A_j h_j``, ``W_k = sum_{j<=k} A_j``, valid while
``h_{k+1} + delta <= 0``; the first segment that reaches ``F`` gives ``delta`` exactly.
``F <= 0`` or no candidates: no contact, no removal.

Sliding speed: the pad's velocity at the point, ``v = v_tip + omega x r`` (world frame), less its
component along the surface normal: ``V = |v - (v . n) n|``.

Over a time step ``dt``: ``depth_i += k_p * p_i * V_i * dt``. SI units throughout (m, N, s, rad).

Cost: :meth:`PrestonModel.accumulate` runs every few milliseconds of simulated time, so it only
touches the points near the pad: the ball of radius ``sqrt(R^2 + slab^2) + margin`` around the tip,
found by one pass over the grid and reused while the tip stays within ``margin`` (0.1 R) of the
ball's centre; the rest is vectorised over those points. Every distance is summed x, y, z in that
order, so the compiled update (:mod:`cnc_twin.polishing.removal_kernel`) finds the same ball.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class RemovalGrid:
    """Surface points of a workpiece on which removal accumulates.

    Attributes
    ----------
    points : shape ``(m, 3)``, world frame [m].
    normals : shape ``(m, 3)``, unit, out of the material (towards the tool).
    areas : shape ``(m,)``, each point's share of the surface area [m^2].
    shape : ``(nu, nv)``; the points are a row-major ``nu x nv`` parameter grid (for images).
    extent : ``(x_min, x_max, y_min, y_max)`` of the points [m] (image axes).
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    shape: tuple[int, int]
    extent: tuple[float, float, float, float]

    def __post_init__(self):
        pts = np.ascontiguousarray(self.points, dtype=np.float64)
        nrm = np.ascontiguousarray(self.normals, dtype=np.float64)
        areas = np.ascontiguousarray(self.areas, dtype=np.float64)
        m = len(pts)
        if pts.shape != (m, 3) or nrm.shape != (m, 3) or areas.shape != (m,):
            raise ValueError(f"points {pts.shape}, normals {nrm.shape}, areas {areas.shape}: need (m,3),(m,3),(m,)")
        nu, nv = (int(s) for s in self.shape)
        if nu * nv != m:
            raise ValueError(f"shape {self.shape} does not hold {m} points")
        if not np.allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-9):
            raise ValueError("normals must be unit vectors")
        if np.any(areas < 0):
            raise ValueError("areas must be >= 0")
        # frozen: the validated float arrays replace what the caller passed
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "normals", nrm)
        object.__setattr__(self, "areas", areas)
        object.__setattr__(self, "shape", (nu, nv))
        object.__setattr__(self, "extent", tuple(float(e) for e in self.extent))

    @classmethod
    def plate(cls, *, center, size_x: float, size_y: float, spacing: float) -> "RemovalGrid":
        """A flat horizontal plate, normal +z, cell-centred points about ``center`` (shape (3,), [m]).

        Cells are ``size / round(size / spacing)`` wide, so the plate is covered exactly; rows run
        along y and columns along x (``shape = (ny, nx)``), so ``depth.reshape(shape)`` is an image
        with y up when drawn with ``origin="lower"``.
        """
        if min(size_x, size_y, spacing) <= 0:
            raise ValueError("size_x, size_y and spacing must be > 0")
        c = np.asarray(center, dtype=np.float64)
        nx, ny = max(1, round(size_x / spacing)), max(1, round(size_y / spacing))
        dx, dy = size_x / nx, size_y / ny
        x = c[0] - 0.5 * size_x + (np.arange(nx) + 0.5) * dx
        y = c[1] - 0.5 * size_y + (np.arange(ny) + 0.5) * dy
        X, Y = np.meshgrid(x, y)  # (ny, nx): row = y
        pts = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, c[2])])
        normals = np.zeros_like(pts)
        normals[:, 2] = 1.0
        return cls(pts, normals, np.full(X.size, dx * dy), (ny, nx), (x[0], x[-1], y[0], y[-1]))


BALL_MARGIN = 0.1
"""how far the tip may move from the centre of its ball of candidates before the ball is found
again [pad radii]: a larger ball is scanned at every update, a smaller one found more often"""


def sequential_sum(values: np.ndarray) -> float:
    """``values[0] + values[1] + ...`` in that order (np.sum adds pairwise: other last bits than a
    compiled loop); 0 for none."""
    return float(np.cumsum(values)[-1]) if len(values) else 0.0


def sliding_speed(v: np.ndarray) -> np.ndarray:
    """``|v|`` of each column of ``v`` (3, k), the squares summed x, y, z in that order."""
    return np.sqrt((v[0] * v[0] + v[1] * v[1]) + v[2] * v[2])


def _unit(axis) -> np.ndarray:
    """``axis`` (3,) as a unit vector (float64), its length summed x, y, z in order; ValueError
    when it is zero."""
    a = np.asarray(axis, dtype=np.float64)
    norm = math.sqrt((a[0] * a[0] + a[1] * a[1]) + a[2] * a[2])
    if not norm > 0:
        raise ValueError(f"tool axis must be non-zero, got {axis}")
    return a / norm


@dataclass(frozen=True)
class Patch:
    """The pad's contact patch at one instant (``k`` grid points)."""

    index: np.ndarray
    """(k,) indices into the grid"""
    pressure: np.ndarray
    """(k,) [Pa]"""
    arm: np.ndarray
    """(3, k) point - tip [m]"""
    sliding: np.ndarray
    """(3, k) the pad's tangential velocity over each point [m/s]"""


class PrestonModel:
    """Preston removal on a :class:`RemovalGrid` under a Winkler pad (see the module docstring).

    Parameters
    ----------
    grid : the surface points.
    preston_k : Preston coefficient [m^2/N], > 0.
    pad_radius : pad disc radius R [m], > 0.
    pad_modulus : Winkler foundation modulus K [N/m^3], > 0.
    slab : largest ``|h|`` of a candidate point [m], > 0.
    """

    def __init__(self, grid: RemovalGrid, *, preston_k: float, pad_radius: float, pad_modulus: float,
                 slab: float = 5e-3):
        if min(preston_k, pad_radius, pad_modulus, slab) <= 0:
            raise ValueError("preston_k, pad_radius, pad_modulus and slab must be > 0")
        self.grid = grid
        self.preston_k, self.pad_radius = float(preston_k), float(pad_radius)
        self.pad_modulus, self.slab = float(pad_modulus), float(slab)
        self.depth = np.zeros(len(grid.points))
        self.contact_time = 0.0
        # every candidate has rho <= R and |h| <= slab, so it lies within this ball of the tip
        self._reach = math.hypot(self.pad_radius, self.slab) * (1 + 1e-9)
        # The tip moves well under a millimetre between calls: one ball of radius reach + margin
        # serves every tip within margin of its centre (exactly: the triangle inequality), so the
        # pass over the whole grid is amortised over many calls.
        self._margin = BALL_MARGIN * self.pad_radius
        self.ball_limits = np.array([(self._reach + self._margin) ** 2, self._margin * self._margin])
        """squared radius of the ball and squared margin of its reuse [m^2]"""
        self.packed = np.ascontiguousarray(np.vstack([grid.points.T, grid.normals.T, grid.areas]))
        """the grid as rows x, y, z [m], nx, ny, nz, area [m^2], shape ``(7, points)`` (structure of
        arrays: one gather per query; the compiled removal update reads it too)"""
        self._ball_centre = np.full(3, np.inf)
        self._ball_idx, self._ball = np.empty(0, dtype=np.intp), np.empty((7, 0))

    def _near(self, tip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Indices (k,) and packed rows (7, k) of a superset of the points within reach of ``tip``."""
        off = tip - self._ball_centre
        if not (off[0] * off[0] + off[1] * off[1]) + off[2] * off[2] <= self.ball_limits[1]:
            self._ball_idx = self._ball_around(tip)
            self._ball = np.take(self.packed, self._ball_idx, axis=1)
            self._ball_centre = tip.copy()
        return self._ball_idx, self._ball

    def _ball_around(self, tip: np.ndarray) -> np.ndarray:
        """Indices (increasing) of the grid points within the ball's radius of ``tip``."""
        r = self.packed[:3] - tip[:, None]
        return np.flatnonzero((r[0] * r[0] + r[1] * r[1]) + r[2] * r[2] <= self.ball_limits[0])

    def _contact(self, tip, axis, force):
        """Points in contact: indices (k,), pressures (k,) [Pa], r = q - tip (3, k), normals (3, k)."""
        empty = np.empty(0, dtype=np.intp), np.empty(0), np.empty((3, 0)), np.empty((3, 0))
        if not force > 0:
            return empty
        tip = np.asarray(tip, dtype=np.float64)
        a = _unit(axis)
        idx, ball = self._near(tip)
        if idx.size == 0:
            return empty
        # Every sum in a fixed order, term by term, so that the compiled patch
        # (cnc_twin.polishing.removal_kernel) gives the same numbers bit for bit: no BLAS dot,
        # no einsum, no pairwise np.sum (sequential_sum).
        r = ball[:3] - tip[:, None]
        h = (a[0] * r[0] + a[1] * r[1]) + a[2] * r[2]
        rho2 = ((r[0] * r[0] + r[1] * r[1]) + r[2] * r[2]) - h * h  # |r - h a|^2 with a unit
        facing = (a[0] * ball[3] + a[1] * ball[4]) + a[2] * ball[5]
        radius = self.pad_radius
        sel = np.flatnonzero((rho2 <= radius * radius) & (np.abs(h) <= self.slab) & (facing > 0))
        if sel.size == 0:
            return empty
        idx, h, A = idx[sel], h[sel], ball[6, sel]  # 1-D: plain indexing is fast
        c = force / self.pad_modulus  # = sum_i A_i max(0, h_i + delta) [m^3]
        W = sequential_sum(A)
        if not W > 0:
            return empty
        delta = (c - sequential_sum(A * h)) / W
        # Not every candidate touches: drop those below the pad at this level and solve again. The
        # level only falls and the set only shrinks, so this ends, at the one level where every
        # point kept touches and every point dropped does not (no sort: each pass is linear).
        keep = h + delta > 0
        while not keep.all():
            sel, idx, h, A = sel[keep], idx[keep], h[keep], A[keep]
            delta = (c - sequential_sum(A * h)) / sequential_sum(A)
            keep = h + delta > 0
        p = self.pad_modulus * (h + delta)
        touch = np.flatnonzero(p > 0)
        sel = sel[touch]  # np.take: far quicker than fancy indexing along axis 1
        return idx[touch], p[touch], np.take(r, sel, axis=1), np.take(ball[3:6], sel, axis=1)

    def pressure(self, tip, axis, force) -> tuple[np.ndarray, np.ndarray]:
        """The contact patch: (indices into the grid, pressures [Pa]), both shape ``(k,)``.

        ``tip`` and ``axis`` shape (3,) [m] (axis need not be unit); ``force`` the normal force [N].
        """
        idx, p, _, _ = self._contact(tip, axis, force)
        return idx, p

    def patch(self, tip, axis, force, v_tip, omega) -> "Patch | None":
        """The contact patch with its pressures and sliding velocities, or None without contact.

        ``tip``, ``axis`` (3,) [m]; ``force`` [N]; ``v_tip`` (3,) [m/s] the tip's velocity;
        ``omega`` (3,) [rad/s] the pad's angular velocity. World frame.
        """
        idx, p, r, n = self._contact(tip, axis, force)
        if idx.size == 0:
            return None
        w = np.asarray(omega, dtype=np.float64)
        t = np.asarray(v_tip, dtype=np.float64)
        v = np.empty_like(r)  # v_tip + omega x r, row by row: cheaper than np.cross on (3, k)
        v[0] = (w[1] * r[2] - w[2] * r[1]) + t[0]
        v[1] = (w[2] * r[0] - w[0] * r[2]) + t[1]
        v[2] = (w[0] * r[1] - w[1] * r[0]) + t[2]
        v -= ((v[0] * n[0] + v[1] * n[1]) + v[2] * n[2]) * n  # sliding is tangential only
        return Patch(index=idx, pressure=p, arm=r, sliding=v)

    def add(self, patch: "Patch", dt: float) -> int:
        """Add a patch's removal over ``dt`` [s] >= 0; returns how many points got removal."""
        if dt < 0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        inc = (self.preston_k * dt) * patch.pressure * sliding_speed(patch.sliding)
        np.add.at(self.depth, patch.index, inc)  # faster than depth[idx] += inc here
        self.contact_time += dt
        return int(np.count_nonzero(inc > 0))

    def step_compiled(self, tip, axis, force, v_tip, omega, dt, centre, mu: float, friction_speed: float,
                      wrench: np.ndarray) -> int:
        """:meth:`patch`, :meth:`add` and the pad's friction wrench about ``centre`` in one compiled
        call (:mod:`cnc_twin.polishing.removal_kernel`), bit for bit those references:
        ``wrench`` (6,) is written (zero without contact); returns how many points got removal,
        -1 without a patch (nothing added, as :meth:`accumulate` adds none)."""
        from cnc_twin.polishing.removal_kernel import removal_step

        if dt < 0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        tip = np.asarray(tip, dtype=np.float64)
        a = _unit(axis)
        idx, ball = self._near(tip)
        touched = removal_step(idx, ball, tip, a, float(force), self.pad_radius, self.slab, self.pad_modulus,
                               self.preston_k * dt, np.asarray(v_tip, dtype=np.float64),
                               np.asarray(omega, dtype=np.float64), np.asarray(centre, dtype=np.float64), mu,
                               friction_speed, self.depth, wrench)
        if touched >= 0:
            self.contact_time += dt
        return touched

    def accumulate(self, tip, axis, force, v_tip, omega, dt) -> int:
        """Add one time step's removal (:meth:`patch`, then :meth:`add`); returns how many points
        got removal. ``dt`` [s] >= 0."""
        if dt < 0:
            raise ValueError(f"dt must be >= 0, got {dt}")
        patch = self.patch(tip, axis, force, v_tip, omega)
        return 0 if patch is None else self.add(patch, dt)

    def volume(self) -> float:
        """Removed volume ``sum(depth * areas)`` [m^3]."""
        return float(self.depth @ self.grid.areas)

    def stats(self, mask: np.ndarray | None = None) -> dict:
        """Depth statistics in um over ``mask`` (bool, shape (m,); default: points with depth > 0).

        Keys: ``mean_um``, ``std_um`` (population), ``pv_um`` (max - min), ``max_um``, ``points``,
        ``nonuniformity`` (std / mean). All 0 when the mask selects nothing.
        """
        d = self.depth[self.depth > 0 if mask is None else np.asarray(mask, dtype=bool)] * 1e6
        if d.size == 0:
            return {"mean_um": 0.0, "std_um": 0.0, "pv_um": 0.0, "max_um": 0.0, "points": 0, "nonuniformity": 0.0}
        mean, std = float(d.mean()), float(d.std())
        return {"mean_um": mean, "std_um": std, "pv_um": float(d.max() - d.min()), "max_um": float(d.max()),
                "points": int(d.size), "nonuniformity": std / mean if mean > 0 else 0.0}

    def save(self, folder: Path) -> list[Path]:
        """Write ``removal.npz`` (depth, grid and parameters) and ``removal.png`` (:meth:`save_picture`)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        g = self.grid
        npz = folder / "removal.npz"
        np.savez(npz, depth=self.depth, points=g.points, normals=g.normals, areas=g.areas,
                 shape=np.array(g.shape), extent=np.array(g.extent), preston_k=self.preston_k,
                 pad_radius=self.pad_radius, pad_modulus=self.pad_modulus, slab=self.slab,
                 contact_time=self.contact_time)
        return [npz, self.save_picture(folder / "removal.png")]

    def save_picture(self, png):
        """Write the depth map in um as a PNG to ``png`` (a path, or a binary file); returns it
        (0.2 - 0.5 s of matplotlib, more for a process's first drawing: its fonts)."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        g = self.grid
        fig = Figure(figsize=(7, 5))
        FigureCanvasAgg(fig)  # a figure of its own: no pyplot state
        ax = fig.add_subplot()
        x0, x1, y0, y1 = g.extent
        # pixels centred on the points: widen the points' extent by half a cell
        hx, hy = (x1 - x0) / max(g.shape[1] - 1, 1) / 2, (y1 - y0) / max(g.shape[0] - 1, 1) / 2
        img = ax.imshow(self.depth.reshape(g.shape) * 1e6, origin="lower",
                        extent=np.array([x0 - hx, x1 + hx, y0 - hy, y1 + hy]) * 1e3,
                        cmap="viridis", aspect="equal", interpolation="nearest")
        fig.colorbar(img, ax=ax, label="removal depth [um]")
        s = self.stats()
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_title(f"removal: mean {s['mean_um']:.3g} um, PV {s['pv_um']:.3g} um\n"
                     f"volume {self.volume() * 1e9:.3g} mm^3, contact {self.contact_time:.3g} s", fontsize=10)
        fig.savefig(png, dpi=110, bbox_inches="tight", format="png")
        return png

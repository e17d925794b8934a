"""The workpiece of a surface program as MuJoCo geometry: a NURBS surface turned into meshes.

MuJoCo collides with a mesh's convex hull, so one mesh cannot stand for a doubly curved face
(a saddle's hull would bridge its hollows). The solid under the surface is cut into tiles in
(u, v); each tile is a mesh of ``(k + 1)^2`` surface points plus the same points dropped to the
solid's base, whose convex hull is the tile's collision shape. On a convex (dome-like) region the
hull's top is the surface itself, up to the tessellation's chord; in a hollow the hull bridges it
by at most the *hull gap*, measured here on the upper hull and reported, so a user sees how
faithful the contact geometry is and can ask for smaller tiles.

:func:`build_model` loads the scene with ``mujoco.MjSpec``, removes the block workpiece
(geom ``workpiece_collision``), adds the tiles (collision group 3, contype 1 / conaffinity 2 like
the block) and a fine visual mesh of the surface (group 2, no contact), and compiles.
Units: m, world frame (the workpiece body sits at the world origin).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial import ConvexHull

from cnc_twin.errors import ScenarioError
from cnc_twin.geometry.surface import NurbsSurface

WORKPIECE_BODY = "workpiece"
BLOCK_GEOM = "workpiece_collision"
PAD_GEOM = "pad_collision"
BASE_DEPTH = 0.02
"""the solid reaches this far below the surface's lowest point [m]"""


@dataclass(frozen=True)
class Tiling:
    """How the surface became collision meshes."""

    tiles: tuple[int, int]
    """tiles along u and v"""
    points_per_edge: int
    hull_gap: float
    """largest height of a tile's convex hull above the surface [m]"""
    base_z: float
    """z of the solid's flat bottom [m]"""


def tile_meshes(surface: NurbsSurface, *, tile_size: float, points_per_edge: int = 5
                ) -> tuple[list[np.ndarray], Tiling]:
    """Vertices (each (2 k^2, 3)) of the tile meshes and the tiling's figures; ``tile_size`` [m]."""
    from cnc_twin.planner.toolpath import parameter_scales

    lu, lv, _, _ = parameter_scales(surface)
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    nu = max(1, int(np.ceil((u1 - u0) * lu / tile_size)))
    nv = max(1, int(np.ceil((v1 - v0) * lv / tile_size)))
    k = points_per_edge
    _, _, grid = surface.grid(nu * (k - 1) + 1, nv * (k - 1) + 1)
    base = float(grid[..., 2].min()) - BASE_DEPTH
    tiles, gap = [], 0.0
    for i in range(nu):
        for j in range(nv):
            top = grid[i * (k - 1):(i + 1) * (k - 1) + 1, j * (k - 1):(j + 1) * (k - 1) + 1].reshape(-1, 3)
            bottom = top.copy()
            bottom[:, 2] = base
            vertices = np.vstack([top, bottom])
            tiles.append(vertices)
            gap = max(gap, _hull_gap(vertices, top))
    return tiles, Tiling(tiles=(nu, nv), points_per_edge=k, hull_gap=gap, base_z=base)


def _hull_gap(vertices: np.ndarray, top: np.ndarray) -> float:
    """Largest height of the hull's upper boundary above the surface points ``top``."""
    hull = ConvexHull(vertices)
    a, b = hull.equations[:, :3], hull.equations[:, 3]  # a.x + b <= 0 inside
    upper = a[:, 2] > 1e-9
    if not np.any(upper):
        return 0.0
    au, bu = a[upper], b[upper]
    # the upper boundary above (x, y): the lowest of the upward facets' planes
    z_top = np.min(-(bu[None, :] + top[:, :1] * au[None, :, 0] + top[:, 1:2] * au[None, :, 1]) / au[None, :, 2],
                   axis=1)
    return float(max(0.0, np.max(z_top - top[:, 2])))


def build_model(model_file: Path, surface: NurbsSurface, *, tile_size: float, friction: float | None = None,
                label: Path | str = "<model>") -> tuple[mujoco.MjModel, Tiling]:
    """The scene with the surface as its workpiece, compiled.

    Raises
    ------
    ScenarioError
        If the scene has no block workpiece to replace, or the result does not compile.
    """
    spec = mujoco.MjSpec.from_file(str(model_file))
    try:
        block = spec.geom(BLOCK_GEOM)
    except Exception:  # pragma: no cover - the binding's lookup raises on unknown names
        block = None
    if block is None:
        raise ScenarioError(label, "program.surface", f"the scene has no geom '{BLOCK_GEOM}' to replace with the surface")
    body = block.parent
    contact = dict(contype=block.contype, conaffinity=block.conaffinity, group=block.group,
                   friction=block.friction.copy(), solref=block.solref.copy(), solimp=block.solimp.copy())
    if friction is not None:
        contact["friction"][0] = friction
    spec.delete(block)
    if os.environ.get("CNC_CONDIM"):
        spec.geom(PAD_GEOM).condim = int(os.environ["CNC_CONDIM"])
    tiles, tiling = tile_meshes(surface, tile_size=tile_size)
    for n, vertices in enumerate(tiles):
        mesh = spec.add_mesh(name=f"surface_tile_{n}")
        mesh.uservert = vertices.ravel().tolist()
        geom = body.add_geom(name=f"surface_tile_{n}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh.name,
                             rgba=[0.7, 0.7, 0.75, 1.0], density=0.0)
        for key, value in contact.items():
            setattr(geom, key, value)
        if os.environ.get("CNC_CONDIM"):
            geom.condim = int(os.environ["CNC_CONDIM"])
    vertices, faces = surface.tessellate(64, 64)
    visual = spec.add_mesh(name="surface_visual")
    visual.uservert = vertices.ravel().tolist()
    visual.userface = faces.ravel().tolist()
    visual.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    body.add_geom(name="surface_visual", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="surface_visual",
                  contype=0, conaffinity=0, group=2, density=0.0, rgba=[0.72, 0.74, 0.8, 1.0])
    try:
        model = spec.compile()
    except ValueError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "does not compile"
        raise ScenarioError(label, "program.surface", f"the surface's meshes do not compile: {first}") from None
    return model, tiling


def pad_radius(model: mujoco.MjModel) -> float:
    """Radius of the pad's contact face [m] (geom ``pad_collision``)."""
    return float(model.geom(PAD_GEOM).size[0])

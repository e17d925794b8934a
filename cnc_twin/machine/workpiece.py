"""The workpiece of a surface program as MuJoCo geometry: a NURBS surface turned into meshes.

MuJoCo collides with a mesh's convex hull. A convex face (a plate, a dome) is therefore one mesh:
the surface sampled 33 x 33 plus the same points dropped to the base. Any other face (a saddle's
hull would bridge its hollows) is cut into tiles in
(u, v); each tile is a mesh of ``(k + 1)^2`` surface points plus the same points dropped to the
solid's base, whose convex hull is the tile's collision shape. On a convex (dome-like) region the
hull's top is the surface itself, up to the tessellation's chord; in a hollow the hull bridges it
by at most the *hull gap*, measured here on the upper hull and reported, so a user sees how
faithful the contact geometry is and can ask for smaller tiles. Tiles meet in seams where the pad
can catch a neighbour's side face (a sideways contact, a bump in the force): fewer, larger tiles
where the face allows.

:func:`build_model` loads the scene with ``mujoco.MjSpec``, removes the block workpiece
(geom ``workpiece_collision``), adds the tiles (collision group 3, contype 1 / conaffinity 2 like
the block; frictionless, with the pad, see below), a fine visual mesh of the surface (group 2, no
contact) and a contact sensor on the pad (:data:`PAD_CONTACTS`, read by the removal map), and compiles.
Units: m, world frame (the workpiece body sits at the world origin).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial import ConvexHull

from cnc_twin.core.errors import ScenarioError
from cnc_twin.machine.model_file import BLOCK_GEOM
from cnc_twin.geometry.surface import NurbsSurface, parameter_scales

WORKPIECE_BODY = "workpiece"
PAD_GEOM = "pad_collision"
PAD_CONTACTS = "pad_contacts"
"""the contact sensor on the pad's geom: per slot the matches found, the contact force (normal
first, contact frame) and the contact normal, for every pad contact in MuJoCo's order"""
PAD_CONTACT_SLOTS = 16
"""pad contacts the sensor reports at most (a pad on a tiled face makes 1-6)"""
PAD_CONTACT_FIELDS = 7
"""values per slot: found, force (3), normal (3)"""
CONVEX_TOLERANCE = 1e-6
"""a face whose single hull stands no more than this above it is meshed as one tile [m]"""
ONE_TILE_POINTS = 33
"""surface points per edge of a one-tile face"""
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
    lu, lv, _, _ = parameter_scales(surface)
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    # A convex face (flat, dome) is one hull: no seams between tiles for the pad to catch on.
    one, tiling = _tiles(surface, 1, 1, ONE_TILE_POINTS)
    if tiling.hull_gap <= CONVEX_TOLERANCE:
        return one, tiling
    nu = max(1, int(np.ceil((u1 - u0) * lu / tile_size)))
    nv = max(1, int(np.ceil((v1 - v0) * lv / tile_size)))
    return _tiles(surface, nu, nv, points_per_edge)


def _tiles(surface: NurbsSurface, nu: int, nv: int, k: int) -> tuple[list[np.ndarray], Tiling]:
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


def build_model(model_file: Path, surface: NurbsSurface, *, tile_size: float, label: Path | str = "<model>",
                edit=None) -> tuple[mujoco.MjModel, Tiling]:
    """The scene with the surface as its workpiece, compiled; ``edit(spec)``, if given, may add
    more to the spec before it compiles (e.g. :func:`cnc_twin.machine.model_file.add_obstacles`).

    Raises
    ------
    ScenarioError
        If the scene has no block workpiece to replace, or the result does not compile.
    """
    spec = mujoco.MjSpec.from_file(str(model_file))
    block = spec.geom(BLOCK_GEOM)  # None when the scene has no such geom
    if block is None:
        raise ScenarioError(label, "program.surface", f"the scene has no geom '{BLOCK_GEOM}' to replace with the surface")
    body = block.parent
    contact = dict(contype=block.contype, conaffinity=block.conaffinity, group=block.group,
                   friction=block.friction.copy(), solref=block.solref.copy(), solimp=block.solimp.copy())
    spec.delete(block)
    # Frictionless pad contact: MuJoCo gives a flat spinning pad one contact point, wherever on
    # its face, and full sliding friction there (a jittering force in a random direction, a
    # 300 Hz load-cell ripple of 1 N at 1200 rpm). The pad's friction is applied from the
    # pressure distribution instead (cnc_twin.polishing.polish.friction_wrench).
    spec.geom(PAD_GEOM).condim = 1
    tiles, tiling = tile_meshes(surface, tile_size=tile_size)
    for n, vertices in enumerate(tiles):
        mesh = spec.add_mesh(name=f"surface_tile_{n}")
        mesh.uservert = vertices.ravel().tolist()
        geom = body.add_geom(name=f"surface_tile_{n}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh.name,
                             rgba=[0.7, 0.7, 0.75, 1.0], density=0.0)
        for key, value in contact.items():
            setattr(geom, key, value)
        geom.condim = 1
    fields = sum(1 << int(f) for f in (mujoco.mjtConDataField.mjCONDATA_FOUND, mujoco.mjtConDataField.mjCONDATA_FORCE,
                                       mujoco.mjtConDataField.mjCONDATA_NORMAL))
    spec.add_sensor(name=PAD_CONTACTS, type=mujoco.mjtSensor.mjSENS_CONTACT, objtype=mujoco.mjtObj.mjOBJ_GEOM,
                    objname=PAD_GEOM, intprm=[fields, 0, PAD_CONTACT_SLOTS])  # reduce 0: all, in contact order
    vertices, faces = surface.tessellate(64, 64)
    visual = spec.add_mesh(name="surface_visual")
    visual.uservert = vertices.ravel().tolist()
    visual.userface = faces.ravel().tolist()
    visual.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    body.add_geom(name="surface_visual", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="surface_visual",
                  contype=0, conaffinity=0, group=2, density=0.0, rgba=[0.72, 0.74, 0.8, 1.0])
    if edit is not None:
        edit(spec)
    try:
        model = spec.compile()
    except ValueError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "does not compile"
        raise ScenarioError(label, "program.surface", f"the surface's meshes do not compile: {first}") from None
    return model, tiling


def pad_friction(model: mujoco.MjModel) -> float:
    """Sliding friction coefficient of the pad's geom in the MJCF."""
    return float(model.geom(PAD_GEOM).friction[0])


def pad_radius(model: mujoco.MjModel) -> float:
    """Radius of the pad's contact face [m] (geom ``pad_collision``)."""
    return float(model.geom(PAD_GEOM).size[0])

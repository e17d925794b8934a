"""A polishing run's workpiece, built once per process and handed to every later run of the same one.

A sweep's runs differ in gains and settings, not in the workpiece: the surface's collision tiles
(convex hulls), the scene compiled around them and the removal map's grid of surface points are
the same for each. :func:`workpiece` builds them on the first run and keeps the last few, keyed
by everything they depend on (the scene file and every file beside it, its includes and meshes,
by name, size and modification time; the surface, the tile size, the obstacle boxes, the grid's
pitch); every run gets its own copy of the compiled
model (a run may change its model: the timestep, an injected fault), the tiles' figures and the
grid are shared read-only. About 50 ms per freeform run (the MJCF compile 19 ms, the hulls 14 ms,
the grid 12 ms).
"""

from __future__ import annotations

import copy
import hashlib
import pickle
from collections import OrderedDict
from pathlib import Path

import mujoco

from cnc_twin.geometry.surface import NurbsSurface, parameter_scales
from cnc_twin.machine.model_file import add_obstacles, folder_state
from cnc_twin.machine.workpiece import Tiling, build_model
from cnc_twin.polishing.polish import removal_grid

KEPT = 4
"""workpieces a process keeps"""
_BUILT: OrderedDict[bytes, tuple] = OrderedDict()


def workpiece(model_file: Path, surface_def, tile_size: float, obstacles: list, grid_spacing: float
              ) -> tuple[NurbsSurface, mujoco.MjModel, Tiling, tuple]:
    """``(surface, model, tiling, grid)``: the surface
    (:class:`~cnc_twin.geometry.surface.NurbsSurface`), the scene compiled with it as the workpiece
    and the obstacle boxes (a copy of its own), the tiling's figures, and the removal map's
    ``(scales, grid, uv)`` (:func:`cnc_twin.polishing.polish.removal_grid`) for ``grid_spacing``
    [m]. Raises what :func:`~cnc_twin.machine.workpiece.build_model` raises (nothing is kept
    then)."""
    path = Path(model_file)
    key = hashlib.sha256(pickle.dumps((folder_state(path), surface_def, tile_size,
                                       [tuple(map(tuple, box)) for box in obstacles], grid_spacing),
                                      protocol=pickle.HIGHEST_PROTOCOL)).digest()
    built = _BUILT.get(key)
    if built is None:
        surface = NurbsSurface.from_def(surface_def)
        model, tiling = build_model(path, surface, tile_size=tile_size, edit=lambda spec: add_obstacles(spec, obstacles))
        scales = parameter_scales(surface)[:2]
        built = (surface, model, tiling, (scales, *removal_grid(surface, grid_spacing, scales)))
        _BUILT[key] = built
        while len(_BUILT) > KEPT:
            _BUILT.popitem(last=False)
    else:
        _BUILT.move_to_end(key)
    surface, model, tiling, grid = built
    return surface, copy.copy(model), tiling, grid


def forget() -> None:
    """Drop every workpiece kept (the next run builds its own again)."""
    _BUILT.clear()

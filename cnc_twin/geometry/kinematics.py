"""Head kinematics: tool-tip position and tool axis <-> X/Y/Z/A/B.

The linear axes carry the A/B pivot; A turns about x, then B about y (in A's frame); the tool tip
sits at a fixed offset from the pivot in B's frame. With A and B held the tip moves with X/Y/Z
one to one, so an axis-space path is the tip path shifted by a constant::

    pivot(X, Y, Z)  = pivot_home + (X, Y, Z)
    tip             = pivot(X, Y, Z) + Rx(A) Ry(B) offset
    (X, Y, Z)       = tip - pivot_home - Rx(A) Ry(B) offset

``pivot_home`` and ``offset`` are read from the MJCF at the home keyframe (body ``a_yoke``,
site ``tool_site``), and the workpiece frame's origin from site ``workpiece_site``. Positions in m.

Tool axis: the unit vector from the tip towards the spindle, ``n = Rx(A) Ry(B) (0, 0, 1)
= (sin B, -sin A cos B, cos A cos B)``, so ``B = asin(n_x)`` and ``A = atan2(-n_y, n_z)``
(the branch with ``|B| < 90`` deg and the tool pointing down, n_z cos A > 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from cnc_twin.core.axes import HOME_KEYFRAME

class UnreachablePose(ValueError):
    """A tool pose the head cannot take; ``index`` is the first offending pose, ``reason`` why."""

    def __init__(self, index: int, reason: str):
        self.index, self.reason = index, reason
        super().__init__(f"pose {index}: {reason}")


PIVOT_BODY = "a_yoke"
TOOL_SITE = "tool_site"
WORKPIECE_SITE = "workpiece_site"


def ab_from_axis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Head angles A, B [rad] that point the tool along ``n`` (shape (..., 3), any length > 0)."""
    n = np.asarray(n, dtype=np.float64)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    b = np.arcsin(np.clip(n[..., 0], -1.0, 1.0))
    a = np.arctan2(-n[..., 1], n[..., 2])
    return a, b


def pose_to_axes(tip, n, pivot, offset) -> tuple[float, float, float, float, float]:
    """Scalar inverse kinematics for the card's per-period work: X, Y, Z [m], A, B [rad] that put
    the tool tip at ``tip`` with the tool along ``n`` (any length > 0); ``pivot`` is the A/B
    pivot at X = Y = Z = 0 and ``offset`` the tip - pivot at A = B = 0 (3-sequences, m)."""
    # indexed, not unpacked: the batch kernel compiles this function for arrays too
    nx, ny, nz = n[0], n[1], n[2]
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    b = math.asin(max(-1.0, min(1.0, nx * inv)))
    a = math.atan2(-ny * inv, nz * inv)
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    ox, oy, oz = offset[0], offset[1], offset[2]
    x1, z1 = cb * ox + sb * oz, -sb * ox + cb * oz
    rx, ry, rz = x1, ca * oy - sa * z1, sa * oy + ca * z1
    return (tip[0] - pivot[0] - rx, tip[1] - pivot[1] - ry, tip[2] - pivot[2] - rz, a, b)


def tool_axis(a: float, b: float) -> tuple[float, float, float]:
    """Unit tool axis (world frame, from the tip towards the head) at head angles A, B [rad]:
    ``Rx(a) Ry(b) (0, 0, 1)``, as :meth:`HeadGeometry.forward` gives it."""
    sa, ca, sb, cb = math.sin(a), math.cos(a), math.sin(b), math.cos(b)
    return (sb, -sa * cb, ca * cb)


def rotation_ab(a: float, b: float) -> np.ndarray:
    """``Rx(a) @ Ry(b)``, shape (3, 3); angles [rad]."""
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    return rx @ ry


@dataclass(frozen=True)
class HeadGeometry:
    """Offsets of the reference machine read from its MJCF (all in the world frame, m)."""

    pivot_home: tuple[float, float, float]
    tool_offset: tuple[float, float, float]
    """tip - pivot at A = B = 0"""
    workpiece_origin: tuple[float, float, float]

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> "HeadGeometry":
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, model.key(HOME_KEYFRAME).id)
        pad = model.joint("pad_joint")
        data.qpos[pad.qposadr[0]] = 0.0  # nominal, undeflected pad
        mujoco.mj_kinematics(model, data)
        pivot = data.body(PIVOT_BODY).xpos.copy()
        tip = data.site(TOOL_SITE).xpos.copy()
        origin = data.site(WORKPIECE_SITE).xpos.copy()
        return cls(tuple(float(x) for x in pivot), tuple(float(x) for x in tip - pivot),
                   tuple(float(x) for x in origin))

    def axes_from_tip(self, tip_world: np.ndarray, a: float, b: float) -> np.ndarray:
        """X/Y/Z [m] that put the tool tip at ``tip_world`` (shape (..., 3)) with A, B [rad] held."""
        shift = np.asarray(self.pivot_home) + rotation_ab(a, b) @ np.asarray(self.tool_offset)
        return np.asarray(tip_world) - shift

    def tip_from_axes(self, xyz: np.ndarray, a: float, b: float) -> np.ndarray:
        """Tool tip [m] in the world frame for axis positions X/Y/Z (shape (..., 3)) and A, B."""
        shift = np.asarray(self.pivot_home) + rotation_ab(a, b) @ np.asarray(self.tool_offset)
        return np.asarray(xyz) + shift

    def axes_from_pose(self, tip_world: np.ndarray, axis: np.ndarray) -> np.ndarray:
        """X/Y/Z/A/B (shape (m, 5)) that put the tip at ``tip_world`` with the tool along ``axis``
        (both shape (m, 3), world frame)."""
        a, b = ab_from_axis(axis)
        ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        ox, oy, oz = self.tool_offset
        # Rx(a) Ry(b) offset, vectorised
        x1, y1, z1 = cb * ox + sb * oz, np.full_like(a, oy), -sb * ox + cb * oz
        rotated = np.stack([x1, ca * y1 - sa * z1, sa * y1 + ca * z1], axis=-1)
        xyz = np.asarray(tip_world) - np.asarray(self.pivot_home) - rotated
        return np.column_stack([xyz, a, b])

    def forward(self, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tool tip and unit tool axis (each (m, 3), world frame) for X/Y/Z/A/B rows (m, 5)."""
        q = np.atleast_2d(np.asarray(axes, dtype=np.float64))
        a, b = q[:, 3], q[:, 4]
        ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        ox, oy, oz = self.tool_offset
        x1, z1 = cb * ox + sb * oz, -sb * ox + cb * oz
        rotated = np.stack([x1, ca * oy - sa * z1, sa * oy + ca * z1], axis=-1)
        tip = q[:, :3] + np.asarray(self.pivot_home) + rotated
        axis = np.stack([sb, -sa * cb, ca * cb], axis=-1)
        return tip, axis

    def inverse(self, tip_world: np.ndarray, axis: np.ndarray, *, travel=None) -> np.ndarray:
        """X/Y/Z/A/B (m, 5) for tool poses, refusing any the head cannot take.

        ``travel``: optional per-axis ``(lo, hi)`` [m | rad] (or None) for X, Y, Z, A, B.

        Raises
        ------
        UnreachablePose
            For the first pose whose tool axis does not point down into the head's branch
            (z component <= 0: ``|B|`` would reach 90 deg) or whose axes leave their travel.
        """
        n = np.atleast_2d(np.asarray(axis, dtype=np.float64))
        n = n / np.linalg.norm(n, axis=1, keepdims=True)
        bad = np.flatnonzero(n[:, 2] <= 1e-9)
        if bad.size:
            raise UnreachablePose(int(bad[0]), f"tool axis {np.round(n[bad[0]], 4).tolist()} does not point "
                                  "into the head's working range (it needs an upward component)")
        q = self.axes_from_pose(np.atleast_2d(tip_world), n)
        if travel is not None:
            names = "XYZAB"
            for i, rng in enumerate(travel):
                if rng is None:
                    continue
                out = np.flatnonzero((q[:, i] < rng[0] - 1e-12) | (q[:, i] > rng[1] + 1e-12))
                if out.size:
                    j = int(out[0])
                    f, unit = (180.0 / math.pi, "deg") if i >= 3 else (1e3, "mm")
                    raise UnreachablePose(j, f"{names[i]} would be {q[j, i] * f:.3f} {unit}, outside its travel "
                                          f"{rng[0] * f:g}..{rng[1] * f:g} {unit}")
        return q

    def world_from_workpiece(self, points: np.ndarray) -> np.ndarray:
        """Workpiece-frame points (origin at the workpiece top centre, axes as the world's) -> world."""
        return np.asarray(points) + np.asarray(self.workpiece_origin)

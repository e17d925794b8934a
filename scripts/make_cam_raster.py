"""Write the bundled dense-G1 program: a 5-axis CAM-style raster over the freeform_polish face.

The face is the NURBS surface of ``scenarios/freeform_polish.yaml`` (workpiece frame, mm). The
raster runs along u in passes 7 mm apart across the middle of the face (25 mm from its edges, the
pad radius), zig-zag, with a point every ``STEP`` mm of surface and the tool along the surface
normal at each (A / B words from the head's kinematics, ``ab_from_axis``), the tip ``LIFT`` mm
above the face along the normal: a dry run of the path, clear of the part, as a machinist tries a
program before cutting. As CAM writes it: plain G1 X Y Z A B lines, four decimals.

Two programs, the same points: ``programs/cam_raster.ngc`` under ``G64 P0.01`` (the planner
fits each pass within 10 um and 0.05 deg) and ``programs/cam_raster_exact.ngc`` under ``G61.1``
(segment by segment, a stop at every point), with a scenario each in ``scenarios/``.

    python scripts/make_cam_raster.py        # writes the four files; the same bytes every time

The passes are linked by half circles (a point every STEP mm) as CAM links a zig-zag, so the
whole raster is one run of gently turning lines for the fit.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cnc_twin.geometry.kinematics import ab_from_axis  # noqa: E402
from cnc_twin.geometry.surface import NurbsSurface  # noqa: E402

STEP = 0.3
"""[mm] between programmed points along a pass"""
STEP_OVER = 7.0
"""[mm] between passes"""
MARGIN = 25.0
"""[mm] from the face's edges"""
LIFT = 1.0
"""[mm] the tip above the face along its normal"""
FEED = 3000.0
"""[mm/min]"""
MODES = {"cam_raster": "G64 P0.01", "cam_raster_exact": "G61.1"}


def face() -> NurbsSurface:
    spec = yaml.safe_load((ROOT / "scenarios" / "freeform_polish.yaml").read_text())["program"]["surface"]
    return NurbsSurface(np.asarray(spec["control_net"], dtype=float), None, spec["knots_u"], spec["knots_v"],
                        spec["degree_u"], spec["degree_v"])


def raster(surface: NurbsSurface) -> list[np.ndarray]:
    """The passes, each (k, 6): tip x y z [mm] and the unit tool axis, zig-zag."""
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    # the face's extent in x and y (its control net is a grid over x, y): the parameters that
    # keep MARGIN from the edges, found along the middle lines
    us = np.linspace(u0, u1, 4001)
    vs = np.linspace(v0, v1, 4001)
    x = surface.point(us, np.full_like(us, 0.5 * (v0 + v1)))[:, 0]
    y = surface.point(np.full_like(vs, 0.5 * (u0 + u1)), vs)[:, 1]
    u_lo, u_hi = us[np.searchsorted(x, x[0] + MARGIN)], us[np.searchsorted(x, x[-1] - MARGIN) - 1]
    v_lo, v_hi = vs[np.searchsorted(y, y[0] + MARGIN)], vs[np.searchsorted(y, y[-1] - MARGIN) - 1]
    passes = []
    count = int(math.floor((y[-1] - y[0] - 2 * MARGIN) / STEP_OVER)) + 1
    for k, v in enumerate(np.linspace(v_lo, v_hi, count)):
        dense = np.linspace(u_lo, u_hi, 20001)
        p = surface.point(dense, np.full_like(dense, v))
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        u = np.interp(np.arange(0.0, s[-1], STEP), s, dense)  # a point every STEP mm of surface
        vv = np.full_like(u, v)
        n = surface.normal(u, vv)
        n = n * np.sign(n[:, 2:3])  # up, out of the face
        tip = surface.point(u, vv) + LIFT * n
        run = np.hstack([tip, n])
        passes.append(run if k % 2 == 0 else run[::-1])
    return passes


def _link(before: np.ndarray, after: np.ndarray) -> list[str]:
    """The words of the points of a half-circle link from the end of one pass to the start of the
    next (``before``: the pass's last two points, ``after``: the next pass's first two, each x y z
    + axis), bulging outwards past the pass ends, a point every STEP mm. Z and the tool axis follow
    cubic Hermite curves that leave and join the passes with their own slopes, as a CAM system's
    smooth link does (a linear blend would put a kink in both at each end)."""
    end, start = before[-1], after[0]
    chord = start[:3] - end[:3]
    radius = 0.5 * float(np.linalg.norm(chord[:2]))
    centre = end[:3] + 0.5 * chord
    out_dir = np.sign(end[0]) * np.array([1.0, 0.0, 0.0])  # past the end of the pass, along x
    length = math.pi * radius
    # slopes per mm along the path: z and the axis components at the pass's end and the next start
    d0 = (before[-1, 2:] - before[-2, 2:]) / np.linalg.norm(before[-1, :2] - before[-2, :2])
    d1 = (after[1, 2:] - after[0, 2:]) / np.linalg.norm(after[1, :2] - after[0, :2])
    count = max(2, int(math.ceil(length / STEP)))
    words = []
    for k in range(1, count):
        t = k / count
        angle = math.pi * t
        p = centre - math.cos(angle) * 0.5 * chord + math.sin(angle) * radius * out_dir
        h00, h10, h01, h11 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t, -2 * t**3 + 3 * t**2, t**3 - t**2
        zn = h00 * end[2:] + h10 * length * d0 + h01 * start[2:] + h11 * length * d1  # z, then the axis
        n = zn[1:] / np.linalg.norm(zn[1:])
        a, b = (math.degrees(float(v)) for v in ab_from_axis(n))
        words.append(f"X{p[0]:.4f} Y{p[1]:.4f} Z{zn[0]:.4f} A{a:.4f} B{b:.4f}")
    return words


def program_text(name: str, passes: list[np.ndarray]) -> str:
    points = sum(len(p) for p in passes)
    head = [
        f"; {name}: a 5-axis CAM-style raster over the freeform_polish face, {len(passes)} passes of "
        f"{points} points in all, linked by half circles,",
        f"; {STEP_OVER:g} mm apart, a point every {STEP:g} mm, the tool along the face's normal (A B), the tip "
        f"{LIFT:g} mm above it:",
        "; a dry run of the path. Written by scripts/make_cam_raster.py from scenarios/freeform_polish.yaml.",
        "; X Y Z: the tool tip in the workpiece frame [mm]; A B: the head's angles [deg].",
        f"G21 G90 G17 G94 {MODES[name]}",
        "G0 Z40",
    ]
    body = []
    for k, run in enumerate(passes):
        a, b = (np.degrees(v) for v in ab_from_axis(run[:, 3:]))
        words = [f"X{x:.4f} Y{y:.4f} Z{z:.4f} A{p:.4f} B{q:.4f}" for (x, y, z), p, q in zip(run[:, :3], a, b)]
        if k == 0:
            x, y, z = run[0, :3]
            body += [f"G0 X{x:.4f} Y{y:.4f} A{a[0]:.4f} B{b[0]:.4f}", f"G1 Z{z:.4f} F600", f"F{FEED:g}"]
            body += [f"G1 {w}" for w in words[1:]]
        else:  # the step over to the next pass along a half circle (as CAM links a zig-zag), then the pass
            body += [f"G1 {w}" for w in _link(passes[k - 1][-2:], run[:2])]
            body += [f"G1 {w}" for w in words]
    tail = ["G0 Z40", "G0 A0 B0", "M2"]
    return "\n".join(head + body + tail) + "\n"


def scenario_text(name: str) -> str:
    exact = name.endswith("exact")
    what = "segment by segment (G61.1)" if exact else "fitted within G64 P0.01"
    return "\n".join([
        "# yaml-language-server: $schema=scenario.schema.json",  # editors: the schema beside it (cnc-twin schema)
        f"# The dense 5-axis CAM raster (programs/{name}.ngc, written by scripts/make_cam_raster.py) run {what}.",
        "# The tip passes 1 mm above the freeform_polish face; the scene's block lies below it.",
        f"name: gcode_{name}",
        f"description: Dense 5-axis CAM raster over the freeform face, {what}.",
        "program:",
        "  type: gcode",
        f"  file: ../programs/{name}.ngc",
        "  axis_tolerance: 0.05      # deg",
        "  settle: 0.3               # s",
    ]) + "\n"


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT, help="folder holding programs/ and scenarios/ (default: the project)")
    out = parser.parse_args(argv).out
    passes = raster(face())
    for name in MODES:
        for folder in ("programs", "scenarios"):
            (out / folder).mkdir(parents=True, exist_ok=True)
        (out / "programs" / f"{name}.ngc").write_text(program_text(name, passes))
        (out / "scenarios" / f"gcode_{name}.yaml").write_text(scenario_text(name))
        print(f"programs/{name}.ngc: {sum(len(p) for p in passes)} points in {len(passes)} passes, "
              f"{program_text(name, passes).count(chr(10) + 'G1 ')} G1 lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Transcribe the published NURBS benchmark curves into the project's own scenario files.

    python scripts/transcribe_published_curves.py [SOURCE_DIR] [--out scenarios/published]

SOURCE_DIR holds LinuxCNC's ``nc_files/nurbs/G6`` programs (default: ``../shared/data/
linuxcnc-nurbs/G6`` next to the repository). Each program's first G6.2 curve (Fanuc form:
``G6.2 X Y R<weight> K<knot> P<order> Q<method>``, then ``X Y R K`` blocks, then knot-only
``G6.2 K`` blocks) becomes a ``nurbs_curve`` scenario: the control points (X, Y and the Z in
effect), the weights and the knot vector exactly as written, degree = order - 1. The curve is
placed as programmed in the XY plane, ``LIFT`` mm above the workpiece top (the programs cut at
Z0 .. Z-1 on their own machine's work offset; the twin only needs the path).

Each curve is also written as an NC program in the authors' G6.2 form (``--programs``, default
``programs/published``): the same numbers, the same plane and feed, reached by rapids from a
safe height, for ``cnc-twin run programs/published/NAME.ngc``.

This reads the numbers only; the output files cite their source and do not copy the programs.
Run by a developer when the source changes; the scenarios and programs it writes are committed.
"""

from __future__ import annotations

import argparse
import re
import sys
import textwrap
from pathlib import Path

CURVES = {
    # output name: (source file, curve's name in the paper)
    "farfalla": ("Curva_Farfalla #1=1.ngc", "Farfalla (butterfly)"),
    "delfino": ("Curva_Delfino #1=1.ngc", "Delfino (dolphin)"),
    "chitarra": ("Curva_Chitarra #1=1.ngc", "Chitarra (guitar)"),
    "stella": ("Curva_Stella #1=1.ngc", "Stella (star)"),
    "mazatrol": ("Curva_Mazatrol #1=1-xy.ngc", "Mazatrol"),
    # longer than one record (2048 words): the card receives their geometry in parts
    "scroll_m": ("Curva_Scrool_M #1=1.ngc", "Scroll M (scroll)"),          # 221 control points
    "scroll_f": ("Curva_Scrool_F #1=1.ngc", "Scroll F (scroll)"),          # 666
    "ruota_dentata": ("Ruota_dentata #1=1.ngc", "Ruota dentata (gear)"),   # 589
}
# UNIPA and homer hold many curves each, with moves between: they run as the .ngc programs
# themselves once the G-code reader reads them.
LIFT = 10.0
"""height of the curve's plane above the workpiece top [mm]"""
FEED = 2400
"""feed along the curve [mm/min], the scenarios' and the programs'"""
SAFE_Z = 20.0
"""the programs' traverse height above the workpiece top [mm]"""
SETTLE = 0.2
"""the scenarios' settle before the curve [s]: the programs' dwell at the start"""
CITATION = ("Lo Valvo, E. and Drago, S., \"An Efficient NURBS Path Generator for a Open Source CNC\"; "
            "the programs as LinuxCNC ships them (nc_files/nurbs/G6, LinuxCNC repository commit 5c41560, "
            "modified for LinuxCNC by J. Franek, 2023-01-20)")
WORD = re.compile(r"([A-Z])\s*([-+]?\d*\.?\d+)")


def strip_comments(line: str) -> str:
    """The line without ``( ... )`` and ``;`` comments, upper case."""
    return re.sub(r"\([^)]*\)", "", line.split(";")[0]).upper()


def first_curve(text: str) -> dict:
    """Control points, weights, knots and order of the first G6.2 curve in ``text``."""
    z = 0.0
    points, weights, knots = [], [], []
    order = None
    inside = False
    for raw in text.splitlines():
        line = strip_comments(raw)
        words = dict(WORD.findall(line))
        starts = "G6.2" in line.replace(" ", "")
        if not inside:
            if "Z" in words and not starts:
                z = float(words["Z"])
            if not starts:
                continue
            inside = True
            order = int(words["P"])
        if "X" in words or "Y" in words:
            if "K" not in words or "R" not in words:
                raise ValueError(f"control point without R and K: {raw.strip()!r}")
            x = float(words.get("X", points[-1][0] if points else 0.0))
            y = float(words.get("Y", points[-1][1] if points else 0.0))
            points.append((x, y, z))
            weights.append(float(words["R"]))
            knots.append(float(words["K"]))
        elif starts and set(words) == {"G", "K"}:
            knots.append(float(words["K"]))
            if len(knots) == len(points) + order:
                return {"points": points, "weights": weights, "knots": knots, "order": order}
        elif inside and line.strip():
            break
    raise ValueError("no complete G6.2 curve (knots != points + order)")


def number(x: float) -> str:
    return f"{x:.6g}" if x != int(x) else str(int(x))


def scenario_text(name: str, source: str, title: str, curve: dict) -> str:
    pts = curve["points"]
    lines = [
        "# yaml-language-server: $schema=../scenario.schema.json",  # editors: the bundled schema (cnc-twin schema)
        f"# {title}: a published NURBS benchmark curve, degree {curve['order'] - 1}, {len(pts)} control points.",
        f"# Source: {CITATION}, file '{source}'.",
        "# The control points, weights and knots are transcribed from that program as written (mm);",
        f"# the curve lies in the program's XY plane at its cutting depth raised by {LIFT:g} mm (above the workpiece top).",
        "# Written by scripts/transcribe_published_curves.py. Units: mm, mm/min, mm/s^2, mm/s^3, deg, s.",
        f"name: published_{name}",
        f"description: {title} (Lo Valvo & Drago) at {FEED} mm/min, 1 um chord tolerance, tool axis vertical.",
        "program:",
        "  type: nurbs_curve",
        f"  degree: {curve['order'] - 1}",
        "  control_points:",
    ]
    lines += [f"    - [{number(x)}, {number(y)}, {number(z + LIFT)}]" for x, y, z in pts]
    lines.append(f"  weights: [{', '.join(number(w) for w in curve['weights'])}]")
    lines.append(f"  knots: [{', '.join(number(k) for k in curve['knots'])}]")
    lines += [
        f"  feed: {FEED:<22}# mm/min",
        "  chord_tolerance: 0.001      # mm",
        "  limits: {path_acceleration: 2000, path_jerk: 50000, normal_acceleration: 2000, normal_jerk: 50000}",
        "  tool_axis: {A: 0, B: 0}",
        "  approach_feed: 12000",
        f"  settle: {SETTLE:g}",
    ]
    return "\n".join(lines) + "\n"


def program_text(name: str, source: str, title: str, curve: dict) -> str:
    """The curve as an NC program in the authors' G6.2 form (``;`` comments: the citation holds
    parentheses): rapids to the curve's start in the scenario's plane, a dwell of the scenario's
    settle (the rapid's last micrometres die out before the curve), the feed, the control point
    blocks ``X Y R<weight> K<knot>`` (``P<order>`` on the first), the closing ``G6.2 K`` blocks,
    back up and M2. The numbers are written as :func:`scenario_text` writes them. Every line is
    well under LinuxCNC's 253 characters ("Command too long")."""
    pts = curve["points"]
    z = pts[0][2] + LIFT
    if any(p[2] + LIFT != z for p in pts):
        raise ValueError(f"{name}: the control points do not share one Z")
    knots = curve["knots"]
    lines = [
        f"; {title}: a published NURBS benchmark curve, degree {curve['order'] - 1}, {len(pts)} control points.",
        *textwrap.wrap(f"Source: {CITATION}, file '{source}'.", 96, initial_indent="; ", subsequent_indent=";   "),
        "; The control points, weights and knots are transcribed from the numbers of that program (mm), not a",
        "; copy of the file; the curve lies in the program's XY plane at its cutting depth raised by",
        f"; {LIFT:g} mm (above the workpiece top), as in scenarios/published/{name}.yaml, at the same feed.",
        "; Written by scripts/transcribe_published_curves.py.",
        "; X Y Z: the tool tip in the workpiece frame [mm], origin at the workpiece top centre.",
        "G21 G90 G17 G94 G64 P0.001",
        f"G0 Z{number(SAFE_Z)}",
        f"G0 X{number(pts[0][0])} Y{number(pts[0][1])}",
        f"G0 Z{number(z)}",
        f"G4 P{number(SETTLE)}    ; settle before the curve, as the scenario's settle",
        f"F{FEED}",
    ]
    for k, ((x, y, _), w, knot) in enumerate(zip(pts, curve["weights"], knots)):
        block = f"X{number(x)} Y{number(y)} R{number(w)} K{number(knot)}"
        lines.append(f"G6.2 {block} P{curve['order']}" if k == 0 else f"     {block}")
    lines += [f"G6.2 K{number(knot)}" for knot in knots[len(pts):]]
    lines += [f"G0 Z{number(SAFE_Z)}", "M2"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    here = Path(__file__).resolve().parent.parent
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", nargs="?", type=Path, default=here.parent / "shared/data/linuxcnc-nurbs/G6")
    parser.add_argument("--out", type=Path, default=here / "scenarios/published")
    parser.add_argument("--programs", type=Path, default=here / "programs/published")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    args.programs.mkdir(parents=True, exist_ok=True)
    for name, (file, title) in CURVES.items():
        curve = first_curve((args.source / file).read_text(encoding="utf-8", errors="replace"))
        out = args.out / f"{name}.yaml"
        out.write_text(scenario_text(name, file, title, curve), encoding="utf-8")
        print(f"{out}: degree {curve['order'] - 1}, {len(curve['points'])} points, {len(curve['knots'])} knots")
        program = args.programs / f"{name}.ngc"
        program.write_text(program_text(name, file, title, curve), encoding="utf-8")
        print(f"{program}: G6.2 P{curve['order']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

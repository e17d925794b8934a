"""Write the bundled circular-test programs (programs/ballbar_xy.ngc, _xz, _yz): ISO 230-4's
circles as a ballbar's own software writes them, counter-clockwise then clockwise.

    python scripts/make_ballbar_programs.py [--out programs]

Each pass: a rapid to 5 mm outside the circle, a radial feed-in, a lead-in arc of OVERSHOOT,
the full 360 deg data circle from the plane's first axis (0 deg), a lead-out arc of OVERSHOOT
and a radial feed-out. The circles lie above the workpiece (its top is Z0): XY at Z20 about
X0 Y0, XZ and YZ about Z70. Their scenarios (scenarios/ballbar_*.yaml) give the same centre,
radius and overshoot in their ``ballbar:`` section.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

RADIUS, FEED, OVERSHOOT, APPROACH = 50.0, 3000.0, 45.0, 5.0  # mm, mm/min, deg, mm
PLANES = {
    # plane: (G-code plane word, axis letters across / up, arc-centre letters, centre (X, Y, Z),
    #         the word that turns from the first axis towards the second)
    "xy": ("G17", ("X", "Y"), ("I", "J"), (0.0, 0.0, 20.0), "G3"),
    "xz": ("G18", ("X", "Z"), ("I", "K"), (0.0, 0.0, 70.0), "G2"),  # G18's G3 turns from Z towards X
    "yz": ("G19", ("Y", "Z"), ("J", "K"), (0.0, 0.0, 70.0), "G3"),
}


def program(plane: str, radius: float = RADIUS, feed: float = FEED, overshoot: float = OVERSHOOT) -> str:
    """The test program for ``plane`` (``xy``, ``xz``, ``yz``): radius [mm], feed [mm/min], overshoot [deg]."""
    word, (a, b), (i, j), centre, positive = PLANES[plane]
    negative = "G2" if positive == "G3" else "G3"
    index = {"X": 0, "Y": 1, "Z": 2}
    ca, cb = centre[index[a]], centre[index[b]]

    def at(angle_deg: float, r: float) -> tuple[float, float]:
        t = math.radians(angle_deg)
        return ca + r * math.cos(t), cb + r * math.sin(t)

    def move(angle_deg: float, r: float) -> str:
        pa, pb = at(angle_deg, r)
        return f"{a}{pa:.4f} {b}{pb:.4f}"

    def arc(turn: str, start_deg: float, end_deg: float) -> str:
        sa, sb = at(start_deg, radius)
        return f"{turn} {move(end_deg, radius)} {i}{ca - sa:.4f} {j}{cb - sb:.4f}"

    fixed = "".join(f" {axis}{centre[index[axis]]:.4f}" for axis in "XYZ" if axis not in (a, b))
    lines = [f"(circular test, ISO 230-4: {plane.upper()} plane, R{radius:g} mm about X{centre[0]:g} "
             f"Y{centre[1]:g} Z{centre[2]:g}, F{feed:g} mm/min)",
             f"(counter-clockwise then clockwise, {overshoot:g} deg lead-in and lead-out)",
             "(written by scripts/make_ballbar_programs.py)",
             f"G21 G90 G94 G40 G49 G54 {word} G64",
             "G0 Z130.0000",
             f"G0{fixed}"]
    for sign, turn in ((+1, positive), (-1, negative)):
        start, stop = -sign * overshoot, sign * overshoot
        lines += [f"G0 {move(start, radius + APPROACH)}",
                  f"G1 {move(start, radius)} F{feed:g}",
                  arc(turn, start, 0.0),
                  arc(turn, 0.0, 0.0),  # the whole circle: same end as start
                  arc(turn, 0.0, stop),
                  f"G1 {move(stop, radius + APPROACH)}"]
    lines += ["G0 Z130.0000", "M2"]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "programs")
    args = parser.parse_args()
    for plane in PLANES:
        path = args.out / f"ballbar_{plane}.ngc"
        path.write_text(program(plane), encoding="ascii")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

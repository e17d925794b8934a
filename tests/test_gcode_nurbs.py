"""NURBS blocks (G5.2 / G5.3, G6.2) collected into curves as LinuxCNC 2.9 collects them.

The G5.2 curves are checked point for point against LinuxCNC's own evaluation: its Python
``gcode`` module (``oracle_samples``) samples each curve at its parameters ``u`` (``n + 1``
points: ``(n + 1) * 15`` steps of ``umax / div`` summed as it sums them), and our NurbsCurve at
the same ``u`` must agree to 1e-9; ``rs274`` gives the NURBS_FEED counts and the refusals. G6.2
has no oracle in LinuxCNC 2.9 ("Unknown g code used"): its reference curves must be clamped,
start and end at their end control points, and where the knots are LinuxCNC's uniform ones the
same curve written as G5.2 must sample to the same points.

A small reader below drives the collectors the way the interpreter will (motion modes, G90 /
G91, the current point that stays put while a G5.2 curve is read); the reference programs
(``../shared/data/linuxcnc-nurbs``, GPL, read in place) are read with it.
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest

import oracle
import oracle_samples
import shared_data
from cnc_twin.gcode.blocks import BlockError, apply_assignments, read_block
from cnc_twin.gcode.expressions import Parameters
from cnc_twin.gcode.modal import g_code
from cnc_twin.gcode.nurbs import AXES, G52Collector, G62Collector, NurbsBlock, g53

REFERENCE = shared_data.LINUXCNC_NURBS
REFERENCE_ABSENT = (f"the published NURBS programs are not at {REFERENCE} (LinuxCNC's nc_files/nurbs, "
                    "see its README.md): this test reads them there")
TOLERANCE = 1e-9


def read_program(text: str) -> list[tuple[NurbsBlock, int]]:
    """The NURBS curves of ``text``, each with the line that finished it; BlockError (with its
    line as ``.line``) where the program is refused. Only what the NURBS need is modelled."""
    params, pos, absolute, plane, feed, per_minute = Parameters(), [0.0, 0.0, 0.0], True, 170, 0.0, True
    mode, collector, curves = None, None, []
    for number, line in enumerate(text.splitlines(), start=1):
        try:
            block = read_block(line, number, params)
            apply_assignments(block, params)
            # G6.2 is not LinuxCNC 2.9's (modal.py refuses it): the reader to come adds it to group 1
            codes = [62 if round(g * 10) == 62 else g_code(g) for g in block.g]
            absolute = {900: True, 910: False}.get(next((c for c in codes if c in (900, 910)), None), absolute)
            plane = next((c for c in codes if c in (170, 180, 190)), plane)
            per_minute = {930: False, 940: True, 950: False}.get(next((c for c in codes if c in (930, 940, 950)), None),
                                                                 per_minute)
            feed = block.words.get("f", feed)
            rate = feed if per_minute else None  # LinuxCNC checks the rate in G94 only
            motion = next((c for c in codes if c in (0, 10, 52, 53, 62)), None)
            axes = any(a in block.words for a in AXES)
            point = tuple(block.words.get(a, pos[i]) if absolute else pos[i] + block.words.get(a, 0.0)
                          for i, a in enumerate("xyz"))
            if motion == 53:
                curves.append((g53(collector, number), number))
                pos, mode, collector = list(curves[-1][0].end), None, None
            elif motion == 52 or (motion is None and mode == 52 and axes):
                if mode == 52 and collector is not None:
                    collector.add(block.words, point, number, feed_rate=rate)
                else:
                    collector, mode = G52Collector(tuple(pos), plane, block.words, point, number, feed_rate=rate), 52
            elif motion == 62 or (motion is None and mode == 62 and axes):
                if isinstance(collector, G62Collector):
                    collector.add(block.words, point, number, feed_rate=rate)
                else:
                    collector, mode = G62Collector(tuple(pos), plane, block.words, point, number, feed_rate=rate), 62
                if axes:
                    pos = list(point)  # Fanuc: an axis left out keeps the last control point's value
                if collector.complete:
                    curves.append((collector.finish(number), number))
                    mode, collector = None, None
            elif motion in (0, 10) or (motion is None and axes):
                mode = motion if motion is not None else mode
                collector = None  # another motion drops an open G5.2 curve
                pos = list(point)
        except BlockError as error:
            error.line = number
            raise
    return curves


def linuxcnc_parameters(block: NurbsBlock) -> np.ndarray:
    """The parameters gcodemodule's NURBS_FEED samples ``block`` at, summed as it sums them."""
    count, order = len(block.control_points), block.degree + 1
    umax = float(count - 1 - order + 2)
    step = umax / (count * 15)
    u, out = 0.0, []
    while u + step < umax:
        out.append(u + step)
        u = u + step
    return np.array(out)


def assert_samples_match(curves: list[tuple[NurbsBlock, int]], moves: list) -> None:
    """Each curve's samples among the module's ``moves`` (those of its finishing line) are our
    curve at LinuxCNC's parameters, then the last control point, at the start's z."""
    for block, line in curves:
        got = np.array([m.point for m in moves if m.kind == "feed" and m.line == line])
        u = linuxcnc_parameters(block)
        want = np.vstack([block.curve().point(u), block.control_points[-1]])
        assert got.shape == want.shape, f"line {line}: {len(got)} samples, expected {len(want)}"
        scale = max(1.0, float(np.max(np.abs(want))))
        assert np.max(np.abs(got - want)) < TOLERANCE * scale, f"curve ending line {line}"


def _run_both(program: str, tmp_path: Path):
    calls, said = oracle.run(program, tmp_path / "rs274")
    moves, error, _ = oracle_samples.run(program, tmp_path / "module")
    return calls, said, moves, error


def _nurbs_counts(calls) -> list[str]:
    return [args for name, args in calls if name == "NURBS_FEED"]


def _require_oracles() -> None:
    oracle.require()
    oracle_samples.require()


# --- G5.2: the rules, by hand ------------------------------------------------------------------

def test_the_current_point_is_the_first_control_point_and_the_knots_are_linuxcnc_s():
    collector = G52Collector((0.0, 0.0, 2.0), 170, {"p": 4.0, "l": 3.0}, (0.0, 0.0, 2.0), 7)
    for k, (x, y, p) in enumerate([(0, 1, 1), (2, 2, 1), (2, 0, 1), (0, 0, 2)]):
        collector.add({"x": x, "y": y, "p": p}, (x, y, 9.0), 8 + k)
    block = collector.finish(12)
    assert block.control_points.tolist() == [[0, 0, 2], [0, 1, 2], [2, 2, 2], [2, 0, 2], [0, 0, 2]]
    assert block.weights.tolist() == [4, 1, 1, 1, 2]  # P of a first block without X Y: the start's weight
    assert block.knots.tolist() == [0, 0, 0, 1, 2, 3, 3, 3] and block.degree == 2
    assert (block.line, block.canon_text(), block.end) == (7, "5, ...", (0.0, 0.0, 2.0))
    curve = block.curve()
    assert np.allclose(curve.point([0.0, 3.0]), [[0, 0, 2], [0, 0, 2]])


def test_order_from_l_above_three_on_any_block():
    def order(*ls):
        collector = G52Collector((0.0, 0.0, 0.0), 170, {"p": 1.0, **({"l": ls[0]} if ls[0] is not None else {})},
                                 (0, 0, 0), 1)
        for k, l_word in enumerate(ls[1:] + (None,) * 5):
            collector.add({"x": k + 1.0, "y": k % 2, "p": 1.0, **({"l": l_word} if l_word else {})}, (k + 1.0, k % 2, 0), 2)
        return collector.finish(9).degree + 1

    assert [order(None), order(2), order(0), order(5), order(3, 5), order(5, 3), order(4, 6)] == [3, 3, 3, 5, 5, 5, 6]


# --- G5.2 against LinuxCNC --------------------------------------------------------------------

BEHAVIOURS = {
    "first block with X Y: the start has weight 1": "G0 X1 Y2\nF100\nG5.2 X3 Y4 P3 L3\nX5 Y1 P0.5\nX7 Y3 P1\nG5.3\n",
    "first block without X Y: the start has weight P": "G0 X1 Y2\nF100\nG5.2 P3 L3\nX5 Y1 P0.5\nX7 Y3 P1\nG5.3\n",
    "G18 and G19 change nothing: still X Y": "G0 Z3\nF100\nG18\nG5.2 P2\nX1 Y1 P1\nX2 Y0 P1\nG19\nX3 Y1 P1\nG5.3\n",
    "G91: every point relative to the start": "G0 X1 Y1\nF100\nG91\nG5.2 P1 L3\nX1 Y1 P1\nX1 Y-1 P2\nX3 Y0 P1\nG5.3\n",
    "Z and G5.3's axis words are ignored": "F100\nG5.2 P1\nX1 Y1 Z5 P1\nX2 Y0 A3 P1\nX3 Y1 P1\nG5.3 X7 Y7\n",
    "blocks without motion leave the curve alone": "F100\nG5.2 P1 L4\nX1 Y1 P1\nF200\nM3 S100\nG4 P0.1\n(note)\n"
                                                   "X2 Y0 P1\nX3 Y1 P1\nG5.3\n",
    "L on a later block; G5.2 written again": "F100\nG5.2 P1\nX1 Y1 P1\nG5.2 X2 Y0 P1 L5\nX3 Y1 P1\nX4 Y0 P1\nG5.3\n",
    "a G1 in between starts the next curve afresh": "F100\nG5.2 P1\nX1 Y1 P1\nG1 X2 Y0\nG5.2 X3 Y1 P2\nX4 Y0 P1\n"
                                                    "G5.3\n",
    "order equal to the number of points (Bezier)": "F100\nG5.2 P1 L5\nX1 Y1 P1\nX2 Y0 P1\nX3 Y1 P1\nX4 Y0 P1\nG5.3\n",
    "inches and inverse time": "G20 G93\nG5.2 P1\nX1 Y1 P1 F1\nX2 Y0 P1 F1\nG5.3\n",
    "millimetres, two curves": "G21\nF100\nG5.2 P1\nX10 Y10 P1\nX20 Y0 P1\nG5.3\nG5.2 X30 Y10 P2 L3\nX40 Y0 P1\nG5.3\n",
}


@pytest.mark.parametrize("program", BEHAVIOURS.values(), ids=BEHAVIOURS.keys())
def test_behaviours_sample_as_linuxcnc_samples(program, tmp_path):
    _require_oracles()
    program += "M2\n"
    curves = read_program(program)
    calls, said, moves, error = _run_both(program, tmp_path)
    assert said == [] and error is None
    assert _nurbs_counts(calls) == [block.canon_text() for block, _ in curves]
    assert_samples_match(curves, moves)


def _random_program(rng: random.Random) -> str:
    """Six random G5.2 curves in one program, both first-block forms, orders 3 to 7."""
    point = lambda: f"X{rng.uniform(-80, 80):.4f} Y{rng.uniform(-80, 80):.4f}"  # noqa: E731
    weight = lambda: f"P{rng.uniform(0.2, 5):.5f}"  # noqa: E731
    lines = ["G21 G90 G17", "G0 X0 Y0 Z1", "F300"]
    for _ in range(6):
        count = rng.randint(3, 14)  # control points, the start included
        order = rng.randint(3, min(count, 7))
        l_word = f" L{order}" if order > 3 or rng.random() < 0.5 else ""
        if rng.random() < 0.5:
            lines += [f"G5.2 {weight()}{l_word}"] + [f"{point()} {weight()}" for _ in range(count - 1)]
        else:
            lines += [f"G5.2 {point()} {weight()}{l_word}"] + [f"{point()} {weight()}" for _ in range(count - 2)]
        lines += ["G5.3", f"G1 {point()}"]
    return "\n".join(lines + ["M2"]) + "\n"


@pytest.mark.parametrize("seed", range(4))
def test_random_curves_sample_as_linuxcnc_samples(seed, tmp_path):
    _require_oracles()
    program = _random_program(random.Random(seed))
    curves = read_program(program)
    calls, said, moves, error = _run_both(program, tmp_path)
    assert said == [] and error is None
    assert _nurbs_counts(calls) == [block.canon_text() for block, _ in curves]
    assert_samples_match(curves, moves)


def _reference(folder: str) -> list[Path]:
    if not REFERENCE.is_dir():
        pytest.skip(REFERENCE_ABSENT)
    return sorted((REFERENCE / folder).glob("*.ngc"))


def test_reference_g5_programs_read_or_refused_as_linuxcnc(tmp_path):
    """The G5/ programs LinuxCNC 2.9 runs sample alike; the others (YZ / ZX planes, G2.2) are
    refused with its message at its line."""
    _require_oracles()
    run = 0
    for path in _reference("G5"):
        program = path.read_text()
        calls, said, moves, error = _run_both(program, tmp_path / path.stem)
        if said:
            with pytest.raises(BlockError) as info:
                read_program(program)
            assert str(info.value) == said[0], path.name
            assert program.splitlines()[info.value.line - 1].strip() == said[1], path.name
            continue
        curves = read_program(program)
        assert error is None and curves, path.name
        assert _nurbs_counts(calls) == [block.canon_text() for block, _ in curves], path.name
        assert_samples_match(curves, moves)
        run += 1
    assert run == 7  # Chitarra, Delfino, Mazatrol, butterfly-xy, leto, nurbs-xy, trident-xy


# --- G5.2 refusals ----------------------------------------------------------------------------

START = "G0 X0 Y0\nF100\n"
REFUSALS = [
    ("G5.2 P1 L3\nX1 Y1 P1\nG5.3\n", 5, "You must specify a number of control points at least equal to the order L = 3"),
    ("G5.2 P1 L6\nX1 Y1 P1\nX2 Y0 P1\nX3 Y1 P1\nX4 Y0 P1\nG5.3\n", 8,
     "You must specify a number of control points at least equal to the order L = 6"),
    ("G5.3\n", 3, "Cannot use G5.3 without G5.2 first"),
    ("G5.2 P1\nX1 Y1 P1\nG1 X2 Y0\nG5.3\n", 6, "Cannot use G5.3 without G5.2 first"),
    ("G5.2 X1 P1\n", 3, "You must specify both X and Y coordinates for Control Points"),
    ("G5.2 P1\nY1 P1\n", 4, "You must specify both X and Y coordinates for Control Points"),
    ("G18\nG5.2 P1\nX1 Z1 P1\n", 5, "You must specify both X and Y coordinates for Control Points"),
    ("G5.2 P1\nX1 Y1 P1\nG5.2 P2\n", 5, "Can specify P without X and Y only for the first control point"),
    ("G5.2 P1\nX1 Y1 P1\nZ1 P1\n", 5, "Can specify P without X and Y only for the first control point"),
    ("G5.2 P1\nX1 Y1\n", 4, "Must specify positive weight P for every Control Point"),
    ("G5.2 P1\nX1 Y1 P0\n", 4, "Must specify positive weight P for every Control Point"),
    ("G5.2 P1\nX1 Y1 P1\nX2 Y2 P-1\n", 5, "Must specify positive weight P for every Control Point"),
    ("G5.2 P1\nX1 Y1 P1\nZ1\n", 5, "Must specify positive weight P for every Control Point"),
    ("G5.2 P1\nX1 Y1 P1 F0\n", 4, "Cannot make a NURBS with 0 feedrate"),
    ("G5.2 P1 L3.5\n", 3, "Non integer value for integer"),
    ("G5.2 P1 L-2\n", 3, "Negative l word used"),
]


@pytest.mark.parametrize("program, line, message", REFUSALS, ids=[r[2][:40] + f" {k}" for k, r in enumerate(REFUSALS)])
def test_refusals(program, line, message, tmp_path):
    program = START + program + "M2\n"
    with pytest.raises(BlockError) as info:
        read_program(program)
    assert (str(info.value), info.value.line) == (message, line)
    if oracle.available():
        _, said = oracle.run(program, tmp_path)
        assert said == [message, program.splitlines()[line - 1].strip()]


def test_zero_feed_is_refused_on_the_first_block_in_units_per_minute_only():
    with pytest.raises(BlockError, match="Cannot make a NURBS with 0 feedrate"):
        read_program("G5.2 P1 L3\n")
    with pytest.raises(BlockError, match="Cannot make a NURBS with 0 feedrate"):
        G52Collector((0, 0, 0), 170, {"p": 1.0}, (0, 0, 0), 1, feed_rate=0.0)
    G52Collector((0, 0, 0), 170, {"p": 1.0}, (0, 0, 0), 1, feed_rate=None)  # G93 / G95


def test_a_first_control_point_without_positive_weight_is_refused_where_linuxcnc_runs_it(tmp_path):
    """LinuxCNC takes an absent P as -1 (P0, P-2 as written) on a first block with X Y and samples a
    curve through that weight (checked against its samples); the twin refuses it."""
    from scipy.interpolate import BSpline

    for words, weight in (("X1 Y0 L3", -1.0), ("X1 Y0 P0 L3", 0.0), ("X1 Y0 P-2 L3", -2.0)):
        program = f"{START}G5.2 {words}\nX2 Y1 P1\nX3 Y0 P1\nG5.3\nM2\n"
        with pytest.raises(BlockError, match="Must specify positive weight P for every Control Point"):
            read_program(program)
        if not (oracle.available() and oracle_samples.available()):
            continue
        calls, said, moves, _ = _run_both(program, tmp_path)
        assert said == [] and _nurbs_counts(calls) == ["4, ..."]
        points, weights = np.array([[0, 0], [1, 0], [2, 1], [3, 0]], float), np.array([1, weight, 1, 1])
        knots = np.array([0, 0, 0, 1, 2, 2, 2], float)
        u = linuxcnc_parameters(NurbsBlock(np.zeros((4, 3)), weights, knots, 2, 3))
        homogeneous = BSpline(knots, np.hstack([points * weights[:, None], weights[:, None]]), 2)(u)
        got = np.array([m.point[:2] for m in moves if m.kind == "feed"])[:-1]
        assert np.max(np.abs(got - homogeneous[:, :2] / homogeneous[:, 2:])) < TOLERANCE


# --- G6.2 -------------------------------------------------------------------------------------

def _g62(blocks: list[dict], start=(0.0, 0.0, 0.0)) -> NurbsBlock:
    first, *rest = blocks
    point = lambda w: tuple(w.get(a, s) for a, s in zip("xyz", start))  # noqa: E731
    collector = G62Collector(start, 170, first, point(first), 1)
    for k, words in enumerate(rest):
        collector.add(words, point(words), k + 2)
    return collector.finish(len(blocks))


GOOD = [{"x": 0, "y": 0, "r": 1, "k": 0, "p": 3, "q": 1}, {"x": 1, "y": 2, "r": 2, "k": 0},
        {"x": 2, "y": -1, "r": 0.5, "k": 0}, {"x": 3, "y": 1, "k": 1.5}, {"k": 4}, {"k": 4}, {"k": 4}]


def test_g62_reads_points_weights_and_knots():
    block = _g62(GOOD)
    assert block.control_points.tolist() == [[0, 0, 0], [1, 2, 0], [2, -1, 0], [3, 1, 0]]
    assert block.weights.tolist() == [1, 2, 0.5, 1]  # R left out: 1
    assert block.knots.tolist() == [0, 0, 0, 1.5, 4, 4, 4] and block.degree == 2
    assert np.allclose(block.curve().point([0.0, 4.0]), [[0, 0, 0], [3, 1, 0]])


G62_REFUSALS = [
    ({0: {"x": 0, "y": 0, "k": 0, "q": 1}}, "G6.2 needs the order P in its first block"),
    ({0: {"x": 0, "y": 0, "k": 0, "p": 1}}, "G6.2 order P must be 2 or more, got P1"),
    ({0: {"x": 0, "y": 0, "k": 0, "p": 2.5}}, "Non integer value for integer"),
    ({0: {"x": 5, "y": 0, "k": 0, "p": 3}}, "G6.2 first control point must be the current point (0, 0, 0)"),
    ({0: {"k": 0, "p": 3}}, "G6.2 needs its first control point (axis words) in its first block"),
    ({1: {"x": 1, "y": 2, "r": 2}}, "G6.2 needs a knot K in every block"),
    ({1: {"x": 1, "y": 2, "k": 0, "p": 3}}, "G6.2 takes P and Q only in its first block"),
    ({2: {"x": 2, "y": -1, "r": 0, "k": 0}}, "G6.2 weight R must be positive, got R0"),
    ({2: {"x": 2, "y": -1, "r": -1, "k": 0}}, "G6.2 weight R must be positive, got R-1"),
    ({5: {"k": 4, "r": 1}}, "G6.2 closing knot block takes no weight R"),
    ({5: {"x": 4, "y": 4, "k": 4}}, "G6.2 control point after the closing knots"),
    ({6: None}, "G6.2 with 4 control points and order P3 needs 7 knots K (3 closing G6.2 K blocks), got 6"),
    ({7: {"k": 4}}, "G6.2 curve already has its 3 closing knots"),
    ({3: {"x": 3, "y": 1, "k": 5}}, "G6.2 knots K must not decrease"),
    ({2: {"x": 2, "y": -1, "k": 0.5}}, "G6.2 knots must be clamped: exactly the first 3 and the last 3 knots equal"),
    ({3: {"x": 3, "y": 1, "k": 0}}, "G6.2 knots must be clamped: exactly the first 3 and the last 3 knots equal"),
    ({6: {"k": 5}}, "G6.2 knots must be clamped: exactly the first 3 and the last 3 knots equal"),
    ({0: {**GOOD[0], "p": 5}}, "G6.2 order P5 needs at least 5 control points, got 4"),
    ({0: {**GOOD[0], "p": 2}, 1: {"x": 1, "y": 2, "k": 0}, 2: {"x": 2, "y": -1, "k": 1}, 3: {"x": 3, "y": 1, "k": 1},
      6: None}, "G6.2 interior knot repeated 2 times: at most 1 for order P2"),
]


@pytest.mark.parametrize("changes, message", G62_REFUSALS, ids=[m for _, m in G62_REFUSALS])
def test_g62_refusals(changes, message):
    blocks = GOOD + [{"k": 4}] if 7 in changes else list(GOOD)
    for index, words in sorted(changes.items(), reverse=True):
        if words is None:
            del blocks[index]
        else:
            blocks[index] = words
    with pytest.raises(BlockError) as info:
        _g62(blocks)
    assert str(info.value) == message


def test_reference_g6_programs_are_clamped_curves_between_their_end_points():
    """Every G6/ program reads (LinuxCNC 2.9 refuses G6.2 itself: no oracle here); each curve
    starts and ends on its first and last control points; the three variants #1=1/2/3 of a
    curve (method Q1/Q2/Q3) are the same curve."""
    by_name: dict[str, list] = {}
    for path in _reference("G6"):
        curves = read_program(path.read_text())
        assert curves, path.name
        for block, _ in curves:
            curve = block.curve()
            assert np.allclose(curve.point(list(curve.domain)), block.control_points[[0, -1]], atol=1e-12)
        stem = path.stem.replace("#1=2", "#1=1").replace("#1=3", "#1=1")
        by_name.setdefault(stem, []).append(curves)
    assert len(by_name) >= 20
    for stem, variants in by_name.items():
        # the same curves (homer's #1=1 draws one of them twice)
        keys = [{(c.control_points.tobytes(), c.weights.tobytes(), c.knots.tobytes()) for c, _ in curves}
                for curves in variants]
        assert all(k == keys[0] for k in keys[1:]), stem


def _number(value: float) -> str:
    return np.format_float_positional(value, unique=True, trim="-")


def _in_plane(block: NurbsBlock) -> NurbsBlock:
    """``block`` with its two moving axes as x, y (z 0): a G6.2 curve of any plane as one in XY."""
    axes = [a for a in range(3) if np.ptp(block.control_points[:, a]) > 0][:2]
    points = np.zeros_like(block.control_points)
    points[:, :2] = block.control_points[:, axes]
    return NurbsBlock(points, block.weights, block.knots, block.degree, block.line)


def _as_g52(blocks: list[NurbsBlock]) -> tuple[str, list[int]]:
    """``blocks`` (in XY) written as LinuxCNC's G5.2, one after the other: each first control
    point as the start, its weight as P on a G5.2 line without X Y; the program and the lines of
    its G5.3s."""
    lines, ends = ["F100"], []
    for block in blocks:
        pts, w = block.control_points, block.weights
        lines += [f"G0 X{_number(pts[0, 0])} Y{_number(pts[0, 1])}", f"G5.2 P{_number(w[0])} L{block.degree + 1}"]
        lines += [f"X{_number(p[0])} Y{_number(p[1])} P{_number(wk)}" for p, wk in zip(pts[1:], w[1:])]
        lines.append("G5.3")
        ends.append(len(lines))
    return "\n".join(lines + ["M2"]) + "\n", ends


def _uniform(block: NurbsBlock) -> bool:
    count, order = len(block.control_points), block.degree + 1
    n = count - 1
    want = np.concatenate([np.zeros(order), np.arange(1.0, n - order + 2), np.full(order, n - order + 2.0)])
    return order >= 3 and block.knots.shape == want.shape and np.array_equal(block.knots, want)


def test_reference_g6_curves_with_uniform_knots_sample_as_their_g52_form(tmp_path):
    """Where a G6.2 curve's knots are LinuxCNC's uniform ones, the same points and weights as
    G5.2 go through LinuxCNC's own evaluation: its samples are our G6.2 curve's points."""
    _require_oracles()
    checked = set()
    for path in _reference("G6"):
        if "#1=1" not in path.name:
            continue
        # LinuxCNC's nurbs_point costs n^2 2^order per sample: the long scrolls and the gear
        # (221 to 666 points) would take minutes
        flat = [_in_plane(block) for block, _ in read_program(path.read_text())
                if _uniform(block) and len(block.control_points) <= 60]
        if not flat:
            continue
        program, ends = _as_g52(flat)
        moves, error, _ = oracle_samples.run(program, tmp_path / path.stem)
        assert error is None
        assert_samples_match(list(zip(flat, ends)), moves)
        checked.add(path.stem.split(" ")[0])
    assert {"Curva_Stella", "Curva_Delfino", "Curva_Chitarra", "Curva_Mazatrol"} <= checked


def test_g5_versions_of_g6_curves_share_their_control_points(tmp_path):
    """The G5/ versions of Chitarra, Delfino and Mazatrol repeat the start as a control point and
    use weights 1 and LinuxCNC's default order 3 (Chitarra's L3), so their curves only resemble
    the G6.2 ones (weights up to 75, order 4 or 5): the control points (but the repeated start)
    are the same, the curves start and end together and stay within a few percent of the part's
    size of each other. (Stella's G5 version is written G2.2, which LinuxCNC refuses.)"""
    for name in ("Curva_Delfino", "Curva_Mazatrol", "Curva_Chitarra"):
        (g5,) = [p for p in _reference("G5") if p.name.startswith(name)]
        (g6,) = [p for p in _reference("G6") if p.name.startswith(name + " #1=1")
                 and "yz" not in p.name and "zx" not in p.name and "xy-yz" not in p.name]
        (a, _), = read_program(g5.read_text())
        (b, _), *_ = read_program(g6.read_text())
        g5_points = a.control_points[1:] if np.array_equal(a.control_points[0], a.control_points[1]) else a.control_points
        assert np.array_equal(g5_points[:, :2], b.control_points[:, :2]), name
        ca, cb = a.curve(), b.curve()
        ua, ub = np.linspace(*ca.domain, 4000), np.linspace(*cb.domain, 4000)
        pa, pb = ca.point(ua)[:, :2], cb.point(ub)[:, :2]
        assert np.allclose(pa[[0, -1]], pb[[0, -1]])
        gap = max(np.min(np.linalg.norm(pa[:, None] - pb[None, ::8], axis=2), axis=1).max(),
                  np.min(np.linalg.norm(pb[:, None] - pa[None, ::8], axis=2), axis=1).max())
        size = np.ptp(pb, axis=0).max()
        assert gap < 0.08 * size, (name, gap, size)  # measured: 3.5 % (Delfino), 2.0 %, 5.9 % (Chitarra)

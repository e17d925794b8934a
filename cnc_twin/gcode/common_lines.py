"""The lines most of a CAM program is made of, run at once: the reader's fast path. Each makes
exactly the calls the full path (:meth:`~cnc_twin.gcode.interpreter.Interpreter.run`, line by
line) makes with it, skipping only checks that cannot refuse it (``tests/test_gcode_speed_paths.py``
runs the outside programs and LinuxCNC's examples both ways and compares every call).

A *common line* is, once its spaces are dropped and its letters lowered (as LinuxCNC reads a
line): an optional N word of digits, then at most one of each word, in this order: G (``G0`` ..
``G3``, ``G00`` .. ``G03``), X Y Z A B C, I J K R, F, S, each with a plain number
(:data:`~cnc_twin.gcode.blocks.NUMBER`): ``N120 G1 X-1.5 Y2 F300``, ``G02 X49.9 Y38.2 Z-1 I-1.9
J0.2``, ``X12.5 Z19.8 A-13.7``; then at most one comment, ending the line (``G01 Z-1 F100
(Penetrate)``, or the comment alone). Nothing else: no tab, M or T word, parameter, expression,
block delete, other G code or other order (``G1 F300 X1``: rare, left to the full path). A
common line is taken only in a state where nothing of the full path can refuse it or do more
with it; any other line, and a common line in any other state, is left to the full path (which
refuses it, if it must, in its own words). Why the full path does the same with a line taken:

- reading (:func:`~cnc_twin.gcode.reading.read_line`): no M word, so no Fanuc M98 / M99 line;
  no ``;`` or ``)`` but the one comment's, whose text the reader keeps without its leading
  spaces and tabs, reading the words before it as a line of their own; no ``o``, so no O-word
  line; no ``#``, so no parameter setting; no ``/``; letters and plain numbers only, so the
  reader's quick path reads each value as ``float`` of its text, as here (and refuses a negative
  F or S: not taken here); the N word's text is :func:`~cnc_twin.gcode.blocks.n_text`'s; a line
  LinuxCNC finds too long (``too_long`` of :class:`~cnc_twin.gcode.source.Source`) is never taken;
- modal groups (:func:`~cnc_twin.gcode.modal.modal_codes`): one G code of group 1 and no M code
  cannot repeat a group nor meet an axis-owning group 0 code;
- :func:`~cnc_twin.gcode.checks.refuse_unsupported`: G0 .. G3 are the machine's; no U V W E;
- :func:`~cnc_twin.gcode.checks.check_words`: with no polar word, no group 0 code and a motion
  code (if any) that is no G80, cycle or probe, axis words are refused only when nothing uses
  them: axis words without G are taken only in the motion modes G0 .. G3 (the full path refuses
  them after G80 and checks a canned cycle's words whole); with no D $ H L P Q word, and A B C
  refused only in a cycle, only I J K R remain, refused without an arc: taken only with G2 / G3
  (the line's, or the mode's for a line with axis words); a comment is no word;
- the block's steps (``Interpreter._execute``): with no M or T
  word and no G code but the motion, only the comment
  (:meth:`~cnc_twin.gcode.interpreter.Interpreter.comment`), F, S and the motion run, in that
  order. F sets the feed in units per minute (G94); in inverse time (G93) F sets no feed and each
  move needs its own, so nothing is taken in G93;
- the motion (:meth:`~cnc_twin.gcode.motion.MotionRunner.move`): nothing is taken while a NURBS
  curve is being gathered (a move would end it or be refused); G0 / G1 go to the end point as
  ``ends`` finds it (each axis word its value, or in G91 the current point's plus it), a G1 at a
  feed of 0 is refused there (not taken here); G2 / G3 go to that end point through ``move``'s
  own arc step (:meth:`~cnc_twin.gcode.motion.MotionRunner.arc`), after F and S as in the full
  path, its checks and refusals included;
- a motion call forgets the tool length offset changes since the last one (``tool_shift``), as
  ``Interpreter.emit`` does.
"""

from __future__ import annotations

import bisect
import re
from typing import TYPE_CHECKING

from cnc_twin.gcode.arcs import xy_offset_arc
from cnc_twin.gcode.blocks import NUMBER, n_text
from cnc_twin.gcode.canon import Call
from cnc_twin.gcode.modal import G

if TYPE_CHECKING:  # the interpreter runs this on itself; only its type is needed here
    from cnc_twin.gcode.interpreter import Interpreter

WORDS = "xyzabcijkrfs"
"""a common line's words after N and G, in the order they must come"""
_COMMENTED = re.compile(r"([^();]*+)\(([^()]*+)\)[ \t]*+")
"""a line that ends in its one comment: the words before it, the comment's text"""
_LINE = re.compile(r"(?:n([0-9]++))?+(?:g(0?[0-3]))?+" + "".join(rf"(?:{letter}({NUMBER}))?+" for letter in WORDS))
"""a common line, spaces dropped and letters lowered: groups N digits, G text, then one per
letter of :data:`WORDS` (None when absent)"""
G0, G1, G2, G3, G91, G94, G17, G21, G91_1 = (int(code) for code in (G.G0, G.G1, G.G2, G.G3, G.G91, G.G94, G.G17,
                                                                      G.G21, G.G91_1))
"""the codes as plain numbers, as the reader keeps its modes (looking up an enum member, 70 ns,
is a share of a line's time here)"""
MOTIONS = {"0": G0, "00": G0, "1": G1, "01": G1, "2": G2, "02": G2, "3": G3, "03": G3}
"""a common line's G text -> its code (``float`` of the text, in tenths, as the reader has it)"""
MODES = frozenset((G0, G1, G2, G3))
"""motion modes in which a common line's axis words without G move"""


def run_common_lines(interpreter: Interpreter, index: int, most: int | None = None) -> int:
    """Run the common lines from 0-based ``index`` on, while the state lets them run, ``most``
    lines at most (None: no bound); the index of the first line not run (``index`` itself when
    that line is not taken)."""
    s = interpreter.state
    if s.feed_mode != G94 or interpreter.motion.nurbs is not None:
        return index
    source = interpreter.source
    text, starts = source.lines.text, source.lines.starts  # a line cut out here: no call a line
    long = source.too_long
    k = bisect.bisect_left(long, index)
    stop = min(source.end, long[k] if k < len(long) else source.end)
    if most is not None:
        stop = min(stop, index + max(0, most))
    append = interpreter.calls.append
    match_line = _LINE.fullmatch
    match_commented = _COMMENTED.fullmatch
    incremental = s.distance == G91
    while index < stop:
        raw = words_text = text[starts[index]:starts[index + 1] - 1]
        comment = None
        if "(" in raw:
            commented = match_commented(raw)
            if commented is None:
                break
            words_text, comment = commented.groups()
        if not words_text.isascii():  # lower() would make letters of some other characters (K, the kelvin sign)
            break
        match = match_line(words_text.replace(" ", "").lower())
        if match is None:
            break
        words = match.groups()
        n_digits, code, x, y, z, a, b, c, i, j, k, r, f, sp = words
        feed = speed = None
        if f is not None:
            feed = float(f)
            if feed < 0.0:
                break
        if sp is not None:
            speed = float(sp)
            if speed < 0.0:
                break
        if code is not None:
            motion = MOTIONS[code]
        elif x is not None or y is not None or z is not None or a is not None or b is not None or c is not None:
            motion = s.motion
            if motion not in MODES:
                break
        else:
            motion = None
        arc = motion == G2 or motion == G3
        if not arc and (i is not None or j is not None or k is not None or r is not None):
            break
        if motion == G1 and (s.feed if feed is None else feed) <= 0.0:
            break
        # taken: from here the line runs as the full path runs it
        line = index + 1
        number = None
        if n_digits is not None:
            # the N word's text as written: its digits when the line starts with them ("N120 G1"),
            # for n_text reads that far and no further; else (spaces, "/ N 1 2") n_text's reading
            number = n_digits if raw[0] in "nN" and raw.startswith(n_digits, 1) else n_text(raw)
        if comment is not None:
            interpreter.at(line, number)  # a debug or print comment may read #<_line>
            interpreter.comment(comment.lstrip(" \t"))
        if feed is not None:
            s.feed = feed
            append(Call("SET_FEED_RATE", (feed,), line, number))
        if speed is not None:
            s.speed = speed
            append(Call("SET_SPINDLE_SPEED", (speed,), line, number))
        if motion is not None:
            p = s.position
            if incremental:
                end = [p[0] if x is None else p[0] + float(x), p[1] if y is None else p[1] + float(y),
                       p[2] if z is None else p[2] + float(z), p[3] if a is None else p[3] + float(a),
                       p[4] if b is None else p[4] + float(b), p[5] if c is None else p[5] + float(c)]
            else:
                end = [p[0] if x is None else float(x), p[1] if y is None else float(y),
                       p[2] if z is None else float(z), p[3] if a is None else float(a),
                       p[4] if b is None else float(b), p[5] if c is None else float(c)]
            if arc:
                interpreter.at(line, number)  # the arc's call and refusal name the line
                if (r is None and k is None and (i is not None or j is not None) and s.plane == G17
                        and s.ijk_distance == G91_1 and s.feed > 0.0):
                    # CAM's arc (G17, I J, relative centre, a feed): what the motion runner's
                    # arc makes of it, without the checks that cannot fail
                    move = xy_offset_arc(motion == G2, p, end, 0.0 if i is None else float(i),
                                         0.0 if j is None else float(j), s.units == G21)
                    append(Call("ARC_FEED", (end[3], end[4], end[5]), line, number, move))
                    s.tool_shift = [0.0] * 6
                else:
                    values = {}  # the block's words, as the reader has them
                    for letter, value in zip(WORDS, words[2:]):
                        if value is not None:
                            values[letter] = float(value)
                    interpreter.motion.arc(motion, values, end)
            else:
                append(Call("STRAIGHT_TRAVERSE" if motion == G0 else "STRAIGHT_FEED", tuple(end), line, number))
                s.tool_shift = [0.0] * 6
            s.position = end
            s.motion = motion
        index += 1
    return index

"""One line of a program read as LinuxCNC reads it, with the refusals it makes while reading.

:func:`~cnc_twin.gcode.blocks.read_block` reads the words; two refusals depend on more than the
line's text:

- LinuxCNC checks each G and M code as it reads it, so a bad code is refused before what
  follows it on the line (``M40 G999`` for M40, ``M40 X1 X2`` for M40 too): a line refused while
  read has the codes read before the refusal checked first (:func:`~cnc_twin.gcode.modal.read_codes`);
- a bad character is named by its byte in the file: one that is not UTF-8 is U+FFFD in the
  program's text, so the line is read again as the file holds it
  (:attr:`~cnc_twin.gcode.source.Source.escaped`) for LinuxCNC's message (``Bad character '\\351'
  used`` for a Latin-1 ``é``);
- a line that starts with M98 or M99 (after ``/`` and an N word) is a Fanuc-style subprogram
  call or return to LinuxCNC: M98 is refused as not supported, an M99 in a subroutine called by
  ``o... call`` with LinuxCNC's message (elsewhere M99 ends the program as M2 does).
"""

from __future__ import annotations

import re

from cnc_twin.gcode.blocks import BadCharacter, Block, BlockError, normalise, read_block
from cnc_twin.gcode.checks import UNSUPPORTED_MARK
from cnc_twin.gcode.expressions import ExpressionError, Parameters, integer_of, read_real
from cnc_twin.gcode.modal import read_codes
from cnc_twin.gcode.source import Source

_LEADING_M = re.compile(r"[ \t\r]*(?:/[ \t\r]*)?(?:[nN][0-9. \t\r]*)?[mM]")
"""an M word first on a line, after ``/`` and an N word (a comment before it makes it no
subprogram line: LinuxCNC looks at the line with its comments)"""


def read_line(source: Source, index: int, params: Parameters, in_call: bool = False) -> Block:
    """The line at 0-based ``index`` of ``source`` read into a block, or LinuxCNC's refusal;
    ``in_call``: the line runs in a called subroutine."""
    text = source.lines[index]
    leading = _LEADING_M.match(text)
    if leading is not None:
        _fanuc_subprogram(text[leading.end():], params, in_call)
    try:
        return read_block(text, index + 1, params)
    except BlockError as exc:
        if exc.block is not None:
            read_codes(exc.block)  # a code before the refusal is refused first
        if isinstance(exc, BadCharacter) and exc.char == "\ufffd" and index in source.escaped:
            # the line is refused: reading it again (its settings never apply) names the byte
            try:
                read_block(source.escaped[index], index + 1, params)
            except BadCharacter as again:
                raise again from None
        raise


def _fanuc_subprogram(rest: str, params: Parameters, in_call: bool) -> None:
    """Refuse a line whose first word is M98, or M99 in a called subroutine (``rest``: the
    line after its M), as LinuxCNC does: it reads three characters for the code (``M099`` or
    ``M[99]`` leave one over), then comments only."""
    try:
        norm, _ = normalise(rest)
        code = integer_of(read_real(norm, 0, params)[0])
    except (BlockError, ExpressionError):
        return  # read_block reports it
    if code == 98:
        raise BlockError(f"M98 (Fanuc-style subprogram call) is {UNSUPPORTED_MARK}")
    if code == 99 and in_call:
        if norm[2:]:
            raise BlockError("Unexpected character after O-word")
        raise BlockError("'O.... endsub' or 'O.... return' must follow 'O.... sub' subroutine definition")

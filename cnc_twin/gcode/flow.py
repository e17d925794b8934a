"""O-word control flow as LinuxCNC runs it: subroutines (``sub`` / ``endsub`` / ``call`` /
``return``), ``if`` / ``elseif`` / ``else`` / ``endif``, ``while`` / ``endwhile``, ``do`` /
``while``, ``repeat`` / ``endrepeat``, ``break`` and ``continue``.

Partners are found by the O-word's name (``o100 if`` ends at ``o100 endif``), not by nesting,
as in LinuxCNC. A call saves the caller's ``#1`` .. ``#30`` and its local named parameters
(names without a leading ``_``), sets ``#1`` .. ``#n`` to the call's arguments (the rest 0),
and restores them on return; ``endsub [v]`` / ``return [v]`` set ``#<_value>`` and
``#<_value_returned>``. A subroutine is known once execution has passed its definition or, when
called before it, by looking for a file named after it (:mod:`~cnc_twin.gcode.subfiles`), then
by searching the rest of the calling file, as LinuxCNC does. Errors carry LinuxCNC's wording.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cnc_twin.gcode.blocks import BlockError
from cnc_twin.gcode.expressions import ExpressionError, Parameters, evaluate
from cnc_twin.gcode.limits import MAX_CALLS
from cnc_twin.gcode.source import KEYWORDS, OLine, Source
from cnc_twin.gcode.subfiles import SubroutineFiles

LOCALS = 30
"""``#1`` .. ``#30`` are a subroutine's own"""
MAX_CALL_DEPTH = 10
"""LinuxCNC's nesting limit for calls"""
CONDITIONAL = ("if", "elseif", "while", "repeat")
"""keywords that must be followed by a bracketed condition (or count)"""
OPENERS = ("if", "while", "repeat", "do")
"""keywords whose label LinuxCNC records when it runs them"""
RETURNED = ("_value", "_value_returned")
"""the named parameters a subroutine's return sets"""


class SeekError(BlockError):
    """A call whose subroutine the rest of the file does not hold: LinuxCNC reports it at the
    last line it read while seeking (``line``, 1-based)."""

    def __init__(self, message: str, line: int):
        self.line = line
        super().__init__(message)


@dataclass
class Frame:
    """A subroutine call in progress: where to go back to and what the caller had."""

    name: str
    return_to: int
    numbered: dict[int, float]
    named: dict[str, float]
    loops: int
    source: Source | None = None
    """the caller's file, which the return goes back to"""


@dataclass
class Loop:
    """A ``while`` / ``do`` / ``repeat`` in progress (``start``: index of its first line)."""

    name: str
    kind: str
    start: int
    remaining: int = 0


@dataclass
class Flow:
    """Control-flow state of one run: call frames, open loops, known subroutines. ``source``:
    the file being run (the program's, or a subroutine file's while it runs); ``files``: where
    subroutine files are looked for (None: nowhere)."""

    source: Source
    params: Parameters
    frames: list[Frame] = field(default_factory=list)
    loops: list[Loop] = field(default_factory=list)
    subroutines: dict[str, tuple[Source, int]] = field(default_factory=dict)
    """name -> the file and 0-based index of its ``sub`` line"""
    files: SubroutineFiles | None = None
    passes: int = 0
    max_passes: int = MAX_CALLS
    """O-word lines run before the reader gives up on a program that never ends (a loop making no
    calls, which the calls' bound does not see): the reader's ``max_calls``"""
    labels: list[dict[str, tuple[int, str]]] = field(default_factory=lambda: [{}])
    """per call level (the program, then each call in progress): the labels of the ``if``,
    ``while``, ``repeat`` and ``do`` lines run so far -> their line index and keyword"""

    def __post_init__(self):
        # what the last subroutine returned: 0 until one returns, set by the interpreter only
        for name in RETURNED:
            self.params.named.setdefault(name, 0.0)
        self.params.read_only_named.update(RETURNED)
        self.main = self.source

    def release(self) -> None:
        """Let go of the programs' lines once the reading is over (the main program's and the
        subroutine files'; :meth:`~cnc_twin.gcode.subfiles.SubroutineFiles.texts` read first if
        wanted): the interpreter's parts refer to each other, and such a cycle is freed only when
        Python's collector comes round to it, late in a run of hours, with the text it holds (150 MB
        for 5 000 000 lines)."""
        self.source = self.main = None
        self.frames.clear()
        self.loops.clear()
        self.subroutines.clear()
        if self.files is not None:
            self.files.read.clear()

    def _keyword(self, o_line: OLine) -> tuple[str, str]:
        """The keyword and the argument text after it (LinuxCNC reads the longest keyword)."""
        text = o_line.keyword + o_line.rest
        if not text:  # a program number (O0001, O0001 (NAME)): read and passed over
            return "", ""
        keyword = max((k for k in KEYWORDS if text.startswith(k)), key=len, default=None)
        if keyword is None:
            raise BlockError("Unknown control command in o word")
        rest = text[len(keyword):]
        if keyword in CONDITIONAL and not rest.startswith("["):
            raise BlockError(f"Left bracket missing after '{keyword}'")
        if rest and not rest.startswith("["):
            raise BlockError("Unexpected character after O-word")
        return keyword, rest

    def _condition(self, rest: str) -> float:
        try:
            value, end = evaluate(rest, 0, self.params)
        except ExpressionError as exc:
            raise BlockError(str(exc)) from None
        return value

    def _arguments(self, rest: str) -> list[float]:
        values, pos = [], 0
        try:
            while pos < len(rest):
                if rest[pos] != "[":
                    raise BlockError("Unexpected character after O-word")
                value, pos = evaluate(rest, pos, self.params)
                values.append(value)
        except ExpressionError as exc:
            raise BlockError(str(exc)) from None
        return values

    def _after(self, index: int, name: str, keywords: tuple[str, ...], shown: str) -> int:
        """The index after the partner line of ``name`` with one of ``keywords``."""
        found = self.source.find_forward(index, name, keywords)
        if found is None:
            raise BlockError(f"{index + 1}: undefined O-word label: '{shown}'")
        return found.index

    def step(self, index: int) -> int | str:
        """Run the O-word line at ``index``: the index of the next line to read, or ``"end"``
        when a subroutine returns past the top level."""
        self.passes += 1
        if self.passes > self.max_passes:
            raise BlockError(f"more than {self.max_passes} O-word lines run: the loop here runs on, the program "
                             "does not end (the bound: program.max_calls, gcode --max-calls)")
        o_line = self.source.o_lines[index]
        keyword, rest = self._keyword(o_line)
        if not keyword:  # a Fanuc-style program number line: nothing to run
            return index + 1
        name = o_line.name
        shown = self.source.lines[index].strip()
        if keyword in OPENERS:
            self._label(index, name, keyword, shown)
        elif keyword == "endif" and name not in self.labels[-1]:
            raise BlockError(f"{index + 1}: undefined O-word label: '{shown}'")
        if keyword == "sub":
            return self._define(index, name)
        if keyword == "call":
            return self._call(index, name, rest)
        if keyword in ("endsub", "return"):
            return self._return(index, name, rest, shown)
        if keyword == "if":
            return self._branch(index, name, rest, shown)
        if keyword in ("elseif", "else"):
            if self.source.find_backward(index, name, ("if",)) is None:
                raise BlockError(f"{index + 1}: undefined O-word label: '{shown}'")
            return self._after(index, name, ("endif",), shown) + 1
        if keyword == "endif":
            return index + 1
        return self._loop(index, name, keyword, rest, shown)

    def _label(self, index: int, name: str, keyword: str, shown: str) -> None:
        """LinuxCNC's record of the labels a call level has run: one label names one line (a
        ``do`` takes a known label, the ``while`` that closes a ``do`` is its partner)."""
        labels = self.labels[-1]
        known = labels.get(name)
        if known is None:
            labels[name] = (index, keyword)
            return
        first, kind = known
        if first == index or keyword == "do" or (keyword == "while" and kind == "do"):
            return
        if keyword == "if":
            raise BlockError(f"{index + 1}: duplicate O-word label - already defined in line {first + 1}: '{shown}'")
        raise BlockError(f"{index + 1}: duplicate O-word label: '{shown}' - defined in line {first + 1}")

    def _define(self, index: int, name: str) -> int:
        """A ``sub`` line met in the flow: its body is skipped to its ``endsub``, as LinuxCNC
        reads it, refusing a definition inside it or a file that ends first."""
        known = self.subroutines.get(name)
        if known is not None and known != (self.source, index):
            raise BlockError(f"File:{self.source.name} line:{index + 1} redefining sub: o|{name.strip('<>')}| "
                             f"already defined in file:{known[0].name}")
        self.subroutines[name] = (self.source, index)
        for o_line in self.source.o_lines_after(index):
            if o_line.keyword == "sub":
                raise SeekError("Nested subroutine definition", o_line.index + 1)
            if o_line.keyword == "endsub" and o_line.name == name:
                return o_line.index + 1
        raise SeekError(self.source.eof_message, self.source.end)

    def _branch(self, index: int, name: str, rest: str, shown: str) -> int:
        condition = self._condition(rest)
        while not condition:
            partner = self.source.find_forward(index, name, ("elseif", "else", "endif"))
            if partner is None:
                raise BlockError(f"{index + 1}: undefined O-word label: '{shown}'")
            if partner.keyword == "elseif":
                index = partner.index
                condition = self._condition(self._keyword(partner)[1])
                continue
            return partner.index + 1
        return index + 1

    def _loop(self, index: int, name: str, keyword: str, rest: str, shown: str) -> int:
        top = self.loops[-1] if self.loops else None
        if keyword == "do":
            if not (top and top.start == index):
                self.loops.append(Loop(name, "do", index))
            return index + 1
        if keyword == "while" and top and top.name == name and top.kind == "do":
            if self._condition(rest):
                return top.start + 1
            self.loops.pop()
            return index + 1
        if keyword == "while":
            if self._condition(rest):
                if not (top and top.start == index):
                    self.loops.append(Loop(name, "while", index))
                return index + 1
            if top and top.start == index:
                self.loops.pop()
            return self._after(index, name, ("endwhile",), shown) + 1
        if keyword == "repeat":
            count = int(self._condition(rest))
            if count <= 0:
                return self._after(index, name, ("endrepeat",), shown) + 1
            self.loops.append(Loop(name, "repeat", index, count))
            return index + 1
        if keyword == "endwhile":
            loop = self._open(name, "while", index, shown)
            return loop.start
        if keyword == "endrepeat":
            loop = self._open(name, "repeat", index, shown)
            loop.remaining -= 1
            if loop.remaining > 0:
                return loop.start + 1
            self.loops.pop()
            return index + 1
        loop = self._open(name, None, index, shown)
        end = {"while": ("endwhile",), "repeat": ("endrepeat",), "do": ("while",)}[loop.kind]
        if keyword == "break":
            self.loops.pop()
            return self._after(index, name, end, shown) + 1
        # continue: a while re-tests at its start, a do at its closing while, a repeat counts the pass
        if loop.kind == "while":
            return loop.start
        return self._after(index, name, end, shown)

    def _open(self, name: str, kind: str | None, index: int, shown: str) -> Loop:
        while self.loops and self.loops[-1].name != name:
            self.loops.pop()
        if not self.loops or (kind is not None and self.loops[-1].kind != kind):
            raise BlockError(f"{index + 1}: undefined O-word label: '{shown}'")
        return self.loops[-1]

    def _call(self, index: int, name: str, rest: str) -> int:
        args = self._arguments(rest)
        if len(args) > LOCALS:
            raise BlockError("Too many subroutine parameters")
        known = self.subroutines.get(name)
        if known is None:
            known = self.subroutines[name] = self._find_sub(index, name)
        if len(self.frames) >= MAX_CALL_DEPTH:
            raise BlockError("Too many nested subroutine calls")  # LinuxCNC's limit, its wording differs
        numbered = self.params.numbered
        saved_numbered = {k: numbered.pop(k) for k in range(1, LOCALS + 1) if k in numbered}
        saved_named = {k: v for k, v in self.params.named.items() if not k.startswith("_")}
        for k in saved_named:
            del self.params.named[k]
        for k, value in enumerate(args, start=1):
            numbered[k] = value
        self.frames.append(Frame(name, index + 1, saved_numbered, saved_named, len(self.loops), self.source))
        self.labels.append({})
        self.source, start = known
        return start + 1

    def _find_sub(self, index: int, name: str) -> tuple[Source, int]:
        """Where subroutine ``name``, not met yet, is: in its file when one is found (searched
        from its start), else in the rest of the calling file; refused at the last line read,
        in the file searched (which LinuxCNC has opened by then)."""
        here, start = self.source, index
        found_file = self.files.find(name) if self.files is not None else None
        if found_file is not None:
            here, start = found_file, -1
        found = here.find_forward(start, name, ("sub",))
        if found is None:
            self.source = here
            shown = name if name.startswith("<") else f"<{name}>"
            raise SeekError(f"EOF in file:{here.name} seeking o-word: o{shown} from line: {start + 1}", here.end)
        return here, found.index

    def _return(self, index: int, name: str, rest: str, shown: str) -> int | str:
        if not self.frames:
            raise BlockError(f"{index + 1}: not in a subroutine definition: '{shown}'")
        value = self._condition(rest) if rest else None
        frame = self.frames.pop()
        self.labels.pop()
        self.source = frame.source
        numbered = self.params.numbered
        for k in range(1, LOCALS + 1):
            numbered.pop(k, None)
        numbered.update(frame.numbered)
        for k in [k for k in self.params.named if not k.startswith("_")]:
            del self.params.named[k]
        self.params.named.update(frame.named)
        self.params.named["_value"] = 0.0 if value is None else value
        self.params.named["_value_returned"] = 0.0 if value is None else 1.0
        del self.loops[frame.loops:]  # loops opened inside the subroutine end with it
        return frame.return_to

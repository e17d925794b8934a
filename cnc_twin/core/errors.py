"""Errors users see as one line and exit code 2 (bad input)."""

from __future__ import annotations

from pathlib import Path


EXIT_OK = 0
EXIT_BAD_INPUT = 2
"""a scenario, program or option is wrong: one line, nothing run"""
EXIT_FAULT = 3
"""the run ended by a fault of the card (its run directory complete, saying which)"""
EXIT_RESOURCE = 4
"""the machine could not give the run what it needs (disk space, shared memory, a folder that
stays writable): one line saying which and what is free; what could be kept is"""


class ResourceError(Exception):
    """What the run needs from the machine it does not get: rendered by the CLI as one line
    ``WHERE: what is missing`` and :data:`EXIT_RESOURCE`."""

    def __init__(self, where: str | Path, message: str):
        self.where = str(where)
        self.message = message
        super().__init__(str(self))

    def __str__(self) -> str:
        return one_line(f"{self.where}: {self.message}")


class ScenarioError(Exception):
    """A scenario (or a file it references) is invalid.

    Rendered by the CLI as one line ``FILE: KEY.PATH: what was expected`` and exit code 2.

    Parameters
    ----------
    file
        path of the offending file.
    key_path
        dotted key path inside the file, e.g. ``program.moves[2].X``; empty when the problem is
        the file as a whole.
    message
        what was expected or what is wrong.
    """

    def __init__(self, file: str | Path, key_path: str, message: str):
        self.file = str(file)
        self.key_path = key_path
        self.message = message
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.file}: {self.key_path}" if self.key_path else self.file
        return one_line(f"{where}: {self.message}")


def one_line(text: str) -> str:
    """``text`` with every non-printable character escaped (``\\n``, ``\\x1e``...): an error stays
    one line whatever the input held."""
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii") for ch in text)


def format_key_path(loc: tuple) -> str:
    """Turn a location tuple such as ``("program", "moves", 2, "X")`` into ``program.moves[2].X``."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out

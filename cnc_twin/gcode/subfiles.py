"""Subroutine files, found as LinuxCNC finds them.

``o<name> call`` of a subroutine the run has not met yet is looked for in a file ``name.ngc``
(the name as read: lower case; ``o100 call`` looks for ``100.ngc``) before the rest of the
calling file: in the program's folder (where rs274 runs, its working folder), then in each
folder of the subroutine path in turn (LinuxCNC's ``[RS274NGC]SUBROUTINE_PATH``), the first one
found. A file found runs its ``o<name> sub`` .. ``endsub`` as its own lines (an error names the
file and its line); a subroutine found once is called from where it was found, as LinuxCNC's
table of subroutines keeps it. Messages name a file as LinuxCNC does: by its name in the
program's folder, by its full path in a subroutine-path folder.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from cnc_twin.gcode.blocks import BlockError
from cnc_twin.gcode.source import Source, SourceError

SUFFIX = ".ngc"
"""LinuxCNC's subroutine files end so"""


def file_name(name: str) -> str:
    """The file a subroutine ``name`` (``<name>`` or digits, as an O-word holds it) lives in."""
    return name.strip("<>") + SUFFIX


class SubroutineFiles:
    """Where a run looks for subroutine files: ``folder``, the program's own (None: a program
    not read from a file), then the folders of ``path`` in order. ``read``: the files read so
    far, by path (each one read once, as it was when first called)."""

    def __init__(self, folder: Path | None, path: Sequence[Path] = ()):
        self.folder = folder
        self.path = tuple(Path(p) for p in path)
        self.read: dict[Path, Source] = {}

    def find(self, name: str) -> Source | None:
        """The file holding subroutine ``name``, read; None when no folder has one."""
        base = file_name(name)
        places = ([(self.folder, False)] if self.folder is not None else []) + [(p, True) for p in self.path]
        for folder, full in places:
            path = folder / base
            if path.is_file():
                return self._source(path, str(path.resolve()) if full else base)
        return None

    def _source(self, path: Path, shown: str) -> Source:
        source = self.read.get(path)
        if source is None:
            try:
                source = Source.read(path)
            except (SourceError, OSError) as exc:
                reason = exc.strerror if isinstance(exc, OSError) else str(exc)
                raise BlockError(f"Unable to open file <{path}>: {reason}") from None
            source.name = shown
            self.read[path] = source
        return source

    def texts(self) -> dict[Path, str]:
        """The files read, by path: their text as read (a run directory keeps them)."""
        return {path: source.text for path, source in self.read.items()}

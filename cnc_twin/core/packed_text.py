"""A long text held compressed (:class:`~cnc_twin.core.packed_text.PackedText`): a CAM program's
text, which the run directory keeps as it was read, held through a run at a fifth of its size (a
5 000 000-line raster: 151 MB as a string, 31 MB packed) and written out without a whole copy of it
in memory."""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

PIECE = 1 << 22
"""characters (bytes) handled at a time when packing (writing): no whole UTF-8 copy is made"""
LEVEL = 1
"""zlib's fastest level: G-code packs to about a fifth at 120 MB/s (a higher level gains 10 %
for four times the time)"""


@dataclass(frozen=True)
class PackedText:
    """UTF-8 text, zlib-compressed (``data``), of ``chars`` characters."""

    data: bytes
    chars: int

    @classmethod
    def of(cls, text: str, *, piece: int = PIECE) -> PackedText:
        packer = zlib.compressobj(LEVEL)
        parts = [packer.compress(text[k:k + piece].encode("utf-8")) for k in range(0, len(text), piece)]
        parts.append(packer.flush())
        return cls(b"".join(parts), len(text))

    def text(self) -> str:
        """The text, whole."""
        return zlib.decompress(self.data).decode("utf-8")

    def write(self, path: Path, *, piece: int = PIECE) -> None:
        """The text to the file ``path`` as UTF-8 (the bytes ``path.write_text(text,
        encoding="utf-8")`` writes), a piece at a time."""
        unpacker = zlib.decompressobj()
        with open(path, "wb") as out:
            for k in range(0, len(self.data), piece):
                out.write(unpacker.decompress(self.data[k:k + piece]))
            out.write(unpacker.flush())

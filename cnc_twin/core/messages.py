"""Messages between the twin's processes over pipes (the recording process, the paths helper): a
pickle after its length, 8 bytes little-endian."""

from __future__ import annotations

import os
import pickle
import struct

HEADER = struct.Struct("<Q")
"""a message: its pickle's length, then the pickle"""


def framed(message) -> bytes:
    """``message`` pickled, after its length: the bytes to write."""
    payload = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    return HEADER.pack(len(payload)) + payload


def read_exact(fd: int, size: int) -> bytes | None:
    """Exactly ``size`` bytes from ``fd``; None at its end first."""
    parts, left = [], size
    while left:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            return None
        parts.append(chunk)
        left -= len(chunk)
    return b"".join(parts)


def read_payload(fd: int) -> bytes | None:
    """The next message's pickle, not yet loaded (a reading thread hands it on); None at the end."""
    header = read_exact(fd, HEADER.size)
    return None if header is None else read_exact(fd, HEADER.unpack(header)[0])


def read_message(fd: int):
    """The next message; None at the end of ``fd``."""
    payload = read_payload(fd)
    return None if payload is None else pickle.loads(payload)

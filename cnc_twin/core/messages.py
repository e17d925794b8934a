"""Messages between the twin's processes over pipes and sockets (the recording process, the paths
helper, the warm server): a pickle after its length, 8 bytes little-endian."""

from __future__ import annotations

import os
import pickle
import struct
from collections.abc import Callable

HEADER = struct.Struct("<Q")
"""a message: its pickle's length, then the pickle"""


def framed(message) -> bytes:
    """``message`` pickled, after its length: the bytes to write."""
    payload = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    return HEADER.pack(len(payload)) + payload


def read_exact(source: int | Callable[[int], bytes], size: int) -> bytes | None:
    """Exactly ``size`` bytes from ``source`` (a descriptor, or a function reading up to n bytes,
    such as a socket's ``recv``); None at its end first."""
    read = (lambda n: os.read(source, n)) if isinstance(source, int) else source
    parts, left = [], size
    while left:
        chunk = read(min(left, 1 << 20))
        if not chunk:
            return None
        parts.append(chunk)
        left -= len(chunk)
    return b"".join(parts)


def read_payload(source: int | Callable[[int], bytes]) -> bytes | None:
    """The next message's pickle, not yet loaded (a reading thread hands it on); None at the end."""
    header = read_exact(source, HEADER.size)
    return None if header is None else read_exact(source, HEADER.unpack(header)[0])


def read_message(source: int | Callable[[int], bytes]):
    """The next message; None at the end of ``source`` (see :func:`read_exact`)."""
    payload = read_payload(source)
    return None if payload is None else pickle.loads(payload)

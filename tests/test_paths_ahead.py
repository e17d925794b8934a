"""A long program's feed paths prepared in a helper process while the reader reads on
(cnc_twin.gcode.paths_ahead): the same operations, bit for bit and in order, as prepared in the
reader's process; an error where it would come without the helper; a helper that dies replaced
by preparing here; no helper process left once the reading ends, however it ends."""

from __future__ import annotations

import dataclasses
import math
import os
import signal
import struct
from pathlib import Path

import numpy as np
import pytest

from cnc_twin.gcode import toolpath as tp
from cnc_twin.gcode.interpreter import read_program
from cnc_twin.gcode.paths_ahead import PathsAhead
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable


def _raster(passes: int, points: int = 300) -> str:
    """``passes`` zig-zag passes of ``points`` G1 lines over a waved surface under G64 P0.01 (its
    runs fitted), a dwell between passes now and then (operations made at once, between paths)."""
    out = ["G21 G90 G64 P0.01", "G0 X0 Y0 Z5", "G1 Z0 F600", "F3000"]
    for k in range(passes):
        xs = [0.1 * j for j in range(points + 1)]
        for x in (xs if k % 2 == 0 else xs[::-1])[1:]:
            out.append(f"G1 X{x:.4f} Y{0.5 * k:.4f} Z{0.5 * math.sin(x / 3.0) * math.cos(k / 7.0):.4f}")
        if k % 5 == 4:
            out.append("G4 P0.1")
    return "\n".join(out + ["G0 Z5", "M2"]) + "\n"


CALLS = read_program(Source(_raster(30)), ToolTable()).calls


def _bytes(ops) -> list[tuple[str, bytes]]:
    """Every value of the operations, flattened: (where, its type and bits): every field, every
    array's dtype, shape and bytes, every float's bits (a pickle's bytes would also tell which
    objects are shared, which the helper's copies need not match)."""
    out: list[tuple[str, bytes]] = []

    def walk(value, where: str) -> None:
        if isinstance(value, np.ndarray):
            out.append((where, f"{value.dtype.str}{value.shape}".encode() + np.ascontiguousarray(value).tobytes()))
        elif isinstance(value, float):
            out.append((where, struct.pack("<d", value)))
        elif isinstance(value, (list, tuple)):
            out.append((where, f"{type(value).__name__}{len(value)}".encode()))
            for k, item in enumerate(value):
                walk(item, f"{where}[{k}]")
        elif dataclasses.is_dataclass(value) or hasattr(value, "__dict__"):
            out.append((where, type(value).__qualname__.encode()))
            fields = ([f.name for f in dataclasses.fields(value)] if dataclasses.is_dataclass(value)
                      else sorted(vars(value)))
            for name in fields:
                walk(getattr(value, name), f"{where}.{name}")
        else:
            out.append((where, repr(value).encode()))

    for k, op in enumerate(ops):
        walk(op, f"op{k}")
    return out


def _helpers() -> set[int]:
    """This process's children that are path helpers."""
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            command = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        parent = int(stat.rsplit(")", 1)[1].split()[1])
        if parent == os.getpid() and b"cnc_twin.gcode.paths_ahead" in command:
            found.add(int(entry.name))
    return found


def test_the_helper_makes_the_same_operations_in_order():
    here = list(tp.iter_operations(iter(CALLS), path_elements=500))
    ahead = list(tp.iter_operations(iter(CALLS), path_elements=500, helper=True))
    assert len(here) > 20 and sum(isinstance(op, tp.FeedPath) for op in here) > 15
    assert _bytes(ahead) == _bytes(here)
    assert not _helpers()


def test_the_helper_answers_every_path():
    from cnc_twin.gcode.feed_paths import OpenChain

    chains = []
    for k in range(12):
        chain = OpenChain([0.0, float(k), 0.0], [0.1, float(k), 0.01], 10 * k)
        for j in range(2, 80):
            chain.add([0.1 * j, float(k), 0.01 * math.sin(j / 5)], 10 * k + j)
        chains.append([(chain, (3000.0, (0.0, 0.0, 0.0), ("CANON_CONTINUOUS", 0.01)))])
    helped, here = PathsAhead(helper=True, lookahead=3), PathsAhead(helper=False)
    got = []
    for path in chains:
        helped.prepare("feed_paths", path, 0.01)
        here.prepare("feed_paths", path, 0.01)
        got += helped.ready()  # more than three waiting: the first handed out
    got += helped.drain()
    helped.close()
    assert helped.answered == len(chains)
    assert _bytes(got) == _bytes(here.drain())


def test_a_later_error_comes_after_every_operation_made_before_it():
    class Bad(Exception):
        pass

    def failing():
        yield from CALLS[:len(CALLS) // 2]
        raise Bad

    def until_error(helper: bool) -> list:
        got = []
        with pytest.raises(Bad):
            for op in tp.iter_operations(failing(), path_elements=500, helper=helper):
                got.append(op)
        return got

    here = until_error(False)
    assert len(here) > 10
    assert _bytes(until_error(True)) == _bytes(here)
    assert not _helpers()


def test_a_path_the_helper_cannot_prepare_raises_as_here():
    bad = [("not an element", (3000.0, (0.0, 0.0, 0.0), ("CANON_CONTINUOUS", 0.01)))]
    raised = []
    for helper in (False, True):
        ahead = PathsAhead(helper=helper)
        try:
            ahead.prepare("feed_paths", bad, 0.01)
            list(ahead.drain())
        except Exception as exc:  # noqa: BLE001 - the type is compared
            raised.append(type(exc))
        finally:
            ahead.close()
    assert len(raised) == 2 and raised[0] is raised[1]


def test_a_helper_killed_mid_load_is_replaced_by_preparing_here():
    here = list(tp.iter_operations(iter(CALLS), path_elements=500))
    stream = tp.iter_operations(iter(CALLS), path_elements=500, helper=True)
    got = [next(stream)]
    (pid,) = _helpers()
    os.kill(pid, signal.SIGKILL)
    got += list(stream)
    assert _bytes(got) == _bytes(here)
    assert not _helpers()


def test_no_helper_is_left_when_the_reading_stops_early():
    stream = tp.iter_operations(iter(CALLS), path_elements=500, helper=True)
    next(stream)
    assert len(_helpers()) == 1
    stream.close()
    assert not _helpers()


def test_a_path_of_thousands_of_blended_corners_comes_back_whole():
    # each element keeps its turn from the one before (a reference): pickled as it was, a path of
    # 3000 corners would link too deep for pickle; the helper's copy is the same path
    lines = ["G21 G90 G64 P0.01", "G0 X0 Y0 Z5", "G1 Z0 F600", "F3000"]
    lines += [f"G1 X{k:d} Y{k % 2:d}" for k in range(1, 3001)]
    calls = read_program(Source("\n".join(lines + ["M2"]) + "\n"), ToolTable()).calls
    here = list(tp.iter_operations(iter(calls)))
    assert max(len(op.elements) for op in here if isinstance(op, tp.FeedPath)) > 3000
    assert _bytes(tp.iter_operations(iter(calls), helper=True)) == _bytes(here)

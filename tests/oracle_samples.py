"""LinuxCNC's Python ``gcode`` module (the interpreter behind the AXIS preview) as an oracle for the
points LinuxCNC samples along a G5.2 NURBS: ``rs274`` only prints ``NURBS_FEED(<points>, ...)``,
but the module's canon (``gcodemodule.cc``) evaluates the curve with LinuxCNC's own knot vector
and ``nurbs_point`` and hands each sample to ``straight_feed``.

The module is the one unpacked with ``rs274`` (``tests/oracle.py``); it is built for Python 3.11
and keeps global state, so each program runs in a fresh child process, under the same lock as
``rs274``. ``gcode.parse(file, canon, unit_code, init_code, interpreter)`` returns ``(result,
last line)`` (result > ``gcode.MIN_ERROR``: refused, ``gcode.strerror(result)`` is the message).
It needs: a canon answering ``get_external_length_units``, ``get_external_angular_units``,
``get_axis_mask`` (all nine axes, or A words are refused), ``get_block_delete``, ``get_tool``,
``check_abort`` (a callback that fails counts as an interpreter error), a ``parameter_file``
attribute naming a file that exists (else ``link (updating variable file)`` is printed), and a
tool-data memory map (else M6 / D / H crash it; see ``_CHILD``). The other canon calls are
ignored here. The canon receives inches whatever the program's units (the unit code ``G20``
leaves a program without G21 in its own numbers); each point is turned back into the program's
units of its line (``linecode.units``: 200 inches, 210 millimetres).
"""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from oracle import ROOT, TOOL_TABLE

PACKAGES = ROOT / "usr" / "lib" / "python3" / "dist-packages"
MODULE = PACKAGES / "gcode.cpython-311-x86_64-linux-gnu.so"
ABSENT = (f"LinuxCNC's Python gcode module is not unpacked at {MODULE}: run "
          "`python scripts/fetch_linuxcnc_oracle.py` (it needs apt-get and a Debian 12 mirror)")
WRONG_PYTHON = f"LinuxCNC's gcode module is built for Python 3.11, this is {sys.version_info[0]}.{sys.version_info[1]}"

_CHILD = r"""
import ctypes, json, sys
# The interpreter reads tools (M6, D, H) from the tool-data memory map a running LinuxCNC makes;
# without it the module dies on the first tool access. Make one here ($HOME/.tool.mmap) and load
# the oracle's tool table into it (C++ names of libtooldata, LinuxCNC 2.9).
tooldata = ctypes.CDLL("libtooldata.so.0", mode=ctypes.RTLD_GLOBAL)
tooldata._Z17tool_mmap_creatorPK13EMC_TOOL_STATi(ctypes.create_string_buffer(1 << 16), 0)
tooldata._Z13tooldata_initb(ctypes.c_bool(False))
tooldata._Z13tooldata_loadPKcPPc(b"tool.tbl", None)
sys.path.insert(0, sys.argv[1])
import gcode

class Canon:
    def __init__(self, parameter_file):
        self.parameter_file = parameter_file
        self.moves = []
        self.line, self.scale = 0, 1.0
    def next_line(self, state):
        self.line = state.sequence_number
        self.scale = 25.4 if state.units == 210 else 1.0
    def _move(self, kind, args):
        self.moves.append((kind, self.line, [v * self.scale for v in args[:3]]))
    def straight_feed(self, *args): self._move("feed", args)
    def straight_traverse(self, *args): self._move("traverse", args)
    def arc_feed(self, *args): self.moves.append(("arc", self.line, list(args)))
    def get_external_length_units(self): return 1.0
    def get_external_angular_units(self): return 1.0
    def get_axis_mask(self): return 0x1ff  # all nine axes, as rs274 has them
    def get_block_delete(self): return False
    def get_tool(self, index): return (-1,) + (0.0,) * 12 + (0,)
    def check_abort(self): return False
    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *args: None

canon = Canon(sys.argv[3])
result, line = gcode.parse(sys.argv[2], canon, "G20", "", "")
error = gcode.strerror(result) if result > gcode.MIN_ERROR else None
print(json.dumps({"moves": canon.moves, "error": error, "line": line}))
"""


@dataclass
class Move:
    """One motion the module's canon received: ``kind`` feed / traverse / arc, the program ``line``
    it came from, and ``point`` (x, y, z) in the program's units (an arc: its raw arguments)."""

    kind: str
    line: int
    point: tuple[float, ...]


def available() -> bool:
    return MODULE.is_file() and sys.version_info[:2] == (3, 11)


def require() -> None:
    """Skip the calling test, with the reason, when the module cannot run here."""
    import pytest

    if not MODULE.is_file():
        pytest.skip(ABSENT)
    if sys.version_info[:2] != (3, 11):
        pytest.skip(WRONG_PYTHON)


def run(program: str, folder: Path) -> tuple[list[Move], str | None, int]:
    """``program`` (text) through LinuxCNC's gcode module: the motions its canon received, in
    order, with full float precision; the interpreter's refusal (None when the program ran to its
    end) and the line it stopped at."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "program.ngc").write_text(program)
    (folder / "tool.tbl").write_text(TOOL_TABLE)
    parameters = folder / "rs274ngc.var"
    parameters.write_text("")
    env = dict(os.environ, HOME=str(folder),
               LD_LIBRARY_PATH=f"{ROOT / 'usr' / 'lib'}:{ROOT / 'usr' / 'lib' / 'x86_64-linux-gnu'}")
    # the same machine-wide lock as tests/oracle.py: one LinuxCNC interpreter at a time
    with open(Path(tempfile.gettempdir()) / "cnc_twin_rs274.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        out = subprocess.run([sys.executable, "-c", _CHILD, str(PACKAGES), "program.ngc", str(parameters)],
                             cwd=folder, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                             timeout=60)
    lines = [line for line in out.stdout.splitlines() if line.startswith("{")]
    if out.returncode != 0 or not lines:
        raise RuntimeError(f"the gcode module failed (exit {out.returncode}): {out.stderr.strip()[-300:]}")
    answer = json.loads(lines[-1])
    moves = [Move(kind, line, tuple(point)) for kind, line, point in answer["moves"]]
    return moves, answer["error"], answer["line"]

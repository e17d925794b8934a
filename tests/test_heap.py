"""What a run starts with (:func:`cnc_twin.core.heap.return_freed_memory`): a long program's load
leaves nothing large for Python's collector to find late in the run (the interpreter lets go of
the program's text when its reading ends), and the memory the load freed is given back to the
system before the run."""

from __future__ import annotations

import gc
import math

import numpy as np

from cnc_twin.core.heap import resident_bytes, return_freed_memory
from cnc_twin.gcode.source import Source


def _raster(passes: int, points: int = 1000) -> str:
    lines = ["G21 G90 G64 P0.01", "G0 X0 Y0 Z5", "G1 Z0 F600", "F3000"]
    for k in range(passes):
        xs = [0.1 * j for j in range(points + 1)][1:]
        lines += [f"G1 X{x if k % 2 == 0 else 100.0 - x:.4f} Y{0.5 * k:.4f} Z{0.5 * math.sin(x / 3.0):.4f}"
                  for x in xs]
    return "\n".join(lines + ["G0 Z5", "M2"]) + "\n"


def test_a_loaded_program_leaves_no_text_for_the_collector(tmp_path):
    from cnc_twin.scenario.load import load_scenario

    program = tmp_path / "raster.ngc"
    program.write_text(_raster(20))  # 20 000 lines
    gc.collect()
    gc.disable()  # what the load leaves in cycles stays there until looked for
    try:
        load_scenario(program)
        held = [o for o in gc.get_objects() if isinstance(o, Source)]
        assert held == []
    finally:
        gc.enable()


def test_freed_memory_is_given_back():
    return_freed_memory()
    before = resident_bytes()
    # many medium blocks (below the C heap's own mapping threshold): freed, they stay the
    # heap's until trimmed
    blocks = [np.ones(1000) for _ in range(60_000)]  # 8 KB each, 480 MB
    assert resident_bytes() > before + 400e6
    del blocks
    return_freed_memory()
    assert resident_bytes() < before + 50e6

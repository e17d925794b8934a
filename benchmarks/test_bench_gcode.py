"""Reading speed of the G-code reader against LinuxCNC's ``rs274`` on the same program, measured
in the same run (``python -m pytest benchmarks/test_bench_gcode.py --benchmark-only -s``).

The program is ``3D_Chips.ngc`` (200 kB, 4711 lines of CAM-style moves with expressions), shipped
with LinuxCNC. Both sides read the whole program and produce its canonical calls as text: ours in
process (:func:`cnc_twin.gcode.listing.list_program`), rs274 as its own process with output to
/dev/null; rs274's time for an empty program (its start-up) is measured too and taken off, so
the ratio compares reading alone. Goal (issue #20): ours no slower than 2x rs274 (printed with the
ratio; speed is measured, not asserted).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import oracle  # noqa: E402
from cnc_twin.gcode.listing import list_program  # noqa: E402

GOAL = 2.0
"""ours at most this many times rs274's reading time (issue #20)"""
PROGRAM = oracle.ROOT / "usr" / "share" / "linuxcnc" / "ncfiles" / "3D_Chips.ngc"


def _rs274_seconds(folder: Path, name: str, rounds: int = 7) -> float:
    env = dict(os.environ, LD_LIBRARY_PATH=f"{oracle.ROOT / 'usr' / 'lib'}:{oracle.ROOT / 'usr' / 'lib' / 'x86_64-linux-gnu'}")
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        subprocess.run([str(oracle.RS274), "-t", "tool.tbl", "-g", name], cwd=folder, env=env, check=True,
                       stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        best = min(best, time.perf_counter() - start)
    return best


def test_reading_speed_against_rs274(benchmark, tmp_path):
    oracle.require()
    (tmp_path / "tool.tbl").write_text(oracle.TOOL_TABLE)
    (tmp_path / "tool_mm.tbl").write_text(oracle.TOOL_TABLE)
    (tmp_path / "program.ngc").write_bytes(PROGRAM.read_bytes())
    (tmp_path / "empty.ngc").write_text("M2\n")
    lines = len(PROGRAM.read_text().splitlines())
    rs274_whole = _rs274_seconds(tmp_path, "program.ngc")
    rs274_start = _rs274_seconds(tmp_path, "empty.ngc")
    listing, error = benchmark.pedantic(list_program, args=(tmp_path / "program.ngc", tmp_path / "tool.tbl", "inch", True),
                                        rounds=7, iterations=1)
    assert error is None and len(listing) > 4700
    ours = benchmark.stats.stats.min
    rs274 = rs274_whole - rs274_start
    figures = {"lines": lines, "bytes": PROGRAM.stat().st_size, "ours_s": ours, "rs274_s": rs274,
               "rs274_start_s": rs274_start, "ours_lines_per_s": lines / ours, "rs274_lines_per_s": lines / rs274,
               "ratio": ours / rs274}
    benchmark.extra_info.update(figures)
    print(f"\n3D_Chips.ngc, {lines} lines: ours {ours * 1e3:.1f} ms ({lines / ours:,.0f} lines/s), rs274 "
          f"{rs274 * 1e3:.1f} ms ({lines / rs274:,.0f} lines/s; start-up {rs274_start * 1e3:.1f} ms taken off), "
          f"ratio {ours / rs274:.2f} (goal: at most {GOAL:g})")

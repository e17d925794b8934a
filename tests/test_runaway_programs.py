"""A program that does not end is refused in one line at the line of its loop, with its memory
bounded meanwhile (the reader's bounds: ``program.max_calls`` / ``gcode --max-calls`` on the
calls, 2 000 000 by default, and as many O-word lines run for a loop that makes no calls).
The memory is measured at the default bound, once; the rest set a smaller one (the same code,
caught sooner)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


from conftest import run_cli

MOVING = """G21 G90 F1000
G0 X0 Y0 Z5
o100 while [1]
  G1 X1
  G1 X0
o100 endwhile
M2
"""
STILL = """G21 G90 F1000
G0 X0 Y0 Z5
o<spin> while [1]
  #1 = [#1 + 1]
o<spin> endwhile
M2
"""
MEMORY_BOUND_MB = 1500
"""what a process catching the moving loop at the default bound may take at its peak"""


def _cnc_twin(*args: str) -> tuple[int, str, float]:
    """``cnc-twin ARGS`` as its own process: exit code, standard error, peak memory [MB].

    Started by a small Python process that reports its child's peak: Linux counts a process's
    peak from the memory of the process that forked it (a pytest worker may hold a GB)."""
    done = subprocess.run([sys.executable, "-c", _MEASURED, sys.executable, "-m", "cnc_twin", *args],
                          capture_output=True, text=True)
    code, peak_kb = done.stdout.split()
    return int(code), done.stderr, int(peak_kb) / 1024.0


_MEASURED = ("import os, subprocess, sys\n"
             "child = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL)\n"
             "_, status, usage = os.wait4(child.pid, 0)\n"
             "print(os.waitstatus_to_exitcode(status), usage.ru_maxrss)")
"""the measuring process's program: run argv, print its exit code and peak RSS [kB]"""


def _scenario(tmp_path: Path, text: str, **program) -> Path:
    (tmp_path / "p.ngc").write_text(text)
    extra = "".join(f"  {k}: {v}\n" for k, v in program.items())
    (tmp_path / "s.yaml").write_text(f"name: endless\nprogram:\n  type: gcode\n  file: p.ngc\n{extra}")
    return tmp_path / "s.yaml"


def test_an_endless_loop_is_refused_at_its_line_in_bounded_memory(tmp_path):
    _scenario(tmp_path, MOVING)
    code, err, peak = _cnc_twin("gcode", str(tmp_path / "p.ngc"))
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "p.ngc:3:" in err, err
    assert peak < MEMORY_BOUND_MB, peak


def test_validate_refuses_an_endless_loop_at_its_line(tmp_path):
    code, _, err = run_cli("validate", _scenario(tmp_path, MOVING, max_calls=200_000))
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "p.ngc:3:" in err, err


def test_a_loop_that_makes_no_calls_is_refused_at_its_loop(tmp_path):
    """The O-word lines run are bounded by the same ``max_calls``: more than it, refused; a
    loop running fewer reads on."""
    (tmp_path / "p.ngc").write_text(STILL)
    code, out, err = run_cli("gcode", tmp_path / "p.ngc", "--max-calls", "100000")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "p.ngc:3:" in err or "p.ngc:5:" in err, err  # the loop's while or endwhile
    counted = STILL.replace("while [1]", "while [#1 LT 1000]")
    (tmp_path / "q.ngc").write_text(counted)
    code, out, err = run_cli("gcode", tmp_path / "q.ngc", "--max-calls", "100000")
    assert code == 0, err
    code, out, err = run_cli("gcode", tmp_path / "q.ngc", "--max-calls", "1500")
    assert code == 2 and ("q.ngc:3:" in err or "q.ngc:5:" in err), err


def test_the_bound_is_the_scenario_s_to_set(tmp_path):
    """program.max_calls: a loop within it reads whole, one past it is refused at the loop's
    line; lines written out count for nothing (they end with the file)."""
    loop = "G21 G90 F1000\nG0 X0 Y0 Z5\n#1 = 0\no7 while [#1 LT 100]\n  G1 X1\n  G1 X0\n  #1 = [#1 + 1]\no7 endwhile\nM2\n"
    code, _, err = run_cli("validate", _scenario(tmp_path, loop, max_calls=1000))
    assert code == 0, err
    (tmp_path / "b").mkdir()
    code, _, err = run_cli("validate", _scenario(tmp_path / "b", loop, max_calls=150))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "p.ngc:4:" in err, err
    code, _, err = run_cli("gcode", tmp_path / "b" / "p.ngc", "--max-calls", "150")
    assert code == 2 and "p.ngc:4:" in err
    (tmp_path / "c").mkdir()
    written = "G21 G90 F1000\nG0 X0 Y0 Z5\n" + "".join(f"G1 X{k % 2}\n" for k in range(300)) + "M2\n"
    code, _, err = run_cli("validate", _scenario(tmp_path / "c", written, max_calls=100))
    assert code == 0, err

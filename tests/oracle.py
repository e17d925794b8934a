"""LinuxCNC's interpreter as the G-code reader's oracle (``scripts/fetch_linuxcnc_oracle.py``
unpacks it into ``.oracle/linuxcnc``): run ``rs274`` on a program, read its canonical calls."""

from __future__ import annotations

import fcntl
import os
import re
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(os.environ.get("CNC_TWIN_ORACLE", Path(__file__).resolve().parents[1] / ".oracle" / "linuxcnc"))
RS274 = ROOT / "usr" / "bin" / "rs274"
ABSENT = (f"the LinuxCNC oracle is not unpacked at {ROOT}: run `python scripts/fetch_linuxcnc_oracle.py` "
          "(it needs apt-get and a Debian 12 mirror)")
TOOL_TABLE = "T1 P1 Z0.511 D0.125\nT2 P2 Z0.1 D0.0625\n"
CALL = re.compile(r"^\s*\d+ N\S*\s+(\w+)\((.*)\)$")


def available() -> bool:
    return RS274.is_file()


def require() -> None:
    """In a test that compares with the oracle: without it, the test does not run and the summary
    says why (pytest -ra), never a silent pass. CI always unpacks it first (.ci/run)."""
    import pytest

    if not available():
        pytest.skip(ABSENT)


def run(program: str | bytes, folder: Path, parameters: dict[int, float] | None = None, *,
        files: dict[str, str] | None = None, subroutine_path: str | None = None) -> tuple[list[tuple[str, str]], list[str]]:
    """``program`` (text, or the file's bytes) through ``rs274 -g``: its calls as ``(name,
    arguments)`` and the other lines it printed (its error messages), in order. ``parameters``: a
    parameter file's (``-v``) numbered parameters, in rs274's machine units (inches); ``files``:
    more files to write, by path relative to ``folder`` (subroutine files); ``subroutine_path``:
    an INI file's ``[RS274NGC]SUBROUTINE_PATH`` (``-i``; rs274 then prints one ON_RESET fewer at
    its end)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tool.tbl").write_text(TOOL_TABLE)
    if isinstance(program, bytes):
        (folder / "program.ngc").write_bytes(program)
    else:
        (folder / "program.ngc").write_text(program)
    for name, text in (files or {}).items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)
    options = []
    if subroutine_path is not None:
        (folder / "program.ini").write_text(f"[RS274NGC]\nSUBROUTINE_PATH = {subroutine_path}\n")
        options = ["-i", "program.ini"]
    if parameters:
        (folder / "program.var").write_text("".join(f"{k}\t{v:.6f}\n" for k, v in sorted(parameters.items())))
        options += ["-v", "program.var"]
    env = dict(os.environ, LD_LIBRARY_PATH=f"{ROOT / 'usr' / 'lib'}:{ROOT / 'usr' / 'lib' / 'x86_64-linux-gnu'}")
    # One rs274 at a time on the machine: instances running at once share state and some die
    # with a bus error (seen with the suite's parallel workers), their messages lost.
    with open(Path(tempfile.gettempdir()) / "cnc_twin_rs274.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        out = subprocess.run([str(RS274), "-t", "tool.tbl", *options, "-g", "program.ngc"], cwd=folder, env=env,
                             stdin=subprocess.DEVNULL, capture_output=True, timeout=60)
    # bytes, decoded here: its lines end at a newline only, as a program's do (a CR is kept)
    printed = (out.stdout + out.stderr).decode("utf-8", errors="replace")
    if out.returncode < 0 or out.returncode > 128:
        raise RuntimeError(f"rs274 died (exit {out.returncode}): {printed.strip()[-200:]}")
    calls, other = [], []
    for line in printed.split("\n"):
        match = CALL.match(line)
        if match:
            calls.append((match.group(1), match.group(2)))
        elif line.strip() and line.strip() != "executing":
            other.append(line.strip())
    return calls, other


def straight_feeds(calls: list[tuple[str, str]]) -> list[list[str]]:
    """The arguments of each STRAIGHT_FEED among ``calls``, as printed (x, y, z, a, b, c)."""
    return [args.split(", ") for name, args in calls if name == "STRAIGHT_FEED"]

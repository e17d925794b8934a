"""The gallery (docs/examples.md) and its examples: each Python example runs as the gallery's own
command line says (``python examples/NAME.py``, here from a scratch folder holding ``examples``, so
the default picture lands there), exits 0, writes its picture (a real PNG with something drawn in
it), prints that picture's path, and leaves no process behind (the sweeps' workers, the runs'
planners). The gallery names every example and shows the committed picture of each Python one.

Every process an example starts carries a marker in its environment, so one left behind is found
even after it lost its parent.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"
GALLERY = REPO / "docs" / "examples.md"
PICTURES = REPO / "docs" / "examples"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MARKER = "CNC_TWIN_EXAMPLES_TEST"
PC_PROGRAMS = ("pc_jog.py", "pc_curve.c")
"""run against `cnc-twin serve` (tests/test_serve.py runs them); no picture of their own"""
SLOW = {"compare_interpolation.py", "sweep_gains.py", "sweep_force_gains.py", "tune_axis.py"}
"""over about 10 s of CPU each on the 2-core VM (compare_tool_axis.py: about 8 s)"""


def python_examples() -> list[str]:
    return sorted(p.name for p in EXAMPLES.glob("*.py") if p.name not in PC_PROGRAMS)


def gallery_commands() -> dict[str, str]:
    """The gallery's command line of each Python example: the first ``python examples/NAME.py``
    line of a console block that names no other argument (the run it shows, picture by default)."""
    found: dict[str, str] = {}
    for block in re.findall(r"^```console\n(.*?)^```", GALLERY.read_text(encoding="utf-8"), re.S | re.M):
        for line in block.splitlines():
            words = shlex.split(line)
            if len(words) == 2 and words[0] == "python" and words[1].startswith("examples/"):
                found.setdefault(Path(words[1]).name, line)
    return found


def _marked(tag: str) -> list[str]:
    """Live processes (zombies aside) with this test's marker in their environment."""
    needle = f"{MARKER}={tag}".encode()
    alive = []
    for name in filter(str.isdigit, os.listdir("/proc")):
        try:
            environ = Path(f"/proc/{name}/environ").read_bytes()
            stat = Path(f"/proc/{name}/stat").read_text()
            cmdline = Path(f"/proc/{name}/cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:  # gone meanwhile, or not ours to read
            continue
        if needle in environ.split(b"\0") and stat.rsplit(")", 1)[1].split()[0] != "Z":
            alive.append(f"{name}: {cmdline}")
    return alive


def distinct_colours(png: Path) -> int:
    import matplotlib.image

    pixels = matplotlib.image.imread(png)
    return len({tuple(p) for p in pixels.reshape(-1, pixels.shape[-1])[::7]})


def check_picture(png: Path) -> None:
    assert png.is_file(), f"no picture at {png}"
    assert png.read_bytes()[:8] == PNG_SIGNATURE, f"{png} is not a PNG"
    # a plot has axes, labels and data in several colours; a blank or one-colour image has one
    assert distinct_colours(png) > 4, f"{png} is blank"


def run_as_the_gallery_says(command: str, cwd: Path) -> subprocess.CompletedProcess:
    """``command`` (``python examples/NAME.py ...``) with this interpreter, in ``cwd``; afterwards
    none of the processes it started is alive (the resource tracker may outlive it by a moment)."""
    (cwd / "examples").symlink_to(EXAMPLES)
    tag = uuid.uuid4().hex
    proc = subprocess.run([sys.executable, *shlex.split(command)[1:]], cwd=cwd, capture_output=True, text=True,
                          timeout=600, env={**os.environ, MARKER: tag})
    deadline = time.monotonic() + 10.0
    while (left := _marked(tag)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not left, f"{command} left processes behind:\n" + "\n".join(left)
    return proc


@pytest.mark.parametrize("script", [pytest.param(name, marks=[pytest.mark.slow] if name in SLOW else [])
                                    for name in python_examples()])
def test_example_runs_as_the_gallery_says_and_draws_its_picture(script, tmp_path):
    command = gallery_commands().get(script)
    assert command is not None, f"docs/examples.md shows no `python examples/{script}` line"
    proc = run_as_the_gallery_says(command, tmp_path)
    assert proc.returncode == 0, proc.stderr
    picture = tmp_path / script.replace(".py", ".png")  # by default beside the current folder
    check_picture(picture)
    assert str(picture.resolve()) in proc.stdout, "the example does not print where its picture is"
    assert {p.name for p in tmp_path.iterdir()} == {"examples", picture.name}, "files besides the picture"


def test_out_puts_the_picture_where_asked(tmp_path):
    """``--out``, as the gallery's regeneration command uses it (the quickest example's)."""
    (tmp_path / "pictures").mkdir()
    proc = run_as_the_gallery_says("python examples/compare_tool_axis.py --out pictures/axis.png", tmp_path)
    assert proc.returncode == 0, proc.stderr
    check_picture(tmp_path / "pictures" / "axis.png")
    assert str((tmp_path / "pictures" / "axis.png").resolve()) in proc.stdout
    assert not list(tmp_path.glob("*.png"))


def test_the_gallery_shows_every_example_and_its_committed_picture():
    text = GALLERY.read_text(encoding="utf-8")
    for script in python_examples():
        assert f"](examples/{script.replace('.py', '.png')})" in text, f"no picture of {script} in the gallery"
    for program in PC_PROGRAMS:
        assert f"examples/{program}" in text, f"the gallery does not describe {program}"
    shown = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert shown, "the gallery shows no picture"
    for image in shown:
        png = GALLERY.parent / image
        check_picture(png)
        # small enough to keep in git (dpi about 100)
        assert png.stat().st_size < 150_000, f"{image}: {png.stat().st_size} bytes"
    # every committed picture is one the gallery shows (none left over from a renamed example)
    assert sorted(p.name for p in PICTURES.glob("*.png")) == sorted(Path(i).name for i in shown)

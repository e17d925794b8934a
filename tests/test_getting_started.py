"""docs/getting-started.md as a new user follows it: each ```bash block pasted into a shell as
written, in order, in one scratch folder (the bundled scenarios run by name from anywhere).

The install block is the README's first Quickstart command (checked equal here), which needs a
fresh virtual environment and the package index: the suite runs in the environment it installs,
so its `cnc-twin` is on PATH instead. `cnc-twin view ... --web` serves until Ctrl-C: the test
opens the address it prints, as a user pastes it into a browser, then sends Ctrl-C.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pyarrow.parquet as pq
import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "getting-started.md"
BASH = re.compile(r"^```bash\n(.*?)^```", re.S | re.M)

pytestmark = pytest.mark.slow


def _blocks() -> list[str]:
    return BASH.findall(PAGE.read_text(encoding="utf-8"))


def _environment() -> dict[str, str]:
    """The suite's environment with its own interpreter's `cnc-twin` first on PATH."""
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def _serve_and_open(block: str, cwd: Path) -> None:
    """Run a `view --web` block, open the address it prints, end it with Ctrl-C."""
    shell = subprocess.Popen(["bash", "-c", block], cwd=cwd, env=_environment(), stdin=subprocess.DEVNULL,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        printed = ""
        deadline = time.monotonic() + 120
        while "http://" not in printed and time.monotonic() < deadline and shell.poll() is None:
            printed += shell.stdout.readline()
        address = re.search(r"http://\S+", printed)
        assert address, f"no address printed: {printed!r}"
        with urllib.request.urlopen(address.group(0), timeout=30) as page:
            assert page.status == 200
            assert page.read(1)
    finally:
        os.killpg(shell.pid, signal.SIGINT)
        try:
            code = shell.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(shell.pid, signal.SIGKILL)
            raise
    assert code in (0, 130), code


def test_the_install_block_is_the_readme_quickstart():
    install = _blocks()[0]
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    first_quickstart = BASH.findall(readme)[0].strip()
    assert first_quickstart.endswith("&& .venv/bin/cnc-twin run")
    assert install.strip().startswith(first_quickstart.removesuffix(" && .venv/bin/cnc-twin run"))


def test_every_block_pasted_in_order(tmp_path):
    blocks = _blocks()
    assert len(blocks) >= 5
    for block in blocks[1:]:
        if re.search(r"^cnc-twin view .*--web", block, re.M):
            _serve_and_open(block, tmp_path)
            continue
        done = subprocess.run(["bash", "-e", "-c", block], cwd=tmp_path, env=_environment(),
                              stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"{block}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    # what the page says each step leaves
    for run in ("runs/circle", "runs/my-jog"):
        assert (tmp_path / run / "metrics.json").is_file()
        assert pq.read_metadata(tmp_path / run / "trace.parquet").num_rows > 0
    assert (tmp_path / "runs/circle/recording.rrd").stat().st_size > 0
    assert {p.name for p in (tmp_path / "runs/tune-X").glob("*.png")} >= {"X_step.png", "X_bode.png"}
    sweep = pq.read_table(tmp_path / "runs/sweep-kp/sweep.parquet")
    assert sweep.num_rows == 3
    assert (tmp_path / "scenario.schema.json").is_file()

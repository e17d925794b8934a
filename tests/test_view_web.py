"""`cnc-twin view RUN --web` as a user meets it: the printed address, pasted into a browser
(headless Chromium), shows the run, not rerun's Welcome page; the served viewer idles quietly.

Chromium comes from Debian's package `chromium` (.ci/run installs it); without it the test does not
run and pytest's summary says so. Set CNC_TWIN_DOCS_SCREENSHOT=1 to also write the photograph to
docs/rerun_default_blueprint.png (the README's picture of the viewer).
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO
from cnc_twin.view.rerun_export import ACTUAL_RGB, COMMANDED_RGB

CHROMIUM_ABSENT = "Chromium is not installed (Debian: apt-get install chromium; .ci/run installs it)"
IDLE_SHARE = 0.10
"""the served viewer's processes may use at most this share of one core once the page has loaded"""


def _screenshot_script():
    spec = importlib.util.spec_from_file_location("screenshot_rerun", REPO / "scripts" / "screenshot_rerun.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _cpu_seconds(port: int) -> float:
    """CPU time [s] used so far by the processes serving the web viewer on ``port``."""
    total = 0.0
    for proc in Path("/proc").iterdir():
        try:
            if f"--web-viewer-port\0{port}\0".encode() not in (proc / "cmdline").read_bytes():
                continue
            fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime
    return total


def test_the_printed_address_opens_the_run_and_the_server_idles(tmp_path):
    shot = _screenshot_script()
    if shot.chromium_binary() is None:
        pytest.skip(CHROMIUM_ABSENT)
    from cnc_twin.run.twin import run_scenario
    from cnc_twin.scenario.load import load_scenario

    run_dir = run_scenario(load_scenario(REPO / "scenarios" / "nurbs_circle.yaml")).write(tmp_path / "run")
    server, address = shot.serve(run_dir)
    port = int(address.split("://127.0.0.1:", 1)[1].split("/", 1)[0])
    try:
        rested = shot.photograph(address, tmp_path / "viewer.png")
        before, t0 = _cpu_seconds(port), time.monotonic()
        time.sleep(4.0)
        idle_share = (_cpu_seconds(port) - before) / (time.monotonic() - t0)
    finally:
        server.send_signal(signal.SIGINT)
        _, err = server.communicate(timeout=30)
    assert server.returncode == 0 and "Traceback" not in err, err
    assert rested, "the page never came to rest"
    from PIL import Image

    pixels = np.asarray(Image.open(tmp_path / "viewer.png").convert("RGB")).astype(int)
    # the plane view draws the commanded and actual paths in their own colours: on screen only if
    # the page loaded this run (the Welcome page, or a run without the views, shows neither); the
    # actual path draws over the commanded one where they meet (on the commissioned default 486
    # pixels of the commanded colour stay in sight)
    for colour in (COMMANDED_RGB, ACTUAL_RGB):
        assert (np.abs(pixels - colour).max(axis=2) <= 8).sum() > 200, f"no path drawn in {colour}"
    assert idle_share < IDLE_SHARE, f"the served viewer used {idle_share:.0%} of a core while idle"
    if os.environ.get("CNC_TWIN_DOCS_SCREENSHOT"):
        shutil.copyfile(tmp_path / "viewer.png", REPO / "docs" / "rerun_default_blueprint.png")

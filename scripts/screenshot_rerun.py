"""Screenshot of a run in rerun's web viewer with the default blueprint (for the docs).

    python scripts/screenshot_rerun.py RUN_DIR docs/rerun_default_blueprint.png [--wait 25]

Serves the run's ``recording.rrd`` with rerun's bundled web viewer on loopback, opens it in
headless Chromium (Debian package ``chromium``; WebGL through SwiftShader), waits in real time for
the viewer to load and draw, and saves a PNG through the DevTools protocol. Nothing leaves the
machine: the viewer and the data come from 127.0.0.1, and Chromium runs with its background
networking off.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from websockets.sync.client import connect

from cnc_twin.view.viewer import viewer_address

VIEWER_PORT, GRPC_PORT, DEVTOOLS_PORT = 9090, 9876, 9222


def wait_http(url: str, timeout: float) -> bytes:
    deadline = time.monotonic() + timeout
    while True:
        try:
            with urllib.request.urlopen(url, timeout=2) as response:
                return response.read()
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.3)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--wait", type=float, default=25.0, help="seconds to let the viewer load and draw")
    parser.add_argument("--size", default="1600,1000")
    args = parser.parse_args()
    rrd = args.run_dir / "recording.rrd"
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if not rrd.is_file() or chromium is None:
        print("need RUN_DIR/recording.rrd and chromium (apt-get install chromium)", file=sys.stderr)
        return 2
    rerun = Path(sys.executable).with_name("rerun")
    server = subprocess.Popen([str(rerun), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(VIEWER_PORT),
                               "--port", str(GRPC_PORT), str(rrd)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)  # venv/bin/rerun is a wrapper: its binary is a child
    profile = tempfile.mkdtemp(prefix="cnc-twin-chromium-")
    browser = subprocess.Popen([chromium, "--headless", "--no-sandbox", "--use-angle=swiftshader",
                                "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--disable-quic",
                                "--no-first-run", "--disable-background-networking", "--disable-component-update",
                                "--disable-sync", f"--user-data-dir={profile}", f"--window-size={args.size}",
                                f"--remote-debugging-port={DEVTOOLS_PORT}", "about:blank"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        wait_http(f"http://127.0.0.1:{VIEWER_PORT}/", 30)
        pages = json.loads(wait_http(f"http://127.0.0.1:{DEVTOOLS_PORT}/json/list", 30))
        page = next(p for p in pages if p.get("type") == "page")
        url = viewer_address(VIEWER_PORT, GRPC_PORT)
        with connect(page["webSocketDebuggerUrl"], max_size=None) as ws:
            ws.send(json.dumps({"id": 1, "method": "Page.navigate", "params": {"url": url}}))
            time.sleep(args.wait)
            ws.send(json.dumps({"id": 2, "method": "Page.captureScreenshot", "params": {"format": "png"}}))
            while True:
                reply = json.loads(ws.recv())
                if reply.get("id") == 2:
                    break
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_bytes(base64.b64decode(reply["result"]["data"]))
        print(f"wrote {args.out}")
        return 0
    finally:
        for proc in (browser, server):  # each in its own session: end the whole group, children too
            _signal_group(proc, signal.SIGTERM)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                _signal_group(proc, signal.SIGKILL)
                proc.wait()
            _signal_group(proc, signal.SIGKILL)  # a child that outlived its parent
        shutil.rmtree(profile, ignore_errors=True)


def _signal_group(proc: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


if __name__ == "__main__":
    raise SystemExit(main())

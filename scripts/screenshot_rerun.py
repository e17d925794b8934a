"""Photograph a run as `cnc-twin view RUN --web` serves it, in headless Chromium (for the docs and
tests/test_view_web.py).

    python scripts/screenshot_rerun.py RUN_DIR docs/rerun_default_blueprint.png
    python scripts/screenshot_rerun.py --address URL OUT.png     # a viewer already serving

Without ``--address`` it starts ``cnc-twin view RUN_DIR --web`` on a free port and opens the address
that command prints, exactly as a user would paste it. Chromium (Debian package ``chromium``;
WebGL through SwiftShader) runs headless with its background networking off and is driven over
its DevTools pipe (``--remote-debugging-pipe``: JSON messages ended by a NUL byte on file
descriptors 3 and 4, so no extra package is needed). The page is photographed every ``--every``
seconds once ``--wait`` has passed, until two photographs in a row are the same (the viewer has
loaded and drawn) or ``--timeout``; the last is written as PNG. Exit 0 with the path printed, 2
when Chromium or the recording is missing, 1 when the page never came to rest.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                  "--ignore-gpu-blocklist", "--disable-quic", "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--mute-audio", "--hide-scrollbars"]


def chromium_binary() -> str | None:
    """Chromium's path on this machine, or None."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


class DevToolsPipe:
    """Chromium started headless with its DevTools protocol on a pipe; :meth:`call` sends a command
    and returns its result (events in between are dropped)."""

    def __init__(self, chromium: str, size: tuple[int, int]):
        self.profile = tempfile.mkdtemp(prefix="cnc-twin-chromium-")
        to_browser, self._commands = os.pipe()
        self._replies, from_browser = os.pipe()
        # above any descriptor the child will be given, so that the dup2s below cannot clash
        ends = [fcntl_dup(fd) for fd in (to_browser, from_browser)]
        for fd in (to_browser, from_browser):
            os.close(fd)

        def descriptors_3_and_4():
            os.dup2(ends[0], 3)
            os.dup2(ends[1], 4)

        self.process = subprocess.Popen(
            [chromium, *CHROMIUM_FLAGS, f"--user-data-dir={self.profile}", f"--window-size={size[0]},{size[1]}",
             "--remote-debugging-pipe", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, pass_fds=(3, 4),
            preexec_fn=descriptors_3_and_4, start_new_session=True)
        for fd in ends:
            os.close(fd)
        self._next_id, self._buffer = 0, b""

    def call(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 60.0) -> dict:
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._commands, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            while b"\0" not in self._buffer:
                if time.monotonic() > deadline:
                    raise TimeoutError(f"Chromium did not answer {method} within {timeout:.0f} s")
                chunk = os.read(self._replies, 1 << 20)
                if not chunk:
                    raise ConnectionError(f"Chromium closed its DevTools pipe (exit {self.process.poll()})")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})

    def close(self) -> None:
        for fd in (self._commands, self._replies):
            os.close(fd)
        stop_group(self.process)
        shutil.rmtree(self.profile, ignore_errors=True)


def fcntl_dup(fd: int) -> int:
    import fcntl

    return fcntl.fcntl(fd, fcntl.F_DUPFD, 100)


def stop_group(process: subprocess.Popen) -> None:
    """End ``process`` and its whole process group (children too), SIGKILL after 10 s."""
    for sig, wait in ((signal.SIGTERM, 10), (signal.SIGKILL, None)):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            pass
        try:
            process.wait(wait)
            if sig == signal.SIGTERM:
                try:  # a child that outlived its parent
                    os.killpg(process.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            return
        except subprocess.TimeoutExpired:
            continue


def photograph(address: str, out: Path, *, size=(1280, 800), wait=5.0, every=2.0, timeout=150.0) -> bool:
    """Open ``address`` in headless Chromium and write a PNG of it to ``out`` once two photographs
    ``every`` seconds apart (after ``wait``) are the same; True if it came to rest before
    ``timeout`` (the last photograph is written either way)."""
    chromium = chromium_binary()
    if chromium is None:
        raise FileNotFoundError("Chromium is not installed (Debian: apt-get install chromium)")
    browser = DevToolsPipe(chromium, size)
    try:
        target = browser.call("Target.createTarget", {"url": address})["targetId"]
        session = browser.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        browser.call("Emulation.setDeviceMetricsOverride", {"width": size[0], "height": size[1],
                                                            "deviceScaleFactor": 1, "mobile": False}, session)
        started, previous, shot = time.monotonic(), None, b""
        time.sleep(wait)
        while True:
            shot = base64.b64decode(browser.call("Page.captureScreenshot", {"format": "png"}, session)["data"])
            if shot == previous or time.monotonic() - started > timeout:
                break
            previous = shot
            time.sleep(every)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(shot)
        return shot == previous
    finally:
        browser.close()


def serve(run_dir: Path) -> tuple[subprocess.Popen, str]:
    """``cnc-twin view RUN_DIR --web`` on a free port: the process and the address it printed."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "cnc_twin", "view", str(run_dir), "--web", "--port", str(port)],
                              stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              start_new_session=True)
    line = server.stderr.readline()
    if not line.startswith("serving "):
        stop_group(server)
        raise RuntimeError(f"cnc-twin view --web did not serve: {line.strip()}")
    return server, line.split(" at ", 1)[1].split()[0]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, nargs="?", help="a run directory with recording.rrd")
    parser.add_argument("out", type=Path, help="the PNG to write")
    parser.add_argument("--address", help="photograph this address (a viewer already serving) instead of RUN_DIR")
    parser.add_argument("--size", default="1280,800", help="the window in pixels, WIDTH,HEIGHT")
    parser.add_argument("--wait", type=float, default=5.0, help="seconds before the first photograph")
    parser.add_argument("--timeout", type=float, default=150.0, help="seconds to wait for the page to come to rest")
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split(","))
    if chromium_binary() is None:
        print("error: Chromium is not installed (Debian: apt-get install chromium)", file=sys.stderr)
        return 2
    server = None
    if args.address is None:
        if args.run_dir is None or not (args.run_dir / "recording.rrd").is_file():
            print("error: RUN_DIR must hold recording.rrd (or give --address)", file=sys.stderr)
            return 2
        server, args.address = serve(args.run_dir)
    try:
        rested = photograph(args.address, args.out, size=size, wait=args.wait, timeout=args.timeout)
    finally:
        if server is not None:
            stop_group(server)
    print(f"wrote {args.out}" + ("" if rested else f" (the page was still changing after {args.timeout:.0f} s)"))
    return 0 if rested else 1


if __name__ == "__main__":
    raise SystemExit(main())

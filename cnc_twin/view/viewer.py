"""Starting the rerun viewer without usage analytics, leaving the user's own rerun settings alone.

The rerun viewer sends anonymous usage events unless its ``analytics.json`` says otherwise, and
nothing of the twin may reach the network. Viewers the twin starts therefore get a config folder
of cnc-twin's own (``XDG_CONFIG_HOME`` pointed at ``<config>/cnc-twin/rerun-viewer``) holding an
``analytics.json`` with analytics disabled. The file is written directly: even
``rerun analytics disable`` looks a host up (a DNS query was seen under strace).
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import signal
import sys
from collections.abc import Iterator
from pathlib import Path


def display_available() -> bool:
    """Whether a native viewer window can open here (always assumed off Linux)."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def serve_web(recording: Path, port: int) -> int:
    """Serve ``recording`` (a .rrd file) to a browser at http://127.0.0.1:``port`` until Ctrl-C:
    rerun's own web viewer, bound to this machine only, its log kept off the terminal (shown only
    if it fails to start). Returns the exit code (0 after Ctrl-C)."""
    import re
    import subprocess
    import threading

    if not 1024 <= port <= 65535:
        print(f"error: --port: expected 1024 - 65535, got {port}", file=sys.stderr)
        return 2
    in_use = _port_in_use(port)
    if in_use is not None:  # said at once: on a loaded machine rerun may take longer than the wait below to fail
        print(f"error: the web viewer did not start: port {port} on 127.0.0.1 is in use ({in_use}); choose "
              "another with --port", file=sys.stderr)
        return 2
    # The recording is served over gRPC on a port of its own; the page must be told where, or the
    # browser opens rerun's Welcome page instead of the run. A free port is taken here so that
    # the address printed below holds it.
    grpc_port = _free_port()
    # The recording goes in through the server's standard input, which stays open until the end:
    # given the file's path instead, rerun 0.41's server spins a core at 100 % from the moment the
    # file is read (its receiver loop polls a source that has ended), idle or not.
    command = rerun_command() + ["-", "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(port),
                                 "--port", str(grpc_port)]
    # Its own process group: `rerun` may be a launcher whose child is the server, and both must
    # end with the command (Ctrl-C and SIGTERM here stop the whole group).
    with viewer_environment() as env:
        child = subprocess.Popen(command, env=env, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.PIPE, start_new_session=True)
    log: list[bytes] = []
    readers = [threading.Thread(target=_feed, args=(recording, child.stdin), daemon=True),
               threading.Thread(target=lambda: log.extend(child.stderr), daemon=True)]
    for reader in readers:
        reader.start()
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        try:  # a port in use ends it at once: say so instead of "serving"
            child.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            print(f"serving {recording} at {viewer_address(port, grpc_port)} (open it in a browser on this "
                  f"machine; the page is on port {port}, the recording on {grpc_port}: over ssh forward both, "
                  f"ssh -L {port}:127.0.0.1:{port} -L {grpc_port}:127.0.0.1:{grpc_port} HOST); Ctrl-C stops",
                  file=sys.stderr, flush=True)
            child.wait()
    except KeyboardInterrupt:
        return 0
    finally:
        signal.signal(signal.SIGTERM, previous)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(child.pid, signal.SIGTERM)
        child.wait()
        readers[1].join(timeout=5)
    if child.returncode != 0:
        text = b"".join(log).decode("utf-8", "replace")
        lines = [re.sub(r"\x1b\[[0-9;]*m", "", line) for line in text.splitlines() if line.strip()]
        print(f"error: the web viewer did not start: {lines[-1] if lines else 'exit ' + str(child.returncode)}",
              file=sys.stderr)
        return 2
    return 0


def _feed(recording: Path, pipe) -> None:
    """Write ``recording`` into the server's standard input and leave the pipe open (its end tells
    the server the source has ended: see :func:`serve_web`); a server gone early ends it quietly."""
    import shutil

    with contextlib.suppress(OSError), recording.open("rb") as source:
        shutil.copyfileobj(source, pipe, 1 << 20)
        pipe.flush()


def viewer_address(port: int, grpc_port: int) -> str:
    """The address that opens the served recording in rerun's web viewer: the page on ``port``,
    told (its ``url`` parameter) to load the recording from the gRPC proxy on ``grpc_port``."""
    from urllib.parse import quote

    return f"http://127.0.0.1:{port}/?url={quote(f'rerun+http://127.0.0.1:{grpc_port}/proxy', safe='')}"


def _free_port() -> int:
    """A port on 127.0.0.1 that no one listens on now."""
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _port_in_use(port: int) -> str | None:
    """Why ``port`` on 127.0.0.1 cannot be listened on (another server holds it), or None."""
    import socket

    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # a closed socket's TIME_WAIT is no owner
        try:
            probe.bind(("127.0.0.1", port))
        except OSError as exc:
            return exc.strerror or str(exc)
    return None


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def rerun_command() -> list[str]:
    """The rerun CLI of this environment."""
    binary = Path(sys.executable).with_name("rerun")
    return [str(binary)] if binary.exists() else [sys.executable, "-m", "rerun"]


def viewer_config_home() -> Path:
    """cnc-twin's own config folder for rerun viewers, with analytics disabled in it."""
    base = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config") / "cnc-twin" / "rerun-viewer"
    config = base / "rerun" / "analytics.json"
    if not config.is_file():
        config.parent.mkdir(parents=True, exist_ok=True)
        # The layout rerun's own `analytics disable` writes (rerun 0.41).
        config.write_text(json.dumps({
            "analytics_enabled": False,
            "analytics_id": secrets.token_hex(16),
            "metadata": {},
            "config_file_path": str(config),
            "data_dir_path": str(base / "analytics-data"),
        }), encoding="utf-8")
    return base


@contextlib.contextmanager
def viewer_environment() -> Iterator[dict[str, str]]:
    """Within the block, processes started from here (rerun's spawn) use the private config."""
    previous = os.environ.get("XDG_CONFIG_HOME")
    os.environ["XDG_CONFIG_HOME"] = str(viewer_config_home())
    try:
        yield dict(os.environ)
    finally:
        if previous is None:
            os.environ.pop("XDG_CONFIG_HOME", None)
        else:
            os.environ["XDG_CONFIG_HOME"] = previous

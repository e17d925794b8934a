"""``cnc-twin server``: the warm servers' state, starting one now, stopping them
(:mod:`cnc_twin.core.server_link` says what they are)."""

from __future__ import annotations

import os
import time

from cnc_twin.core import server_link

START_TIMEOUT = 180.0
"""how long ``--start`` waits for the server to be ready [s] (a fresh install compiles the kernels)"""


def start_in_a_new_process(timeout: float = START_TIMEOUT) -> bool:
    """``cnc-twin server --start`` as a command of its own (this environment's server, even where
    this one says ``CNC_TWIN_SERVER=off``); True when one is ready."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "cnc_twin", "server", "--start"], capture_output=True,
                          timeout=timeout + 30, env={**os.environ, server_link.VARIABLE: "on"})
    return done.returncode == 0


def start_and_wait(timeout: float = START_TIMEOUT) -> dict | None:
    """Start a server for this process's environment unless one runs; wait until it answers.
    Returns its state (:func:`~cnc_twin.core.server_link.server_status`), None if it did not come up."""
    key = server_link.server_key()
    path = server_link.socket_path(key)
    state = server_link.server_status(path)
    if state is not None:
        return state
    process = server_link.start_server(key)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = server_link.server_status(path) if path.exists() else None
        if state is not None:
            return state
        if process.poll() is not None and not path.exists() and not _lock_held(key):
            return None  # it ended without listening, and no other is starting: it failed (see its log)
        time.sleep(0.05)
    return None


def _lock_held(key: str) -> bool:
    """Whether a server of ``key`` holds its lock (it runs, or is starting)."""
    try:
        fd = server_link.take_lock(server_link.lock_path(key))
    except OSError:
        return False
    if fd is None:
        return True
    os.close(fd)
    return False


def describe(state: dict, path) -> str:
    """One line on a server: its process, age, commands served and running, whether it serves
    this environment."""
    age = time.time() - state.get("started", time.time())
    mine = " (this environment's)" if state.get("key") == server_link.server_key() else ""
    return (f"server pid {state.get('pid')}{mine}: up {age:.0f} s, {state.get('served', 0)} commands served, "
            f"{state.get('running', 0)} running; socket {path}")


def server_command(*, start: bool, stop: bool) -> int:
    """The ``cnc-twin server`` command; exit status 0, or 1 when ``--start`` failed."""
    if not server_link.enabled():
        print(f"the warm server is off ({server_link.VARIABLE}={os.environ.get(server_link.VARIABLE)}): "
              "every command runs in its own process")
        if start:
            return 1
    if stop:
        print(f"stopped {server_link.stop_servers()} server(s)")
        return 0
    if start:
        started = time.monotonic()
        state = start_and_wait()
        if state is None:
            print(f"no server came up (what it said: {server_link.log_path(server_link.server_key())})")
            return 1
        print(f"ready in {time.monotonic() - started:.1f} s")
    paths = server_link.running_servers()
    states = [(path, server_link.server_status(path)) for path in paths]
    for path, state in states:
        if state is not None:
            print(describe(state, path))
    if not any(state for _, state in states):
        print("no server running (the next run, validate, gcode or list command starts one)")
    return 0

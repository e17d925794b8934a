"""Ending a helper subprocess (the planner, the recording process) politely, then firmly."""

from __future__ import annotations

import subprocess


def end_process(popen: subprocess.Popen, *, grace: float, term_grace: float) -> None:
    """EOF on its stdin (the helpers exit on it), wait ``grace`` [s]; then SIGTERM and wait
    ``term_grace`` [s]; then SIGKILL. Returns once the process is reaped."""
    try:
        popen.stdin.close()
    except (OSError, AttributeError):
        pass
    try:
        popen.wait(timeout=grace)
    except subprocess.TimeoutExpired:
        popen.terminate()
        try:
            popen.wait(timeout=term_grace)
        except subprocess.TimeoutExpired:  # pragma: no cover - a helper ignoring SIGTERM
            popen.kill()
            popen.wait()

"""The ``cnc-twin`` program's first lines (also ``python -m cnc_twin``).

A signal can arrive while the interpreter imports the command's modules, before any command has
installed its own handling. Until then nothing exists to clean up (no child process, no shared
memory, no file), so SIGINT and SIGTERM end the program at once with one line and 130 / 143,
instead of a KeyboardInterrupt traceback or a silent death by SIGTERM (exit -15). Each command
replaces these handlers as it starts (``cnc_twin.cli.main``); imports run in light order: this
module imports nothing of the package until the handlers are in place.
"""

from __future__ import annotations

import os
import signal


def _before_start(signum: int, _frame) -> None:
    name = signal.Signals(signum).name
    os.write(2, f"interrupted by {name} before the run began; nothing was written\n".encode())
    os._exit(128 + signum)


def install_start_handlers() -> None:
    """SIGINT and SIGTERM end the program before any command's own handling is installed."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _before_start)


def main() -> int:
    """The ``cnc-twin`` program: its start handlers, then the command, by a warm server if one is
    there, else here (:func:`cnc_twin.cli.main`); the exit code."""
    install_start_handlers()
    from cnc_twin.core.phases import mark

    mark("entry")
    import sys

    from cnc_twin.core.server_link import delegate

    code = delegate(sys.argv[1:])  # a warm server runs it, if one is there (and starts one otherwise)
    if code is not None:
        return code
    from cnc_twin.cli import main as cli_main

    return cli_main()

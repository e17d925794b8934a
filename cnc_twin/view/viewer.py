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
import sys
from collections.abc import Iterator
from pathlib import Path


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

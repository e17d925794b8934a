"""Whether a file is a whole rerun recording, before a viewer is opened on it.

A recording cut short (a disk that filled, a copy interrupted) or another file named ``.rrd``
would otherwise open a viewer, or a browser page, on rerun's own error. :func:`check_recording`
reads it as rerun does: its file header, then every chunk to the end.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from cnc_twin.core.errors import ScenarioError, one_line

HEADER = b"RRF"
"""the start of every rerun recording file (then the format's version)"""
AGAIN = "run the scenario again to record it"


def check_recording(path: Path) -> None:
    """Return if ``path`` is a rerun recording readable to its end; else a
    :class:`~cnc_twin.core.errors.ScenarioError` saying what is wrong (one line)."""
    with open(path, "rb") as file:
        head = file.read(len(HEADER))
    if head != HEADER:
        raise ScenarioError(path, "", f"not a rerun recording (no rerun file header): damaged, or another file; {AGAIN}")
    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rerun's note that a cut file has no footer: the read says more
            for _ in RrdReader(str(path)).stream():
                pass
    except Exception as exc:  # rerun raises RuntimeError today; whatever it raises, the file did not read
        raise ScenarioError(path, "", f"the recording is damaged ({one_line(str(exc))[:160]}); {AGAIN}") from None

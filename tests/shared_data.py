"""Where the outside material to test with lives: ``../shared/data`` beside the checkout (CI lays
a copy of shared/ there), else the workplace's ``/work/shared/data``. A test that reads it and
finds it absent says so plainly (pytest -ra), never passes silently."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CANDIDATES = (ROOT.parent / "shared" / "data", Path("/work/shared/data"))
DATA = next((path for path in CANDIDATES if path.is_dir()), CANDIDATES[0])
OUTSIDE_GCODE = DATA / "outside-gcode" / "progs"
"""real CAM programs from public repositories (sources and licences in SOURCES.tsv beside it)"""
LINUXCNC_NURBS = DATA / "linuxcnc-nurbs"


def require(folder: Path) -> Path:
    """``folder``, or the test does not run and the summary says why."""
    import pytest

    if not folder.is_dir():
        pytest.skip(f"the outside material is not at {folder} (shared/data beside the checkout)")
    return folder

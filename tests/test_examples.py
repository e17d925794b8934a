"""The example scripts run as a user would run them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.mark.parametrize("script, expect", [
    ("tune_axis.py", "twin 1 mm step, current ->"),
    ("sweep_gains.py", "following error rms"),
    ("sweep_force_gains.py", "force error rms"),
    ("compare_tool_axis.py", "nurbs_tilted.yaml"),
    ("compare_interpolation.py", "pulse   dda"),
])
def test_example_runs(script, expect):
    proc = subprocess.run([sys.executable, str(EXAMPLES / script)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert expect in proc.stdout

"""The tuner's plots show what its decision read: the step plot's time axis fits the twin's
steps (their settling, not a fixed half second), and the open loops it draws carry the margins the
table printed.

Reference: the figures :func:`~cnc_twin.studies.tuning.step_figures` reads from the same
responses (python-control's ``step_info``), and the tuner's own table rows.
"""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.studies.tuning import step_figures
from cnc_twin.studies.tuning_plots import SETTLED_SPAN, step_time_limit


def _twin(time: np.ndarray, response: np.ndarray) -> dict:
    return {**step_figures(response, time, 1.0), "time_s": time, "response": response}


def test_the_step_plot_ends_a_few_settling_times_after_the_latest_step_settled():
    t = np.arange(0.0, 0.5, 0.001)
    fast = _twin(t, 1.0 - np.exp(-t / 0.004))  # settles in about 16 ms
    slow = _twin(t, 1.0 - np.exp(-t / 0.02))  # about 78 ms
    limit = step_time_limit({"before": fast, "proposed": slow})
    assert limit == pytest.approx(SETTLED_SPAN * slow["settling_time_s"])
    assert limit < 0.25  # not the half second of the record


def test_a_step_that_never_settles_is_shown_whole():
    t = np.arange(0.0, 0.5, 0.001)
    ringing = _twin(t, 1.0 - np.cos(2 * np.pi * 30.0 * t))  # never within 2 %
    assert not np.isfinite(ringing["settling_time_s"])
    assert step_time_limit({"before": ringing}) == pytest.approx(t[-1])

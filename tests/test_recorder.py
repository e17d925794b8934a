"""The recorder: typed columns at their natural widths, grown when a run runs long, and a trace
whose memory is the raw bytes of what was recorded."""

from __future__ import annotations

import numpy as np

from cnc_twin.dsp.servo import PERIOD_FIELDS
from cnc_twin.trace.layout import PERIOD_DTYPE, TICK_BYTES, TOOL_BYTES
from cnc_twin.trace.recorder import Recorder
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.scenario.load import load_scenario
from cnc_twin.run.twin import Twin

TPP = 4


def _frame(t: int) -> list:
    """A servo frame whose every field tells the tick it came from."""
    per_period = [float(t // TPP + i) if name in ("path_u", "path_ds") else t // TPP + i
                  for i, name in enumerate(PERIOD_FIELDS)]
    return [t + 0.5] * 6 + [t] * 6 + [-(t % 2048)] * 6 + [t * 0.25] + per_period


def _fill(recorder: Recorder, periods: int) -> None:
    first = 19
    for k in range(periods):
        if (k + 1) * TPP > recorder.capacity:
            recorder.grow()
        recorder.record_period(k, _frame(k * TPP), first)
        for t in range(k * TPP, (k + 1) * TPP):
            recorder.record_tick(t, _frame(t))
        recorder.count = (k + 1) * TPP


def test_growing_keeps_every_row_and_the_period_signals_expand_per_tick():
    recorder = Recorder(3, TPP)
    _fill(recorder, 50)  # far beyond the 3 periods planned
    trace = recorder.trace(servo_period=0.00025, counts_per_unit=np.ones(6), copy=False)
    t = np.arange(50 * TPP)
    assert np.array_equal(trace.command[:, 0], t + 0.5)
    assert np.array_equal(trace.actual[:, 5], t) and trace.actual.dtype == np.int32
    assert np.array_equal(trace.dac[:, 2], -(t % 2048)) and trace.dac.dtype == np.int16
    assert np.array_equal(trace.following_error[:, 1], np.full(len(t), 0.5))
    assert np.array_equal(trace.time, t * 0.00025) and np.array_equal(trace.period, t // TPP)
    for i, name in enumerate(PERIOD_FIELDS):
        assert np.array_equal(trace.period_signals[name], t // TPP + i), name
        assert len(trace.period_signals.per_period(name)) == 50
    assert trace.period_signals["state"].dtype == np.int64 and trace.period_signals["path_u"].dtype == np.float64


def test_raw_bytes_are_the_natural_widths():
    assert TICK_BYTES == 92 and PERIOD_DTYPE.itemsize == 75 and TOOL_BYTES == 48
    recorder = Recorder(10, TPP)
    _fill(recorder, 10)
    trace = recorder.trace(servo_period=0.00025, counts_per_unit=np.ones(6), copy=False)
    assert trace.raw_nbytes() == 40 * 92 + 10 * (75 + 48) == trace.nbytes() == trace.held_nbytes()


def test_a_short_run_copies_out_of_a_large_recorder():
    recorder = Recorder(100, TPP)
    _fill(recorder, 10)
    trace = recorder.trace(servo_period=0.00025, counts_per_unit=np.ones(6), copy=False)
    assert trace.held_nbytes() == trace.raw_nbytes()  # not the 100 periods' room


def test_a_run_trace_holds_within_20_percent_of_its_raw_bytes():
    result = Twin(load_scenario(scenarios_dir() / "nurbs_circle.yaml")).run()
    trace = result.trace
    assert len(trace) == result.metrics["servo_ticks"] > 10_000
    assert trace.held_nbytes() <= 1.2 * trace.raw_nbytes()
    # against float64 everywhere, as the rows were kept before: 2.5 times as much
    assert trace.raw_nbytes() < 0.5 * len(trace) * (len(trace.columns())) * 8

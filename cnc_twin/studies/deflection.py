"""The tool tip's acceleration-dependent deflection, measured on the circular tests for the card's
correction (``servo.<axis>.deflection``, :func:`~cnc_twin.dsp.servo.deflection_correction`).

A semi-closed loop holds its motor encoder on the command; the tip, beyond the screw and the
structure, deflects with the forces that accelerate it (the screw winds up, the bridge bends), by
an amount proportional to the accelerations. A machine builder measures it with the tip (a
ballbar, a laser tracker or a second scale on the table) against the motor encoders, and enters it
as an acceleration-dependent correction (Heidenhain's cross-talk compensation, CTC)::

    tip_i - encoder_i = d_i + sum_j c_ij a_j        least squares over the tests' periods

``a_j`` the commanded acceleration of axis j [m/s^2] (the card's command, twice differenced per
period), ``c_ij`` [s^2] the deflection, ``d_i`` the frames' offset. Coefficients below
:data:`SMALLEST` are left out (the fit's noise, not a deflection). The tests run at
:data:`FEED_FACTOR` times their feed (:func:`fast_circular_traces`): at the acceptance's 3 m/min
on R50 the centripetal acceleration (0.05 m/s^2) deflects the tip by about one encoder count.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.studies.reversal_tuning import circular_tests

FEED_FACTOR = 4.0
"""the circular tests' feed for the measurement, times theirs (F3000 -> F12000 on R50: 0.8 m/s^2)"""

SMALLEST = 1e-6
"""[s^2] (1 um per m/s^2) the smallest deflection kept"""


def deflection_samples(trace, axes: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """From one run's ``trace`` (:class:`~cnc_twin.trace.trace.Trace`): per period, the tip
    less the encoder of ``axes`` [m], shape ``(n, k)``, and their commanded accelerations [m/s^2],
    shape ``(n, k)``; linear axes only."""
    tpp = trace.ticks_per_period
    n = len(trace.tool)
    columns = [AXES.index(a) for a in axes]
    encoder = trace.actual[tpp - 1::tpp][:n, columns] / trace.counts_per_unit[columns]
    command = trace.command[tpp - 1::tpp][:n, columns] / trace.counts_per_unit[columns]
    period = float(trace.servo_period) * tpp
    acceleration = np.gradient(np.gradient(command, period, axis=0), period, axis=0)
    return trace.tool[:, columns] - encoder, acceleration


def fit_deflection(traces: Iterable, axes: Sequence[str] = ("X", "Y", "Z")) -> dict[str, dict[str, float]]:
    """The deflection ``c_ij`` [s^2] of each of ``axes`` on each one's acceleration (module
    docstring), fitted over the periods of all ``traces`` (each run its own offset); only those of
    at least :data:`SMALLEST`."""
    blocks = [deflection_samples(trace, axes) for trace in traces]
    out: dict[str, dict[str, float]] = {}
    for i, axis in enumerate(axes):
        rows, targets = [], []
        for k, (deflection, acceleration) in enumerate(blocks):
            offsets = np.zeros((len(deflection), len(blocks)))
            offsets[:, k] = 1.0
            rows.append(np.column_stack([acceleration, offsets]))
            targets.append(deflection[:, i])
        coefficients, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(targets), rcond=None)
        out[axis] = {other: float(c) for other, c in zip(axes, coefficients[:len(axes)]) if abs(c) >= SMALLEST}
    return out


def deflection_overrides(deflection: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """``servo.<axis>.deflection`` overrides [um per m/s^2] from :func:`fit_deflection`'s [s^2]."""
    return {f"servo.{axis}.deflection": {other: round(c * 1e6, 2) for other, c in row.items()}
            for axis, row in deflection.items() if row}


def fast_circular_traces(base: Mapping[str, Any], *, scenarios: Path, planes: Sequence[str] = ("XY", "XZ", "YZ"),
                         factor: float = FEED_FACTOR) -> list:
    """The traces of the bundled circular tests of ``planes`` (``scenarios``' ``ballbar_<plane>``)
    with ``base`` overrides, their programs' F words times ``factor``."""
    tests = circular_tests(base, scenarios=scenarios, planes=planes, feed_factor=factor, keep_traces=True)
    return [t.trace for t in tests.values()]

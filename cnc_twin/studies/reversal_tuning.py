"""Reversal (quadrant error) compensation commissioned as a machine builder does it: a first setting
from the identified friction and the drive's velocity loop, then refined on the circular test.

The first setting (why: :mod:`cnc_twin.dsp.reversal`). At a reversal the drive's velocity
integrator must swing from +c to -c, c the axis's Coulomb friction. A speed pulse ``A exp(-t / T)``
gives the proportional path ``kp A`` at once and the integrator ``kp A T / tn`` in the end, so::

    A    = 2 c / kp          [m/s | rad/s]   (Mitsubishi's "double the friction torque")
    T    = tn                [s]             the drive's integral time: the pulse hands over as
                                              the integrator takes it up
    lead = 0                 [s]

``c`` from :func:`~cnc_twin.studies.commissioning.identify_rigid_body` (the drive's own signals),
``kp`` and ``tn`` from the drive's parameters.

The refinement: a coordinate search on the circular test (ISO 230-4, the bundled ``ballbar_*``
scenarios), each axis judged by its own quadrants' reversal spikes (the first axis of a plane
reverses at 0 / 180 deg, the second at 90 / 270), both directions: the objective is the largest
spike's size in um. Both axes of a plane are searched in the same runs (their quadrants apart).
The steps, each keeping the best so far: the lead (what MuJoCo's friction, a soft constraint,
lets creep on before the zero), the amplitude, the decay time, the lead again finer.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from cnc_twin.core import units
from cnc_twin.core.axes import AXES
from cnc_twin.core.config import Scenario

PLANES = ("XY", "XZ", "YZ")
"""the circular tests, in the order the search runs them"""
QUADRANTS_OF = {0: ("0", "180"), 1: ("90", "270")}
"""a plane's first / second axis -> the quadrants (metrics' keys) where it reverses"""
LEAD_STEPS = (0.0, 5e-3, 10e-3, 15e-3, 20e-3)
"""[s] the lead's first search"""
AMPLITUDE_FACTORS = (0.8, 0.9, 1.1, 1.2)
TIME_FACTORS = (0.75, 1.5)
LEAD_REFINE = (-2.5e-3, 2.5e-3)
AMPLITUDE_REFINE = (0.95, 1.05)


@dataclass
class ReversalSetting:
    """One axis's reversal compensation in SI: ``amplitude`` [m/s | rad/s], ``time`` [s], ``lead``
    [s]; ``spike`` the largest reversal spike [um] the circular test measured with it (None:
    not measured yet)."""

    axis: str
    amplitude: float
    time: float
    lead: float = 0.0
    spike: float | None = None

    def overrides(self) -> dict[str, float]:
        """The scenario overrides that set it, in the scenario's units (mm/min | deg/min, ms)."""
        rotary = AXES.index(self.axis) >= 3
        return {f"servo.{self.axis}.reversal_amplitude": round(self.amplitude / units.velocity_factor(rotary), 3),
                f"servo.{self.axis}.reversal_time": round(self.time / units.MS, 3),
                f"servo.{self.axis}.reversal_lead": round(self.lead / units.MS, 3)}


@dataclass
class SearchLog:
    """Every circular test the search ran: the overrides and the spikes per axis [um]."""

    runs: list[tuple[dict[str, float], dict[str, float]]] = field(default_factory=list)


def first_setting(scenario: Scenario, axis: str, coulomb: float | None = None) -> ReversalSetting:
    """The first setting from the drive and the friction (module docstring): ``coulomb`` [N | N m]
    at the axis, identified on the twin when None."""
    drive = scenario.axis(axis).drive
    if drive is None:
        raise ValueError(f"{axis}: the reversal compensation is set from a drive with loops of its own "
                         "(the parameter file's drive: ...); this axis has the MJCF's ideal velocity source")
    if coulomb is None:
        from cnc_twin.studies.commissioning import identify_rigid_body
        coulomb = identify_rigid_body(scenario, axis).coulomb
    return ReversalSetting(axis, amplitude=2.0 * coulomb / drive.kp, time=drive.tn)


def plane_spikes(metrics: Mapping[str, Any], plane: str) -> dict[str, float]:
    """The largest reversal spike's size [um] of each axis of ``plane`` over both directions, from
    a run's metrics (``ballbar``)."""
    ballbar = metrics["ballbar"]
    out = {}
    for k, axis in enumerate(plane):
        sizes = [abs(ballbar[d]["reversal_spikes_um"][q]) for d in ("ccw", "cw") for q in QUADRANTS_OF[k]]
        out[axis] = max(sizes)
    return out


def circular_test(plane: str, overrides: Mapping[str, Any], *, scenarios: Path) -> dict[str, Any]:
    """Run the bundled circular test of ``plane`` with ``overrides``; its metrics."""
    from cnc_twin.run.twin import run_scenario
    from cnc_twin.scenario.load import load_scenario

    scenario = load_scenario(scenarios / f"ballbar_{plane.lower()}.yaml", overrides=dict(overrides))
    return run_scenario(scenario).metrics


def search_plane(plane: str, settings: dict[str, ReversalSetting], base: Mapping[str, Any], *, scenarios: Path,
                 tune: Sequence[str] | None = None, log: SearchLog | None = None,
                 report: Callable[[str], None] = lambda line: None) -> dict[str, float]:
    """Refine the ``settings`` of ``tune`` (default: both of ``plane``'s axes) in place (module
    docstring) on the circular test of ``plane`` with ``base`` overrides and every setting's;
    each axis is judged in this plane only (its spike measured again here first). Returns the
    plane's spikes [um] per axis with the settings kept."""
    axes = tuple(tune if tune is not None else plane)

    def trial(candidate: dict[str, ReversalSetting]) -> dict[str, float]:
        overrides = dict(base)
        for s in settings.values():
            overrides.update(s.overrides())
        for s in candidate.values():
            overrides.update(s.overrides())
        spikes = plane_spikes(circular_test(plane, overrides, scenarios=scenarios), plane)
        if log is not None:
            log.runs.append((overrides, spikes))
        return spikes

    def keep(candidates: Sequence[dict[str, ReversalSetting]]) -> None:
        for candidate in candidates:
            spikes = trial(candidate)
            for axis in axes:
                best = settings[axis]
                if best.spike is None or spikes[axis] < best.spike:
                    chosen = candidate[axis]
                    chosen.spike = spikes[axis]
                    settings[axis] = chosen
        report(f"{plane}: " + ", ".join(f"{a} {_describe(settings[a])}" for a in axes))

    def varied(change: Callable[[ReversalSetting], ReversalSetting]) -> dict[str, ReversalSetting]:
        return {a: change(settings[a]) for a in axes}

    for axis in axes:
        settings[axis].spike = None
    if not axes:  # a plane only checked
        return trial({})
    keep([varied(lambda s: replace(s, spike=None))])
    keep([varied(lambda s, lead=lead: replace(s, lead=lead, spike=None)) for lead in LEAD_STEPS])
    keep([varied(lambda s, f=f: replace(s, amplitude=s.amplitude * f, spike=None)) for f in AMPLITUDE_FACTORS])
    keep([varied(lambda s, f=f: replace(s, time=s.time * f, spike=None)) for f in TIME_FACTORS])
    keep([varied(lambda s, d=d: replace(s, lead=max(0.0, s.lead + d), spike=None)) for d in LEAD_REFINE])
    keep([varied(lambda s, f=f: replace(s, amplitude=s.amplitude * f, spike=None)) for f in AMPLITUDE_REFINE])
    return {axis: settings[axis].spike for axis in axes}


def _describe(s: ReversalSetting) -> str:
    o = s.overrides()
    a, t, lead = (o[f"servo.{s.axis}.reversal_{k}"] for k in ("amplitude", "time", "lead"))
    unit = "deg/min" if AXES.index(s.axis) >= 3 else "mm/min"
    return f"{a:.0f} {unit} / {t:.1f} ms / lead {lead:.1f} ms: spike {s.spike:.1f} um"

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

The refinement: a coordinate search on the circular tests (ISO 230-4, the bundled ``ballbar_*``
scenarios in XY, XZ and YZ), each axis judged by its own quadrants' reversal spikes (the first
axis of a plane reverses at 0 / 180 deg, the second at 90 / 270) in both directions and every
plane it is in: the objective is the largest spike's size in um; between spikes within
:data:`SPIKE_TIE` of the smallest seen, the smaller circular deviation G of its planes. All
axes are varied in the same runs (their quadrants apart). The steps, each keeping the best so
far: the lead (what MuJoCo's friction, a soft constraint, lets creep on before the zero) and the
rise time together, the amplitude, the lead and the amplitude finer, the decay time,
backlash from the lost motion (:func:`reversal_steps`), the lead and the amplitude finer again.
"""

from __future__ import annotations

import re
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core import units
from cnc_twin.core.axes import AXES
from cnc_twin.core.config import Scenario

PLANES = ("XY", "XZ", "YZ")
"""the circular tests, in the order the search runs them"""
QUADRANTS_OF = {0: ("0", "180"), 1: ("90", "270")}
"""a plane's first / second axis -> the quadrants (metrics' keys) where it reverses"""
LEAD_STEPS = (0.0, 5e-3, 10e-3, 15e-3, 20e-3, 25e-3)
"""[s] the lead's first search"""
RISE_STEPS = (0.0, 5e-3, 10e-3)
"""[s] the rise times searched, each with every lead of LEAD_STEPS (a slower rise wants more lead)"""
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
    rise: float = 0.0
    min_speed: float = 0.0
    """the commanded speed a move must reach for its reversal to count [m/s | rad/s] (0: any)"""
    standstill: float = 0.0
    """the share of the pulse given at a stop and at the start after it (0: none)"""
    start_speed: float = 0.0
    stop_speed: float = 0.0
    """the commanded speeds a start's pulse waits for and a stop's pulse comes under [m/s | rad/s]"""
    adapt_amplitude: float = 0.0
    adapt_from: float = 0.0
    adapt_to: float = 0.0
    """the adaptation characteristic: the pulse [m/s | rad/s] at a reversal with the acceleration
    ``adapt_to``, from ``amplitude`` at ``adapt_from`` [m/s^2 | rad/s^2] (0: none)"""
    backlash: float = 0.0
    """the card's backlash compensation [m | rad] (:mod:`cnc_twin.dsp.compensation`); negative
    where the tool leads the motor"""
    spike: float | None = None
    """the largest reversal spike [um] the circular tests measured with it (None: not yet)"""
    circular: float | None = None
    """the largest circular deviation G [um] of its axis's planes, measured with it"""

    def overrides(self) -> dict[str, float]:
        """The scenario overrides that set it, in the scenario's units (mm/min | deg/min, ms, mm | deg)."""
        rotary = AXES.index(self.axis) >= 3
        a = self.axis
        return {f"servo.{a}.reversal_amplitude": round(self.amplitude / units.velocity_factor(rotary), 3),
                f"servo.{a}.reversal_time": round(self.time / units.MS, 3),
                f"servo.{a}.reversal_lead": round(self.lead / units.MS, 3),
                f"servo.{a}.reversal_rise": round(self.rise / units.MS, 3),
                f"servo.{a}.reversal_min_speed": round(self.min_speed / units.velocity_factor(rotary), 3),
                f"servo.{a}.reversal_standstill": round(self.standstill, 3),
                f"servo.{a}.reversal_start_speed": round(self.start_speed / units.velocity_factor(rotary), 3),
                f"servo.{a}.reversal_stop_speed": round(self.stop_speed / units.velocity_factor(rotary), 3),
                f"servo.{a}.reversal_adapt_amplitude": round(self.adapt_amplitude / units.velocity_factor(rotary), 3),
                f"servo.{a}.reversal_adapt_from": round(self.adapt_from / units.position_factor(rotary), 3),
                f"servo.{a}.reversal_adapt_to": round(self.adapt_to / units.position_factor(rotary), 3),
                f"axes.{a}.compensation.backlash": round(self.backlash / units.position_factor(rotary), 5)}


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


def plane_spikes(ballbar: Mapping[str, Any], plane: str) -> dict[str, float]:
    """The largest reversal spike's size [um] of each axis of ``plane`` over both directions, from
    a circular test's figures (metrics.json's ``ballbar``)."""
    out = {}
    for k, axis in enumerate(plane):
        sizes = [abs(ballbar[d]["reversal_spikes_um"][q]) for d in ("ccw", "cw") for q in QUADRANTS_OF[k]]
        out[axis] = max(sizes)
    return out


@dataclass(frozen=True)
class CircularTest:
    """One circular test's ``figures`` (metrics.json's ``ballbar``), its ``passes``
    (:class:`~cnc_twin.run.ballbar.BallbarPass`) and its ``test`` (the scenario's
    :class:`~cnc_twin.core.config.BallbarTest`); ``trace`` the run's, when asked for."""

    figures: dict[str, Any]
    passes: list
    test: Any
    trace: Any = None


def circular_tests(base: Mapping[str, Any], *, scenarios: Path, planes: Sequence[str] = PLANES,
                   feed_factor: float = 1.0, keep_traces: bool = False) -> dict[str, CircularTest]:
    """The bundled circular tests of ``planes`` (``scenarios``' ``ballbar_<plane>.yaml``) run with
    ``base`` overrides, per plane; ``feed_factor`` times their programs' F words (copies in a
    temporary folder), ``keep_traces`` to keep each run's trace."""
    from cnc_twin.run.ballbar import ballbar_passes
    from cnc_twin.run.twin import run_scenario
    from cnc_twin.scenario.load import load_scenario

    out = {}
    with tempfile.TemporaryDirectory(prefix="cnc-twin-circular-") as folder:
        for plane in planes:
            path = scenarios / f"ballbar_{plane.lower()}.yaml"
            overrides = dict(base)
            if feed_factor != 1.0:
                program = Path(load_scenario(path, overrides=overrides).program.file)
                faster = Path(folder) / program.name
                faster.write_text(re.sub(r"F(\d+(?:\.\d*)?)", lambda m: f"F{float(m.group(1)) * feed_factor:g}",
                                         program.read_text()))
                overrides["program.file"] = str(faster)
            scenario = load_scenario(path, overrides=overrides)
            result = run_scenario(scenario)
            passes = ballbar_passes(result.trace, scenario.ballbar, scenario.timing.interpolation_period)
            out[plane] = CircularTest(result.metrics["ballbar"], passes, scenario.ballbar,
                                      result.trace if keep_traces else None)
    return out


def reversal_acceleration(tests: Mapping[str, CircularTest]) -> float:
    """[m/s^2] the smallest centripetal acceleration v^2 / R of the tests' passes (``v`` the
    measured mean feed): an axis's commanded acceleration at its reversal on a circle."""
    return min(p.feed ** 2 / t.test.radius for t in tests.values() for p in t.passes)


@dataclass(frozen=True)
class AxisFigures:
    """What the circular tests say of one axis over the planes it is in: ``spike`` the largest
    reversal spike's size [um], ``lost_motion`` the mean step of the radial deviation across its
    reversals [um] (:func:`reversal_steps`; outward positive)."""

    spike: float
    lost_motion: float
    circular: float
    """the largest circular deviation G [um] of the planes it is in"""


SPIKE_TIE = 0.3
"""[um] spikes within this of the smallest an axis has shown count as equal; G decides between them"""


def reversal_steps(passes, plane: str) -> dict[str, float]:
    """Each axis of ``plane``'s lost motion [um]: the median radial deviation 5 - 15 deg after its
    reversals less 5 - 15 deg before, in the direction of travel, over its two quadrants and the
    passes (``passes``: :class:`~cnc_twin.run.ballbar.BallbarPass`). A tip that lags its motor by
    L/2 in the direction of motion (friction through the screw's and the structure's compliance,
    which the motor's encoder does not see) steps outward by L at every reversal: backlash, as the
    ballbar's analysis names it, and what the card's backlash compensation takes off."""
    out = {}
    for k, axis in enumerate(plane):
        steps = []
        for p in passes:
            sign = 1.0 if p.direction == "ccw" else -1.0
            for quadrant in QUADRANTS_OF[k]:
                rel = np.degrees(np.angle(np.exp(1j * (p.angle - np.radians(float(quadrant)))))) * sign
                after = p.deviation[(rel > 5.0) & (rel < 15.0)]
                before = p.deviation[(rel < -5.0) & (rel > -15.0)]
                if len(after) and len(before):
                    steps.append(float(np.median(after) - np.median(before)) * 1e6)
        out[axis] = float(np.mean(steps)) if steps else 0.0
    return out


def axis_figures(overrides: Mapping[str, Any], *, scenarios: Path, planes: Sequence[str] = PLANES,
                 feed_factor: float = 1.0) -> dict[str, AxisFigures]:
    """Each axis's :class:`AxisFigures` over the circular tests of ``planes`` it is in (the spike
    the largest, the lost motion the mean), at ``feed_factor`` times their feed."""
    spikes: dict[str, float] = {}
    steps: dict[str, list[float]] = {}
    circular: dict[str, float] = {}
    for plane, test in circular_tests(overrides, scenarios=scenarios, planes=planes, feed_factor=feed_factor).items():
        g = max(test.figures[d]["circular_deviation_um"] for d in ("ccw", "cw"))
        for axis, spike in plane_spikes(test.figures, plane).items():
            spikes[axis] = max(spikes.get(axis, 0.0), spike)
            circular[axis] = max(circular.get(axis, 0.0), g)
        for axis, step in reversal_steps(test.passes, plane).items():
            steps.setdefault(axis, []).append(step)
    return {axis: AxisFigures(spikes[axis], float(np.mean(steps[axis])), circular[axis]) for axis in spikes}


def search(settings: dict[str, ReversalSetting], base: Mapping[str, Any], *, scenarios: Path,
           counts_per_unit: Mapping[str, float], planes: Sequence[str] = PLANES,
           report: Callable[[str], None] = lambda line: None) -> dict[str, AxisFigures]:
    """Refine ``settings`` (per axis) in place (module docstring) on the circular tests of
    ``planes`` with ``base`` overrides: every trial runs them all and judges each axis by its
    largest spike over the planes it is in, so a setting good in one plane and bad in another is
    not kept; ``counts_per_unit`` per axis [counts/m | counts/rad] rounds the backlash to whole
    counts. Returns each axis's figures with the settings kept."""
    axes = tuple(settings)
    kept: dict[str, AxisFigures] = {}

    floor: dict[str, float] = {}  # the smallest spike each axis has shown

    def keep(candidates: Sequence[dict[str, ReversalSetting]], step: str) -> None:
        """Run each candidate; per axis keep it where its spike is smaller by more than
        :data:`SPIKE_TIE`, or no larger than that above the smallest seen and its planes' G is
        smaller."""
        for candidate in candidates:
            overrides = dict(base)
            for s in candidate.values():
                overrides.update(s.overrides())
            figures = axis_figures(overrides, scenarios=scenarios, planes=planes)
            for axis in axes:
                best, new = settings[axis], figures[axis]
                if best.spike is None:
                    better = True
                elif new.spike < best.spike - SPIKE_TIE:
                    better = True
                else:
                    better = new.spike <= floor[axis] + SPIKE_TIE and new.circular < best.circular
                floor[axis] = min(floor.get(axis, np.inf), new.spike)
                if better:
                    candidate[axis].spike, candidate[axis].circular = new.spike, new.circular
                    settings[axis] = candidate[axis]
                    kept[axis] = new
        report(f"{step}: " + ", ".join(f"{a} {describe(settings[a])}" for a in axes))

    def varied(change: Callable[[ReversalSetting], ReversalSetting]) -> dict[str, ReversalSetting]:
        return {a: replace(change(settings[a]), spike=None, circular=None) for a in axes}

    def lost_motion() -> None:
        """Backlash compensation from the tip's step across the reversals (and half of it), in
        whole encoder counts: less than one the motor's loop cannot hold, and a fraction of a count
        only moves where its friction limit cycle sits (a Y move settled 4 counts off)."""
        measured = {a: kept[a].lost_motion * 1e-6 for a in axes}

        def counted(s: ReversalSetting, f: float) -> ReversalSetting:
            count = 1.0 / counts_per_unit[s.axis]
            return replace(s, backlash=round((s.backlash + f * measured[s.axis]) / count) * count)

        keep([varied(lambda s, f=f: counted(s, f)) for f in (0.5, 1.0)], "backlash from the lost motion")

    for axis in axes:
        settings[axis].spike = settings[axis].circular = None
    keep([varied(lambda s: s)], "first setting")
    keep([varied(lambda s, lead=lead, rise=rise: replace(s, lead=lead, rise=rise)) for rise in RISE_STEPS
          for lead in LEAD_STEPS], "lead and rise")
    keep([varied(lambda s, f=f: replace(s, amplitude=s.amplitude * f)) for f in AMPLITUDE_FACTORS], "amplitude")
    keep([varied(lambda s, d=d: replace(s, lead=max(0.0, s.lead + d))) for d in LEAD_REFINE], "lead, finer")
    keep([varied(lambda s, f=f: replace(s, amplitude=s.amplitude * f)) for f in AMPLITUDE_REFINE], "amplitude, finer")
    keep([varied(lambda s, f=f: replace(s, time=s.time * f)) for f in TIME_FACTORS], "decay time")
    lost_motion()
    keep([varied(lambda s, d=d: replace(s, lead=max(0.0, s.lead + d))) for d in LEAD_REFINE], "lead, finer")
    keep([varied(lambda s, f=f: replace(s, amplitude=s.amplitude * f)) for f in AMPLITUDE_REFINE], "amplitude, finer")
    return kept


ADAPT_FEED_FACTOR = 2.0
"""the adaptation's circular tests run at this times the acceptance's feed (6 m/min: a reversal at
4 x the acceleration, 0.2 m/s^2 at R 50, near the bundled 6 m/min circle's 0.25)"""
ADAPT_FACTORS = (1.0, 1.05, 1.1, 1.15, 1.2, 1.3, 1.4)
"""the pulse at the faster tests' reversals, tried as these times the one the acceptance's tests set"""


def adapt(settings: dict[str, ReversalSetting], base: Mapping[str, Any], *, scenarios: Path, accel_from: float,
          planes: Sequence[str] = PLANES, report: Callable[[str], None] = lambda line: None) -> float:
    """Set ``settings``' adaptation characteristic in place (Siemens' friction compensation with
    adaptation: the pulse a reversal needs grows with the acceleration it comes with): the circular
    tests of ``planes`` at :data:`ADAPT_FEED_FACTOR` times their feed, ``base`` overrides, every
    axis's pulse there tried at each of :data:`ADAPT_FACTORS` times its own in the same runs, each
    axis keeping the factor with its smallest spike over its planes (between spikes within
    :data:`SPIKE_TIE` of it, the smaller G). ``accel_from`` [m/s^2] the acceptance tests' reversal
    acceleration (:func:`reversal_acceleration`), where the characteristic starts. Returns the
    faster tests' reversal acceleration [m/s^2], where it ends."""
    axes = tuple(settings)
    accel_to = accel_from * ADAPT_FEED_FACTOR ** 2

    def adapted(s: ReversalSetting, factor: float) -> ReversalSetting:
        return replace(s, adapt_amplitude=s.amplitude * factor, adapt_from=accel_from, adapt_to=accel_to)

    trials: dict[str, list[tuple[float, float, float]]] = {a: [] for a in axes}  # (spike, G, factor)
    for factor in ADAPT_FACTORS:
        overrides = dict(base)
        for s in settings.values():
            overrides.update(adapted(s, factor).overrides())
        figures = axis_figures(overrides, scenarios=scenarios, planes=planes, feed_factor=ADAPT_FEED_FACTOR)
        for axis in axes:
            trials[axis].append((figures[axis].spike, figures[axis].circular, factor))
        report(f"adaptation x{factor:g}: " + ", ".join(f"{a} spike {figures[a].spike:.1f} um, G {figures[a].circular:.1f} um"
                                                      for a in axes))
    for axis in axes:
        smallest = min(spike for spike, _, _ in trials[axis])
        _, _, factor = min((g, -spike, f) for spike, g, f in trials[axis] if spike <= smallest + SPIKE_TIE)
        settings[axis] = adapted(settings[axis], factor)
    return accel_to


def describe(s: ReversalSetting) -> str:
    """One line: the setting in the scenario's units and, once measured, its spike."""
    o = s.overrides()
    a, t, lead, rise = (o[f"servo.{s.axis}.reversal_{k}"] for k in ("amplitude", "time", "lead", "rise"))
    backlash = o[f"axes.{s.axis}.compensation.backlash"] * 1e3
    unit = "deg/min" if AXES.index(s.axis) >= 3 else "mm/min"
    measured = "" if s.spike is None else f": spike {s.spike:.1f} um, G {s.circular:.1f} um"
    adapted = "" if not s.adapt_amplitude else (
        f", {o[f'servo.{s.axis}.reversal_adapt_amplitude']:.0f} {unit} from {o[f'servo.{s.axis}.reversal_adapt_to']:g} "
        f"{unit.split('/')[0]}/s^2")
    return (f"{a:.0f} {unit} / {t:.1f} ms / lead {lead:.1f} ms / rise {rise:.1f} ms{adapted}, "
            f"backlash {backlash:.1f} um{measured}")

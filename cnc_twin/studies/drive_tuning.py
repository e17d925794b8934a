"""Loops designed on an axis's measured mechanics, as drive commissioning designs them: the drive's
velocity loop (PI and notch filter), then the card's position loop on top of it, each with its
margins read from the measured response.

The plant is the frequency response H(f) measured on the nonlinear twin (force command -> motor
speed, :func:`~cnc_twin.studies.commissioning.measure_mechanics`). The controllers are known
exactly (the drive's PI and notches as :func:`~cnc_twin.studies.linearize.amplifier_ss` runs
them at the physics step; the card's PID at the servo period), so each loop is their product
with H, and what the machine does decides (its resonances, the current loop's lag, the delays),
not the linearised model::

    velocity loop    L_v = C_v N H F                     (C_v the PI, N the notches, F the drive's
                                                          speed filter on the actual speed)
    velocity closed  T_v = C_v N H / (1 + L_v)           (the motor's true speed per command)
    position loop    L_p = C_p cpu spv T_v dt z / (z - 1) (C_p the card's PID [V/count], cpu counts
                                                          per unit, spv the drive's speed per volt;
                                                          dt z / (z - 1): MuJoCo's semi-implicit
                                                          step from speed to position)

(the servo period equals the physics step here; :func:`position_open_loop` refuses otherwise).

Margins (:func:`loop_margins`) are taken over every crossing, as a measured response with a
resonance inside the loop's band crosses 0 dB and -180 deg more than once: the phase margin is
the least over the gain crossings, the gain margin the least over the phase crossings; only
frequencies where the measurement is coherent count.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnc_twin.core.config import AxisConfig, DriveConfig, Notch
from cnc_twin.machine.amplifier import AMP, notch_coefficients, speed_filter_alpha, torque_filter_beta
from cnc_twin.studies.commissioning import FrequencyResponse, resonances
from cnc_twin.studies.linearize import amplifier_ss, frequency_response, pid_controller, speed_filter_ss
from cnc_twin.studies.tuning import gain_grid

COHERENCE_MIN = 0.6
"""frequencies whose measured coherence is below this are left out of the margins"""
NOTCH_DEPTHS = (10.0, 20.0, 30.0)
"""[dB] notch depths tried at the measured resonance"""
NOTCH_WIDTHS = (0.25, 0.5)
"""notch -3 dB widths tried, as fractions of the resonance frequency"""
TN_CROSSOVERS = (4.0, 10.0)
"""integral times tried besides the drive's own: these multiples of 1 / omega_c, the proportional
loop's crossover (tn = 4 / omega_c: the integral's phase lag at the crossover is 14 deg)"""


@dataclass(frozen=True)
class Margins:
    """A loop's margins over all its crossings: ``gain_margin_db`` (inf without a phase
    crossing), ``phase_margin_deg``, ``crossover_hz`` (the highest gain crossing) and
    ``first_crossover_hz`` (the lowest: where the loop first falls below 0 dB, its bandwidth,
    about; a loop whose response peaks above 0 dB again at a resonance crosses higher too, which
    is no bandwidth)."""

    gain_margin_db: float
    phase_margin_deg: float
    crossover_hz: float
    first_crossover_hz: float = float("nan")


def loop_margins(loop: np.ndarray, frequency: np.ndarray, valid: np.ndarray | None = None,
                 reference: np.ndarray | None = None) -> Margins:
    """The :class:`Margins` of an open loop's response ``loop`` at ``frequency`` [Hz], using the
    points where ``valid`` (default: all). No gain crossing: phase margin and crossover nan; still
    above 0 dB at the last point: crossover inf (beyond the band).

    The phase is followed from the lowest frequency, where these loops lag by less than a turn:
    along ``reference`` (the same loop on the linear model's response: smooth, so its phase
    unwraps without doubt) plus the measured loop's angle from it, or, without one, along
    ``loop`` itself. A loop whose phase has passed -180 deg at a gain crossing has a negative
    margin there, though its wrapped angle looks like a positive one."""
    phase = followed_phase(loop, reference)
    if valid is not None:
        loop, frequency, phase = loop[valid], frequency[valid], phase[valid]
    mag = np.abs(loop)
    up = mag >= 1.0
    gain_x = np.flatnonzero(up[:-1] != up[1:])
    # at each gain crossing the loop is on the unit circle: its phase margin is its phase above -180 deg
    pm = [180.0 + phase[i] for i in gain_x]
    # a phase crossing of -180 deg (the imaginary part changes sign where the real part is
    # negative) inside the unit circle: how much more gain would reach -1 (crossings outside it
    # bound how much less gain the loop takes, a margin this tuner never spends)
    im = loop.imag
    phase_x = np.flatnonzero((np.sign(im[:-1]) != np.sign(im[1:])) & (loop.real[:-1] < 0.0)
                             & (np.maximum(mag[:-1], mag[1:]) < 1.0))
    gm = [-20.0 * np.log10(max(mag[i], mag[i + 1])) for i in phase_x]
    # a loop still above 0 dB at the band's end crosses beyond what was measured: unknown there
    crossover = float("inf") if up[-1] else float(frequency[gain_x[-1]]) if gain_x.size else float("nan")
    first = float(frequency[gain_x[0]]) if gain_x.size else crossover
    return Margins(gain_margin_db=float(min(gm)) if gm else float("inf"),
                   phase_margin_deg=float(min(pm)) if pm else float("nan"), crossover_hz=crossover,
                   first_crossover_hz=first)


Responses = FrequencyResponse | Sequence[FrequencyResponse]
"""one measured response, or one per place the axis was measured (its ends and mid travel): a loop
designed on several must keep its margins on each"""


def _all(fr: Responses) -> tuple[FrequencyResponse, ...]:
    return (fr,) if isinstance(fr, FrequencyResponse) else tuple(fr)


def worst(margins: Sequence[Margins]) -> Margins:
    """The least of each margin over ``margins`` (a loop on each of several measured responses),
    and the lowest crossover; nan where any is nan (a loop that does not cross somewhere)."""
    def least(values):
        values = list(values)
        return float("nan") if any(np.isnan(v) for v in values) else float(min(values))

    return Margins(gain_margin_db=least(m.gain_margin_db for m in margins),
                   phase_margin_deg=least(m.phase_margin_deg for m in margins),
                   crossover_hz=least(m.crossover_hz for m in margins),
                   first_crossover_hz=least(m.first_crossover_hz for m in margins))


def followed_phase(loop: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """An open loop's phase [deg] followed from its lowest frequency (a lag of less than a turn
    there): along ``reference`` (the same loop on the linear model, smooth) plus the loop's angle
    from it, or along ``loop`` itself (see :func:`loop_margins`)."""
    follow = loop if reference is None else reference
    phase = np.unwrap(np.angle(follow))
    phase -= 2.0 * np.pi * np.ceil(phase[0] / (2.0 * np.pi))  # a lag at the lowest frequency: (-360, 0] deg
    if reference is not None:
        phase = phase + np.angle(loop / reference)
    return np.degrees(phase)


def loops_on(fr: FrequencyResponse, loop_of) -> tuple[np.ndarray, np.ndarray | None]:
    """``(loop_of(fr.response), loop_of(fr.reference))``: an open loop through the measured
    response and the same loop through its linear-model reference (None without one).
    ``loop_of`` maps a mechanics response (shape ``(n,)`` at ``fr.frequency``) to the loop's, its
    controllers' responses evaluated once by the caller for both."""
    return loop_of(fr.response), None if fr.reference is None else loop_of(fr.reference)


def margins_on(fr: FrequencyResponse, loop_of, valid: np.ndarray | None = None) -> Margins:
    """:func:`loop_margins` of the loop through the measured response, its phase followed along
    the same loop through ``fr.reference`` where the measurement has one (:func:`loops_on`)."""
    loop, reference = loops_on(fr, loop_of)
    return loop_margins(loop, fr.frequency, valid, reference)


def _amp(kp: float, tn: float, notches: tuple[Notch, ...], dt: float, torque_filter: float = 0.0) -> np.void:
    a = np.zeros(1, AMP)[0]
    a["modelled"] = True
    a["beta"] = torque_filter_beta(torque_filter, dt)
    a["kp"], a["ki_dt"] = kp, kp * dt / tn if tn > 0.0 else 0.0
    a["n_notches"] = len(notches)
    for n, notch in enumerate(notches):
        a["notch"][n] = notch_coefficients(notch.frequency, notch.width, notch.depth, dt)
    return a


def velocity_open_loop(fr: FrequencyResponse, kp: float, tn: float, notches: tuple[Notch, ...],
                       dt: float, speed_filter: float = 0.0, torque_filter: float = 0.0) -> np.ndarray:
    """L_v at ``fr.frequency``: the drive's PI (``kp`` [N/(m/s) | N m/(rad/s) at the axis], ``tn``
    [s]), its torque filter (``torque_filter`` [s], 0: none) and ``notches`` at the physics step
    ``dt`` [s], times the measured mechanics, read through the drive's ``speed_filter`` [Hz] (0: none)."""
    return _controller(fr, kp, tn, notches, dt, torque_filter) * fr.response * _feedback(fr, dt, speed_filter)


def _velocity_margins(frs, feedback, valid, kp, tn, notches, dt, torque_filter) -> Margins:
    """The :func:`worst` margins of L_v over the measured responses ``frs``, each place's speed
    filter (``feedback``) and valid band already evaluated (the same for every loop a design
    tries); the drive's side evaluated once per place for the response and its reference."""
    out = []
    for one, fb, ok in zip(frs, feedback, valid):
        drive_side = _controller(one, kp, tn, notches, dt, torque_filter) * fb
        out.append(margins_on(one, lambda h: drive_side * h, ok))
    return worst(out)


def _controller(fr, kp, tn, notches, dt, torque_filter: float) -> np.ndarray:
    """The drive's PI, torque filter and notches at ``fr.frequency``: speed error -> force command."""
    return frequency_response(amplifier_ss(_amp(kp, tn, notches, dt, torque_filter)), 2.0 * np.pi * fr.frequency, dt)


def _feedback(fr, dt, speed_filter) -> np.ndarray:
    """The drive's speed filter at ``fr.frequency``: the motor's speed -> the actual speed."""
    return frequency_response(speed_filter_ss(speed_filter_alpha(speed_filter, dt)), 2.0 * np.pi * fr.frequency, dt)


LOWEST_BINS = 5
"""a measured response counts from this many of its frequency steps up (2.5 Hz for 2 s Welch
segments): below, a segment's slow trends (the load changing along the sweep, friction) leak
into the estimate"""


def valid_band(fr: FrequencyResponse, dt: float, hold: int = 2) -> np.ndarray:
    """Where the measurement counts: coherent, from :data:`LOWEST_BINS` frequency steps (and at
    least 1 Hz) up, below the PRBS's band (1 / (2 hold dt))."""
    lowest = max(1.0, LOWEST_BINS * float(fr.frequency[1] - fr.frequency[0]))
    return (fr.coherence >= COHERENCE_MIN) & (fr.frequency >= lowest) & (fr.frequency <= 1.0 / (2.0 * hold * dt))


@dataclass(frozen=True)
class VelocityLoop:
    """A drive's velocity loop (axis units) with its margins on the measured response."""

    kp: float
    """[N/(m/s) | N m/(rad/s) at the axis]"""
    tn: float
    """[s]"""
    notches: tuple[Notch, ...]
    margins: Margins
    speed_filter: float = 0.0
    """[Hz] the drive's filter on the actual speed the loop reads (0: none): the drive's, not tuned"""
    torque_filter: float = 0.0
    """[s] the drive's torque reference filter's time constant (0: none): the drive's, not tuned"""


CURRENT_LOOP_SHARE = 1 / 3
"""a velocity loop's crossover stays below this share of the current loop's bandwidth (the
commissioning rule of thumb: the inner loop three to five times faster)"""


def notch_settings(frs: Responses) -> list[tuple[Notch, ...]]:
    """The notch settings a velocity-loop design tries: none, or one centred on the measured
    resonance (between the lowest and the highest where several responses were measured: the
    geometric mean) at each of :data:`NOTCH_DEPTHS`, its width each of :data:`NOTCH_WIDTHS` of
    the centre and, where the resonance moves along the travel, wide enough for the whole spread
    (1.5 x the highest less the lowest)."""
    found = [resonances(fr).resonance_hz for fr in _all(frs)]
    centre = float(np.sqrt(min(found) * max(found)))
    widths = [width * centre for width in NOTCH_WIDTHS]
    spread = 1.5 * (max(found) - min(found))
    if spread > max(widths):
        widths.append(spread)
    return [()] + [(Notch(centre, width, depth),) for depth in NOTCH_DEPTHS for width in widths]


def propose_velocity_loop(fr: Responses, drive: DriveConfig, dt: float, *, phase_margin: float = 45.0,
                          gain_margin: float = 8.0) -> VelocityLoop:
    """The velocity loop with the highest (first) crossover meeting both margins on the measured response (on
    each of several: their :func:`worst`), every crossing below :data:`CURRENT_LOOP_SHARE` of the
    current loop's bandwidth: kp on a log grid (1/30 to 30 times the drive's), tn the drive's or
    from each kp's proportional crossover (:data:`TN_CROSSOVERS`), with no notch or one at the
    measured resonance (:func:`notch_settings`); at equal crossover the one with fewer and
    shallower notches. ValueError when none meets the margins."""
    frs = _all(fr)
    valid = [valid_band(one, dt) for one in frs]
    highest = CURRENT_LOOP_SHARE * drive.current_bandwidth
    feedback = [_feedback(one, dt, drive.speed_filter) for one in frs]

    def margins(kp, tn, notches):
        return _velocity_margins(frs, feedback, valid, kp, tn, notches, dt, drive.torque_filter)

    best: VelocityLoop | None = None
    for kp in np.logspace(np.log10(drive.kp / 30.0), np.log10(drive.kp * 30.0), 61):
        for notches in notch_settings(frs):
            proportional = margins(kp, 0.0, notches)
            if not np.isfinite(proportional.first_crossover_hz):
                continue
            for tn in (drive.tn, *(c / (2.0 * np.pi * proportional.first_crossover_hz) for c in TN_CROSSOVERS)):
                m = margins(kp, tn, notches)
                if not (m.phase_margin_deg >= phase_margin and m.gain_margin_db >= gain_margin
                        and m.crossover_hz <= highest):
                    continue
                if best is None or m.first_crossover_hz > best.margins.first_crossover_hz * (1.0 + 1e-9):
                    best = VelocityLoop(float(kp), float(tn), notches, m, drive.speed_filter, drive.torque_filter)
    if best is None:
        raise ValueError(f"no velocity loop on the grid meets {phase_margin:g} deg / {gain_margin:g} dB "
                         "on the measured response")
    return best


def velocity_closed_loop(fr: FrequencyResponse, loop: VelocityLoop, dt: float) -> np.ndarray:
    """T_v: the motor's true speed per commanded speed, at ``fr.frequency``."""
    return _closed_velocity(fr, loop, dt)(fr.response)


def _closed_velocity(fr: FrequencyResponse, loop: VelocityLoop, dt: float):
    """T_v as a function of a mechanics response at ``fr.frequency`` (the drive's controller and
    speed filter evaluated once)."""
    controller = _controller(fr, loop.kp, loop.tn, loop.notches, dt, loop.torque_filter)
    feedback = _feedback(fr, dt, loop.speed_filter)

    def closed(h: np.ndarray) -> np.ndarray:
        forward = controller * h
        return forward / (1.0 + forward * feedback)

    return closed


def _position_plants(fr: FrequencyResponse, velocity: VelocityLoop, cfg: AxisConfig, servo_period: float,
                     dt: float) -> tuple[np.ndarray, np.ndarray | None]:
    """What the card's PID multiplies into L_p at ``fr.frequency``: the drive's closed velocity loop
    times the speed per volt, the counts per unit and MuJoCo's step from speed to position, on the
    measured response and on its reference (:func:`loops_on`); the same for every gain the card
    tries."""
    if not np.isclose(servo_period, dt):
        raise ValueError("the position loop on the measured response needs the servo period equal to the physics step")
    z = np.exp(2j * np.pi * fr.frequency * dt)
    closed = _closed_velocity(fr, velocity, dt)
    scale = cfg.counts_per_unit * cfg.drive.speed_per_volt * dt * z / (z - 1.0)
    return loops_on(fr, lambda h: scale * closed(h))


def _card(fr: FrequencyResponse, cfg: AxisConfig, servo_period: float, gains: dict) -> np.ndarray:
    """The card's PID [V/count] (``cfg``'s gains, or ``gains``) at ``fr.frequency``."""
    return frequency_response(pid_controller(cfg, servo_period, **gains), 2.0 * np.pi * fr.frequency, servo_period)


def position_open_loop(fr: FrequencyResponse, velocity: VelocityLoop, cfg: AxisConfig, servo_period: float,
                       dt: float, **gains: float) -> np.ndarray:
    """L_p at ``fr.frequency`` (see the module docstring): the card's PID (``cfg``'s gains, or
    ``gains``: kp, ki, kd) on the measured mechanics inside ``velocity``."""
    return _card(fr, cfg, servo_period, gains) * _position_plants(fr, velocity, cfg, servo_period, dt)[0]


def position_open_loops(fr: Responses, velocity: VelocityLoop, cfg: AxisConfig, servo_period: float, dt: float,
                        **gains: float) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """L_p on each measured response and on its reference (:func:`loops_on`), the card's gains
    ``cfg``'s or ``gains``."""
    out = []
    for one in _all(fr):
        card = _card(one, cfg, servo_period, gains)
        plant, reference = _position_plants(one, velocity, cfg, servo_period, dt)
        out.append((card * plant, None if reference is None else card * reference))
    return out


@dataclass(frozen=True)
class PositionLoop:
    kp: float
    """[1/s]"""
    ki: float
    """[1/s^2]"""
    margins: Margins


def position_margins(fr: Responses, velocity: VelocityLoop, cfg: AxisConfig, servo_period: float, dt: float,
                     **gains: float) -> Margins:
    """The position loop's margins on the measured response (on each of several: their
    :func:`worst`), the card's gains ``cfg``'s or ``gains`` (kp, ki, kd)."""
    frs = _all(fr)
    plants = [_position_plants(one, velocity, cfg, servo_period, dt) for one in frs]
    return _position_margins(frs, plants, cfg, servo_period, dt, gains)


def _position_margins(frs, plants, cfg: AxisConfig, servo_period: float, dt: float, gains: dict) -> Margins:
    """:func:`position_margins` with each place's :func:`_position_plants` already evaluated."""
    out = []
    for one, (plant, reference) in zip(frs, plants):
        card = _card(one, cfg, servo_period, gains)
        out.append(loop_margins(card * plant, one.frequency, valid_band(one, dt),
                                None if reference is None else card * reference))
    return worst(out)


POSITION_LOOP_SHARE = 1 / 4
"""a position loop's crossover stays below this share of its velocity loop's (the servo manuals'
rule of thumb in the machine-dynamics reference: position-loop bandwidth < velocity-loop bandwidth / 4)"""


def position_candidates(fr: Responses, velocity: VelocityLoop, cfg: AxisConfig, servo_period: float,
                        dt: float, *, phase_margin: float = 40.0, gain_margin: float = 6.0,
                        kp_range: tuple[float, float] = (5.0, 400.0)) -> list[PositionLoop]:
    """Every card (kp, ki) on the tuner's grid (``cnc_twin.studies.tuning.gain_grid``) meeting
    both margins on the measured response (on each of several), its (first) crossover below
    :data:`POSITION_LOOP_SHARE` of ``velocity``'s, highest crossover first."""
    highest = POSITION_LOOP_SHARE * velocity.margins.first_crossover_hz
    frs = _all(fr)
    plants = [_position_plants(one, velocity, cfg, servo_period, dt) for one in frs]  # the same for every gain
    out = []
    for kp, ki in gain_grid(kp_range):
        m = _position_margins(frs, plants, cfg, servo_period, dt, {"kp": kp, "ki": ki, "kd": 0.0})
        if m.phase_margin_deg >= phase_margin and m.gain_margin_db >= gain_margin and m.first_crossover_hz <= highest:
            out.append(PositionLoop(float(kp), float(ki), m))
    return sorted(out, key=lambda p: -p.margins.first_crossover_hz)


def current_velocity_loop(fr: Responses, drive: DriveConfig, dt: float) -> VelocityLoop:
    """The drive's own velocity loop, with its margins on the measured response (the worst over several)."""
    frs = _all(fr)
    m = _velocity_margins(frs, [_feedback(one, dt, drive.speed_filter) for one in frs],
                          [valid_band(one, dt) for one in frs], drive.kp, drive.tn, drive.notches, dt,
                          drive.torque_filter)
    return VelocityLoop(drive.kp, drive.tn, drive.notches, m, drive.speed_filter, drive.torque_filter)


def choose_velocity_loop(fr: Responses, drive: DriveConfig, dt: float, *, phase_margin: float = 40.0,
                         gain_margin: float = 6.0) -> tuple[VelocityLoop, VelocityLoop]:
    """``(current, chosen)``: the drive's own velocity loop and the one to use, the
    :func:`propose_velocity_loop` one when the current misses a margin or the proposal crosses
    over at least 5 % higher; else the current one (the same object)."""
    current = current_velocity_loop(fr, drive, dt)
    m = current.margins
    meets = m.phase_margin_deg >= phase_margin and m.gain_margin_db >= gain_margin and np.isfinite(m.first_crossover_hz)
    try:
        proposed = propose_velocity_loop(fr, drive, dt, phase_margin=phase_margin, gain_margin=gain_margin)
    except ValueError:
        if meets:
            return current, current
        raise ValueError(f"the drive's velocity loop has {m.phase_margin_deg:.1f} deg / {m.gain_margin_db:.1f} dB on "
                         f"the measured response and no loop on the grid meets {phase_margin:g} deg / "
                         f"{gain_margin:g} dB") from None
    if meets and not proposed.margins.first_crossover_hz > 1.05 * m.first_crossover_hz:
        return current, current
    return current, proposed


def drive_settings(loop: VelocityLoop, drive: DriveConfig) -> dict:
    """``loop`` as the parameter file's ``drive`` keys, in motor terms (kp_speed [N m s/rad], tn_speed
    [ms], notch_filters)."""
    return {"kp_speed": float(f"{loop.kp / drive.motor_per_axis ** 2:.4g}"), "tn_speed": float(f"{loop.tn * 1e3:.4g}"),
            "notch_filters": [{"frequency": float(f"{n.frequency:.4g}"), "width": float(f"{n.width:.4g}"),
                               "depth": float(f"{n.depth:.4g}")} for n in loop.notches]}


def format_velocity_loops(axis: str, current: VelocityLoop, chosen: VelocityLoop, drive: DriveConfig) -> str:
    """The velocity loops' table: the drive's and (when it differs) the proposed, with their margins
    on the measured response."""
    lines = [f"axis {axis} velocity loop (the drive's, on the measured response):",
             f"{'':18}{'kp_speed':>10}{'tn [ms]':>9}{'PM [deg]':>10}{'GM [dB]':>9}{'fc [Hz]':>9}  notch filters"]
    rows = [("before", current)] + ([("proposed", chosen)] if chosen is not current else [])
    for name, loop in rows:
        d = drive_settings(loop, drive)
        notches = ", ".join(f"{n['frequency']:g} Hz / {n['width']:g} Hz wide / {n['depth']:g} dB"
                            for n in d["notch_filters"]) or "none"
        m = loop.margins
        lines.append(f"{name:<18}{d['kp_speed']:>10.4g}{d['tn_speed']:>9.3g}{m.phase_margin_deg:>10.1f}"
                     f"{m.gain_margin_db:>9.1f}{m.first_crossover_hz:>9.1f}  {notches}")
    if chosen is current:
        lines.append("keeping the drive's velocity loop: it meets the margins and no loop on the grid crosses over "
                     "5 % higher")
    return "\n".join(lines)

"""One axis of the validated scenario in SI: its limits, encoder, card gains and, where the
machine's parameter file gives them, its drive's own loops. Part of :mod:`cnc_twin.core.config`'s
interface (imported from there)."""

from __future__ import annotations

from dataclasses import dataclass

from cnc_twin.core import units


@dataclass(frozen=True)
class Notch:
    """A notch filter on a drive's torque command."""

    frequency: float
    """centre [Hz]"""
    width: float
    """-3 dB width [Hz]"""
    depth: float
    """attenuation at the centre [dB], > 0"""


@dataclass(frozen=True)
class DriveConfig:
    """A servo amplifier with loops of its own (:mod:`cnc_twin.machine.amplifier`), in axis units:
    the analog command is a speed, closed by a PI on the motor's speed, its torque command
    notch-filtered and limited, the current loop a lag."""

    speed_per_volt: float
    """the analog input's scaling [m/s/V | rad/s/V at the axis]"""
    kp: float
    """velocity-loop gain [N/(m/s) | N m/(rad/s) at the axis]"""
    tn: float
    """velocity-loop integral time [s]; 0 = P only"""
    current_bandwidth: float
    """the current loop's bandwidth [Hz] (a first-order lag)"""
    force_limit: float
    """peak force [N] or torque [N m] at the axis"""
    notches: tuple[Notch, ...] = ()
    """on the torque command, in order"""
    motor_per_axis: float = 1.0
    """motor rad per axis m | rad (2 pi gear / lead; the ratio): converts back to motor terms"""
    speed_filter: float = 0.0
    """the actual speed's first-order low-pass [Hz] (the drive's velocity-feedback bandwidth); 0:
    the loop reads the motor's exact speed"""
    feedback_counts: int = 0
    """the drive's motor feedback, counts per motor revolution: its speed is the difference of
    these counts over a step; 0: not quantised"""
    torque_filter: float = 0.0
    """the torque command's first-order low-pass time constant [s], before the notches (a drive's
    torque reference filter); 0: none"""


COMP_MAX_POINTS = 256
"""the longest pitch-error table a card holds (LinuxCNC's limit too)"""


@dataclass(frozen=True)
class Compensation:
    """The card's leadscrew compensation of an axis (:mod:`cnc_twin.dsp.compensation`), in
    machine coordinates: a pitch-error table (LinuxCNC's COMP_FILE, empty: none) and backlash."""

    nominal: tuple[float, ...] = ()
    """the table's nominal positions [m | rad], increasing"""
    forward: tuple[float, ...] = ()
    """trim (nominal - position reached) going up at each [m | rad]"""
    reverse: tuple[float, ...] = ()
    """trim going down [m | rad]"""
    backlash: float = 0.0
    """[m | rad]"""
    slew: float = 0.01
    """the fastest the correction changes [m/s | rad/s]"""


@dataclass(frozen=True)
class AxisConfig:
    """One axis in SI. Positions in m (linear) or rad (rotary)."""

    name: str
    rotary: bool
    max_velocity: float
    """[m/s | rad/s]"""
    max_acceleration: float
    """[m/s^2 | rad/s^2]"""
    max_jerk: float
    """[m/s^3 | rad/s^3]"""
    counts_per_unit: float
    """encoder counts per m or per rad (4 x lines x gear / lead)"""
    kp: float
    """[1/s]"""
    ki: float
    """[1/s^2]"""
    kd: float
    """[-]"""
    kvff: float
    """[-]"""
    kaff: float
    """[s]"""
    output_limit: float
    """[V]"""
    integrator_limit: float
    """[V]"""
    travel: tuple[float, float] | None
    """hard travel from the MJCF [m | rad]; None when unlimited"""
    speed_per_volt: float
    """drive scaling read from the MJCF [m/s/V | rad/s/V]"""
    pulse_max_rate: float = 500e3
    """pulse output: highest step rate of the card's generator and the drive input [pulses/s]"""
    drive_position_gain: float = 80.0
    """pulse output: the amplifier's position-loop gain in position mode [1/s]"""
    drive_velocity_ff: float = 1.0
    """pulse output: the amplifier's velocity feed-forward [-]"""
    drive_ff_filter: float = 1e-3
    """pulse output: time constant of the amplifier's feed-forward filter [s]"""
    friction_ff: float = 0.0
    """friction feed-forward [V] with the sign of the commanded speed; 0 = off"""
    friction_ff_band: float = 1e-3
    """commanded speed over which the friction feed-forward ramps from 0 to full [m/s | rad/s]"""
    aff_washout: float = 0.0
    """the acceleration feed-forward's high-pass time constant [s] (the drive's speed-loop integral
    time, whose integral takes over a lasting acceleration); 0 = no high-pass"""
    ff_equivalent_time: float = 0.0
    """the speed loop's equivalent time constant [s]: the position loop compares the actual
    position with the command through a first-order lag of this time (feed-forward symmetrised);
    0 = off"""
    deflection: tuple[float, ...] = ()
    """the tool tip's deflection along this axis per unit commanded acceleration of each axis, in
    ``AXES`` order (X Y Z A B C) [s^2 = m per m/s^2, mixed units for rotary axes]; the card
    commands the axis that much less (an acceleration-dependent position correction); () = none"""
    coupling: tuple[float, ...] = ()
    """the inertia coupling to each axis, in ``AXES`` order (X Y Z A B C): the mass
    matrix's off-diagonal over the axis's own inertia [SI units of this axis's acceleration per
    the other's]; the acceleration feed-forward adds ``coupling_j a_j``; () = none"""
    reversal_amplitude: float = 0.0
    """reversal compensation: the speed pulse added when the commanded velocity changes sign
    [m/s | rad/s]; 0 = off (:mod:`cnc_twin.dsp.reversal`)"""
    reversal_time: float = 0.0
    """reversal compensation: the pulse's decay time constant [s]; 0 = off"""
    reversal_lead: float = 0.0
    """reversal compensation: how long before the commanded velocity's zero (predicted from the
    commanded acceleration) the pulse starts [s]"""
    reversal_rise: float = 0.0
    """reversal compensation: the pulse's rise time constant [s] (a first-order low-pass on it);
    0 = a step"""
    reversal_min_speed: float = 0.0
    """reversal compensation: the commanded speed a move must reach for its reversal to count
    [m/s | rad/s]; 0 = any"""
    reversal_standstill: float = 0.0
    """reversal compensation: the share of the pulse given at a stop (against the motion) and at
    the start after it (with it) [-]; 0 = none"""
    reversal_start_speed: float = 0.0
    """reversal compensation: the commanded speed a start's pulse waits for [m/s | rad/s]"""
    reversal_stop_speed: float = 0.0
    """reversal compensation: the commanded speed under which a decelerating axis gets a stop's
    pulse [m/s | rad/s]"""
    reversal_adapt_amplitude: float = 0.0
    """reversal compensation's adaptation: the pulse at the acceleration ``reversal_adapt_to``
    [m/s | rad/s]; 0 = the same pulse at every acceleration"""
    reversal_adapt_from: float = 0.0
    reversal_adapt_to: float = 0.0
    """the accelerations between which the pulse goes from ``reversal_amplitude`` to
    ``reversal_adapt_amplitude`` [m/s^2 | rad/s^2]"""
    index_period: float = 0.0
    """distance between the encoder's index pulses (one motor revolution) [m | rad]; 0 = none"""
    index_offset: float = 0.0
    """position of one index pulse [m | rad]"""
    following_error_limit: float = 0.0
    """the supervisor's following-error limit [m | rad]; 0 = not checked"""
    soft_limits: tuple[float, float] | None = None
    """the supervisor's soft limits [m | rad]; None = the hard travel only"""
    encoder_mount: str = "motor"
    """where the encoder reads the machine: ``motor`` (semi-closed loop) or ``table`` (a linear
    scale, or a rotary axis's output: full-closed loop); one and the same on a rigid machine"""
    drive: DriveConfig | None = None
    """the amplifier's own loops where the machine's parameter file gives them (a current-mode
    drive in the MJCF); None: the MJCF's velocity-mode drive (an ideal velocity source)"""
    compensation: Compensation | None = None
    """the card's pitch-error table and backlash compensation; None: none"""

    @property
    def allowed(self) -> tuple[float, float] | None:
        """Where programs may go [m | rad]: the soft limits if set, else the travel (None: anywhere)."""
        return self.soft_limits if self.soft_limits is not None else self.travel

    @property
    def allowed_name(self) -> str:
        """What :attr:`allowed` is called in messages: ``soft limits`` or ``travel``."""
        return "soft limits" if self.soft_limits is not None else "travel"

    @property
    def display_factor(self) -> float:
        """Scenario units (mm or deg) per SI unit."""
        return 1.0 / units.position_factor(self.rotary)

    @property
    def display_unit(self) -> str:
        return units.position_unit(self.rotary)

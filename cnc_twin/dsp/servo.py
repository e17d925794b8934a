"""The DSP servo task: every block of the card wired in one explicit, ordered place.

Per interpolation period (``begin_period``), from the coarse interpolator's setpoint
``p_next`` [counts]::

    v = (p_next - p_prev) / T_ipo          # chord velocity [counts/s], feed-forward
    a = (v - v_prev) / T_ipo               # [counts/s^2], feed-forward

Per servo tick ``j`` of ``n`` in the period (``tick``), for each axis::

    command  = p_prev + (p_next - p_prev) * (j + 1) / n     # linear fine interpolation
    actual   = QEP.sample(position)                          # encoder, counts
    volts    = PID+FF(command, actual, v, a)
    volts    = DAC.write(volts)                              # 12-bit, saturation counted
    force    = ADC.convert(load cell) - tare                 # [N], tare taken on the first tick

A step interpolator (point-by-point, DDA) hands its own lattice point for every tick instead of
the linear fine interpolation (``begin_period(setpoint, ticks)``).

Pulse output (``tick_pulses``): no PID and no DAC; each axis's step generator
(:mod:`cnc_twin.dsp.step_output`) emits the pulses that bring its count to the command, and
the amplifiers, in position mode, close the loop (:mod:`cnc_twin.machine.drive`). The card still reads
its encoders, for the following error it reports.

Drives disabled (a supervisor stop, :mod:`cnc_twin.dsp.supervisor`): ``tick_disabled`` only
reads the encoders; the command follows the actual position (follow-up) and the DAC writes 0 V.

The tick fills ``frame`` (a flat list: command x6, actual x6, DAC code x6, force, then the
per-period fields of ``PERIOD_FIELDS`` that the period task writes) for the recorder, so nothing
is allocated per tick besides the returned voltages.
"""

from __future__ import annotations

from collections.abc import Sequence

from cnc_twin.dsp.adc import Adc
from cnc_twin.dsp.dac import Dac12
from cnc_twin.dsp.encoder import QuadratureEncoder
from cnc_twin.dsp.pid import PidFF
from cnc_twin.dsp.step_output import StepGenerator
from cnc_twin.core.config import AxisConfig, ForceSensorConfig, Timing

FRAME_FIELDS = ("command", "actual", "dac")
"""per-axis groups in :attr:`ServoTask.frame`, each 6 wide, followed by one force value"""
PERIOD_FIELDS = ("state", "fault", "fifo_fill", "feed_override", "missed_exchanges", "records_rejected",
                 "last_seq_executed", "path_u", "path_ds", "force_state", "force_setpoint", "force_depth",
                 "feed_factor", "mark", "events")
"""per-period values after the force in :attr:`ServoTask.frame`, written once per period"""


class ServoTask:
    """The card's servo interrupt and its per-period setpoint latch.

    Parameters
    ----------
    axes : the six axes in order (SI configuration).
    timing : the scenario's rates.
    power_on : axis positions when the card powered up [m | rad]; encoders count from here.
    force_sensor : load-cell ADC configuration.
    output : ``analog`` (PID + DAC per axis, :meth:`tick`) or ``pulse`` (step generators,
        :meth:`tick_pulses`; the ``dac`` slots of ``frame`` then hold the pulses of the tick).
    """

    def __init__(
        self,
        axes: Sequence[AxisConfig],
        *,
        timing: Timing,
        power_on: Sequence[float],
        force_sensor: ForceSensorConfig,
        output: str = "analog",
    ):
        self.n_axes = len(axes)
        self.ticks_per_period = timing.ticks_per_period
        self._inv_period = 1.0 / timing.interpolation_period
        self.encoders = [
            QuadratureEncoder(cfg.counts_per_unit, position_at_power_on=p0) for cfg, p0 in zip(axes, power_on)
        ]
        self.loops = [
            PidFF(
                kp=cfg.kp, ki=cfg.ki, kd=cfg.kd, kvff=cfg.kvff, kaff=cfg.kaff,
                friction_ff=cfg.friction_ff, friction_ff_band=cfg.friction_ff_band,
                speed_per_volt=cfg.speed_per_volt, counts_per_unit=cfg.counts_per_unit,
                dt=timing.servo_period, output_limit=cfg.output_limit, integrator_limit=cfg.integrator_limit,
            )
            for cfg in axes
        ]
        self.dacs = [Dac12() for _ in axes]
        self.force_adc = Adc(force_sensor.range_min, force_sensor.range_max, bits=force_sensor.bits)
        self._force_tare: float | None = None
        self.force_fault = 0.0
        """force added to the load cell's reading by an injected fault [N] (0 normally)"""
        n = self.n_axes
        self._p_prev = [0.0] * n
        self._p_next = [0.0] * n
        self._velocity = [0.0] * n
        self._acceleration = [0.0] * n
        self._fractions = [(j + 1) / self.ticks_per_period for j in range(self.ticks_per_period)]
        # command floats, actual and DAC codes ints (as the encoders and DACs produce them)
        self.frame = [0.0] * n + [0] * (2 * n) + [0.0] * (1 + len(PERIOD_FIELDS))
        self.period_slot = len(FRAME_FIELDS) * n + 1
        """index in ``frame`` of the first per-period field"""
        self._channels = list(zip(range(n), self.encoders, self.loops, self.dacs))
        self.steppers = [StepGenerator(cfg.pulse_max_rate, timing.servo_period) for cfg in axes] \
            if output == "pulse" else []
        self._pulse_channels = list(zip(range(n), self.encoders, self.steppers))
        self._tick_commands: list[list[float]] | None = None

    def begin_period(self, setpoint: Sequence[float], ticks: list[list[float]] | None = None) -> None:
        """Latch the next period's end setpoint [counts] and derive the feed-forward terms.

        ``ticks`` (optional, one command per tick, each shape ``(6,)`` [counts]) replaces the
        linear fine interpolation for this period: a step interpolator's own lattice points.
        """
        self._tick_commands = ticks
        inv_t = self._inv_period
        self._p_prev = self._p_next
        self._p_next = list(setpoint)
        velocity = [(b - a) * inv_t for a, b in zip(self._p_prev, self._p_next)]
        self._acceleration = [(v - v0) * inv_t for v, v0 in zip(velocity, self._velocity)]
        self._velocity = velocity

    def tick(self, j: int, positions: Sequence[float], pad_force: float) -> list[float]:
        """One servo interrupt, tick ``j`` of the period.

        Parameters
        ----------
        positions : true axis positions [m | rad], shape ``(6,)``.
        pad_force : load-cell force [N].

        Returns
        -------
        Drive voltages as output by the DACs [V], shape ``(6,)``.
        """
        frac = self._fractions[j]
        p_prev, p_next, vel, acc = self._p_prev, self._p_next, self._velocity, self._acceleration
        frame = self.frame
        n = self.n_axes
        volts = [0.0] * n
        ticks = self._tick_commands
        for i, encoder, loop, dac in self._channels:
            command = p_prev[i] + (p_next[i] - p_prev[i]) * frac if ticks is None else ticks[j][i]
            actual = encoder.sample(positions[i])
            volts[i] = dac.write(loop.update(command, actual, vel[i], acc[i]))
            frame[i] = command
            frame[n + i] = actual
            frame[2 * n + i] = dac.code
        self._read_force(pad_force)
        return volts

    def tick_pulses(self, j: int, positions: Sequence[float], pad_force: float) -> list[int]:
        """One servo interrupt in pulse output: the step pulses per axis for tick ``j`` (signed)."""
        frac = self._fractions[j]
        p_prev, p_next = self._p_prev, self._p_next
        frame = self.frame
        n = self.n_axes
        pulses = [0] * n
        ticks = self._tick_commands
        for i, encoder, stepper in self._pulse_channels:
            command = p_prev[i] + (p_next[i] - p_prev[i]) * frac if ticks is None else ticks[j][i]
            pulses[i] = stepper.emit(command)
            frame[i] = command
            frame[n + i] = encoder.sample(positions[i])
            frame[2 * n + i] = pulses[i]
        self._read_force(pad_force)
        return pulses

    def tick_disabled(self, j: int, positions: Sequence[float], pad_force: float) -> list[float]:
        """One servo interrupt with the drives disabled: follow-up, 0 V out (shape ``(6,)``)."""
        frame = self.frame
        n = self.n_axes
        for i, encoder in enumerate(self.encoders):
            actual = encoder.sample(positions[i])
            frame[i] = float(actual)
            frame[n + i] = actual
            frame[2 * n + i] = 0
        self._read_force(pad_force)
        return [0.0] * n

    def disable(self) -> None:
        """Drives off: the DACs write 0 (code 0) and the position loops forget their state."""
        for dac in self.dacs:
            dac.write(0.0)
        for loop in self.loops:
            loop.reset()

    def replace_encoder(self, axis: int, encoder) -> None:
        """Put ``encoder`` (anything with ``sample(position) -> counts``) on ``axis``'s channel."""
        self.encoders[axis] = encoder
        self._rewire()

    def replace_dac(self, axis: int, dac) -> None:
        """Put ``dac`` (``write``, ``code``, ``saturations`` as :class:`Dac12`) on ``axis``'s channel."""
        self.dacs[axis] = dac
        self._rewire()

    def _rewire(self) -> None:
        n = self.n_axes
        self._channels = list(zip(range(n), self.encoders, self.loops, self.dacs))
        self._pulse_channels = list(zip(range(n), self.encoders, self.steppers))

    def _read_force(self, pad_force: float) -> None:
        measured = self.force_adc.convert(pad_force + self.force_fault)
        if self._force_tare is None:
            self._force_tare = measured
        self.frame[3 * self.n_axes] = measured - self._force_tare

    @property
    def pulse_limited_ticks(self) -> list[int]:
        """Ticks each step generator spent at its rate limit, per axis (pulse output)."""
        return [s.limited_ticks for s in self.steppers]

    @property
    def dac_saturations(self) -> list[int]:
        """Ticks each DAC channel spent clamped, per axis."""
        return [dac.saturations for dac in self.dacs]

"""The DSP servo task: every block of the card wired in one explicit, ordered place.

Per interpolation period (``begin_period``), from the coarse interpolator's setpoint
``p_next`` [counts]::

    v = (p_next - p_prev) / T_ipo          # chord velocity [counts/s], feed-forward
    a = (v - v_prev) / T_ipo               # [counts/s^2], the reversal compensation's prediction
    j = (a - a_prev) / T_ipo               # [counts/s^3], the same
    a_ff = a - the force loop's push's     # [counts/s^2], feed-forward and deflection correction

Per servo tick ``j`` of ``n`` in the period (``tick``, :func:`servo_tick`), for each axis::

    command  = p_prev + (p_next - p_prev) * (j + 1) / n     # linear fine interpolation
    actual   = qep_sample(qep, position, encoder_fault)      # encoder, counts
    command += comp_correction(...) - sum_j deflection_j a_ff_j  # backlash, pitch; the tip's deflection
    volts    = pid_update(pid, command, actual, v, a_ff + sum_j coupling_j a_ff_j)  # PID+FF
    volts   += reversal_pulse(reversal, v, a, j, path_on)    # quadrant error compensation (path_on: another
                                                             # axis moves at its arming speed; not for a
                                                             # step interpolator's commands)
    volts    = dac_write(dac, volts)                         # 12-bit, saturation counted
    force    = adc_convert(load cell + fault) - tare         # [N], tare taken on the first tick

Each block's state is a record (:data:`AXIS` holds one axis's QEP, PID and DAC records and its
setpoint latch; :data:`LOAD_CELL` the ADC's); every function here and in the blocks' modules is
one plain function compiled with numba, called by the methods below once per tick and by the
compiled kernels (:mod:`cnc_twin.run.servo_kernel`, :mod:`cnc_twin.run.period_kernel`) on the
same records.

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

from collections.abc import Callable, Sequence

import numpy as np
from numba import njit

from cnc_twin.core.axes import N_AXES
from cnc_twin.core.config import AxisConfig, ForceSensorConfig, Timing
from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.dsp import adc, compensation, dac, encoder, pid, reversal
from cnc_twin.dsp.adc import ADC, adc_convert, setup_adc
from cnc_twin.dsp.compensation import COMP, MAX_POINTS, TABLE_ROWS, comp_correction, setup_comp
from cnc_twin.dsp.dac import DAC, dac_write, setup_dac
from cnc_twin.dsp.frame import FRAME_FIELDS, PERIOD_FIELDS
from cnc_twin.dsp.encoder import QEP, qep_sample, setup_encoder
from cnc_twin.dsp.pid import PID, pid_reset, pid_update, setup_pid
from cnc_twin.dsp.reversal import REVERSAL, forget_reversal, is_moving, reversal_pulse, setup_reversal
from cnc_twin.dsp.step_output import StepGenerator

# the functions below call the blocks' functions: recompile them when those change
purge_stale(__file__, [encoder.__file__, pid.__file__, dac.__file__, adc.__file__, compensation.__file__,
                       reversal.__file__])

AXIS = np.dtype([("qep", QEP), ("pid", PID), ("dac", DAC), ("p_prev", np.float64), ("p_next", np.float64),
                 ("velocity", np.float64), ("acceleration", np.float64), ("jerk", np.float64),
                 ("push", np.float64), ("push_velocity", np.float64), ("ff_acceleration", np.float64),
                 ("encoder_fault", np.int64),
                 ("comp", COMP), ("reversal", REVERSAL), ("deflection", np.float64, (N_AXES,)),
                 ("coupling", np.float64, (N_AXES,))])
"""One axis's servo channel, the record the servo functions work on:

===============  =================  ===========================================  =========================
field            unit               meaning                                      written by
===============  =================  ===========================================  =========================
qep              :data:`.QEP`       the encoder channel                          :func:`.qep_sample`
pid              :data:`.PID`       the position loop                            :func:`.pid_update`
dac              :data:`.DAC`       the analog output                            :func:`.dac_write`
p_prev           counts             the setpoint at the period's start           :func:`latch_setpoint`
p_next           counts             the setpoint at the period's end             :func:`latch_setpoint`
velocity         counts/s           chord velocity, feed-forward                 :func:`latch_setpoint`
acceleration     counts/s^2         its change, feed-forward                     :func:`latch_setpoint`
jerk             counts/s^3         the acceleration's change                    :func:`latch_setpoint`
push             counts             the force loop's push in the setpoint (the   :func:`latch_setpoint`
                                    setpoint less the path)
push_velocity    counts/s           its chord velocity                           :func:`latch_setpoint`
ff_acceleration  counts/s^2         the acceleration less the push's: what the   :func:`latch_setpoint`
                                    feed-forward and the deflection correction
                                    work on
encoder_fault    counts             added to the reading by injected faults      the fault injector
comp             :data:`.COMP`      backlash and the pitch-error table's state   :func:`.comp_correction`
reversal         :data:`.REVERSAL`  the reversal compensation's pulse            :func:`.reversal_pulse`
deflection       counts per         the tip's deflection along this axis per     :class:`ServoTask`
                 counts/s^2,        commanded acceleration of each axis
                 shape ``(6,)``     (:func:`deflection_correction`)
coupling         counts/s^2 per     the inertia coupling to each axis: the       :class:`ServoTask`
                 counts/s^2,        acceleration feed-forward's share of its
                 shape ``(6,)``     acceleration (:func:`coupled_acceleration`)
===============  =================  ===========================================  =========================
"""

LOAD_CELL = np.dtype([("adc", ADC), ("tare", np.float64), ("tare_set", np.int64), ("fault", np.float64)])
"""The load cell's channel: its :data:`~cnc_twin.dsp.adc.ADC`, the tare [N] taken on the first
tick (``tare_set`` 1 once taken; :func:`read_load_cell`) and the force an injected fault adds to
the cell's reading [N] (``fault``, written by the fault injector; 0 normally)."""


PUSHED_AXES = 3
"""the axes the force loop's push is in (X Y Z: along the tool axis); C's setpoint differs from the
path by the spindle's turn, a motion"""


@njit(cache=True)
def latch_setpoint(axes, setpoint, path, inv_period):
    """Latch the period's end setpoint [counts] (shape ``(n,)``) into ``axes`` (:data:`AXIS`,
    shape ``(n,)``) and derive the feed-forward terms; ``inv_period`` is 1 / T_ipo [1/s].

    ``path`` [counts] (shape ``(n,)``) is the interpolator's path, the setpoint without the force
    loop's push along the tool axis: the push is the setpoint less the path on
    :data:`PUSHED_AXES`, and the acceleration feed-forward and the deflection correction work on
    the setpoint's acceleration less the push's (``ff_acceleration``). The push is a correction the
    card adds to the path, its second difference the loop's noise: fed forward (Z's kaff through its
    high-pass) or turned into a position correction (Z's deflection) it set the bundled force
    programs' Z oscillating at about 3 Hz, their force error from 0.5 - 0.8 % to 21 - 33 %. Where
    the push starts or ends (0 before or after, the standoff on the other side: the setpoint goes
    on smoothly, the push steps) its step is no motion: the push's rate starts again from there.
    """
    for i in range(axes.shape[0]):
        a = axes[i]
        a.p_prev = a.p_next
        a.p_next = setpoint[i]
        velocity = (a.p_next - a.p_prev) * inv_period
        acceleration = (velocity - a.velocity) * inv_period
        a.jerk = (acceleration - a.acceleration) * inv_period
        a.acceleration = acceleration
        a.velocity = velocity
        push = setpoint[i] - path[i] if i < PUSHED_AXES else 0.0
        if (push == 0.0) != (a.push == 0.0):  # it starts or ends: a step, not a motion
            push_velocity = 0.0
            a.push_velocity = 0.0
        else:
            push_velocity = (push - a.push) * inv_period
        a.ff_acceleration = acceleration - (push_velocity - a.push_velocity) * inv_period
        a.push_velocity = push_velocity
        a.push = push


@njit(cache=True)
def fine_command(a, fraction, tick_command, use_tick_command):
    """One axis's command this tick [counts]: the linear fine interpolation of ``a`` (an
    :data:`AXIS` record) at ``fraction`` of the period, or ``tick_command`` with ``use_tick_command``."""
    if use_tick_command:
        return tick_command
    return a.p_prev + (a.p_next - a.p_prev) * fraction


@njit(cache=True)
def fine_commands(axes, fraction, tick_command, use_tick_command, command_out):
    """:func:`fine_command` of every axis into ``command_out`` (shape ``(n,)``; pulse output)."""
    for i in range(axes.shape[0]):
        command_out[i] = fine_command(axes[i], fraction, tick_command[i], use_tick_command)


@njit(cache=True)
def weighted_acceleration(axes, weights, start):
    """``start + sum_j weights[j] a_j`` [counts/s^2 x the weights' unit] over the axes'
    ``ff_acceleration`` (:func:`latch_setpoint`), summed in that order; ``weights`` shape ``(n,)``:
    an axis's deflection or coupling."""
    total = start
    for j in range(axes.shape[0]):
        total += weights[j] * axes[j].ff_acceleration
    return total


@njit(cache=True)
def deflection_correction(axes, i):
    """Axis ``i``'s correction [counts] for its tip's acceleration-dependent deflection: the
    opposite of ``sum_j deflection[j] a_j`` over the axes' commanded accelerations ``a_j``
    [counts/s^2] without the force loop's push (``ff_acceleration``, :func:`latch_setpoint`).
    No rate of it goes to the velocity feed-forward: that would be the jerk, the setpoints' third
    difference (the term took the flat plate's force error from 0.51 to 36 %); the position loop
    takes the correction's slow changes."""
    return -weighted_acceleration(axes, axes[i].deflection, 0.0)


@njit(cache=True)
def coupled_acceleration(axes, i):
    """The acceleration [counts/s^2] axis ``i``'s acceleration feed-forward works on: its own
    commanded acceleration plus ``coupling[j] a_j`` of the others (``ff_acceleration``: without the
    force loop's push, :func:`latch_setpoint`; the mass matrix's off-diagonal
    over the axis's inertia: the force another axis's acceleration puts on this axis's drive,
    which the feed-forward then supplies, as it supplies the axis's own)."""
    return weighted_acceleration(axes, axes[i].coupling, axes[i].ff_acceleration)


@njit(cache=True)
def servo_tick(axes, comp_tables, fraction, tick_command, use_tick_command, positions, command_out, actual_out,
               code_out, volts_out):
    """One servo interrupt for every axis of ``axes`` (:data:`AXIS`, shape ``(n,)``; their pitch-error
    tables ``comp_tables``, shape ``(n, TABLE_ROWS, MAX_POINTS)``): the fine
    interpolation at ``fraction`` of the period (or ``tick_command`` [counts], shape ``(n,)``,
    with ``use_tick_command``), QEP at ``positions`` [m | rad], the leadscrew compensation's
    correction added to the command (:func:`~cnc_twin.dsp.compensation.comp_correction`) and the
    tip's deflection's (:func:`deflection_correction`, not under a step interpolator's commands),
    PID+FF, the reversal compensation's pulse (:func:`~cnc_twin.dsp.reversal.reversal_pulse`;
    none under a step interpolator's commands, whose older cards had none and whose staircase
    would read as reversals), DAC. Writes the command [counts] (without the correction), the
    reading [counts], the DAC code and the output voltage [V] per axis into the ``*_out`` arrays
    (shape ``(n,)`` each)."""
    n = axes.shape[0]
    moving = 0  # axes at their reversal compensation's arming speed: a path goes on (module docstring)
    for i in range(n):
        if is_moving(axes[i].reversal, axes[i].velocity):
            moving += 1
    for i in range(n):
        a = axes[i]
        command = fine_command(a, fraction, tick_command[i], use_tick_command)
        actual = qep_sample(a.qep, positions[i], a.encoder_fault)
        corrected = command + comp_correction(a.comp, comp_tables[i], command, a.velocity)
        if not use_tick_command:
            corrected += deflection_correction(axes, i)
        volts = pid_update(a.pid, corrected, actual, a.velocity, coupled_acceleration(axes, i))
        if use_tick_command:
            forget_reversal(a.reversal)
        else:
            others = moving - (1 if is_moving(a.reversal, a.velocity) else 0)
            volts += reversal_pulse(a.reversal, a.velocity, a.acceleration, a.jerk, others > 0)
        volts_out[i] = dac_write(a.dac, volts)
        command_out[i] = command
        actual_out[i] = actual
        code_out[i] = a.dac.code


@njit(cache=True)
def read_encoders(axes, positions, actual_out):
    """Only the QEP of every axis (drives off, pulse output, a hung task's counters): the
    readings [counts] into ``actual_out`` (shape ``(n,)``)."""
    for i in range(axes.shape[0]):
        a = axes[i]
        actual_out[i] = qep_sample(a.qep, positions[i], a.encoder_fault)


@njit(cache=True)
def disable_axes(axes):
    """Drives off: every DAC writes 0 V (code 0), every position loop forgets its state and
    every reversal pulse ends."""
    for i in range(axes.shape[0]):
        a = axes[i]
        dac_write(a.dac, 0.0)
        pid_reset(a.pid)
        a.reversal.pulse = 0.0
        a.reversal.output = 0.0


@njit(cache=True)
def read_load_cell(cell, value):
    """The load cell ``value`` [N] (plus the injected ``cell.fault``) through the ADC, less the
    tare taken on the first reading [N]."""
    measured = adc_convert(cell.adc, value + cell.fault)
    if cell.tare_set == 0:
        cell.tare = measured
        cell.tare_set = 1
    return measured - cell.tare


TASK_FUNCTIONS = (latch_setpoint, servo_tick, fine_commands, read_encoders, read_load_cell, disable_axes)
"""the compiled functions :class:`ServoTask` calls from Python (:meth:`ServoTask.warm_up`)"""


class ServoTask:
    """The card's servo interrupt and its per-period setpoint latch.

    The state lives in :attr:`axes` (:data:`AXIS`, one record per axis) and :attr:`load_cell`
    (:data:`LOAD_CELL`, shape ``(1,)``); the methods call the compiled block functions on them,
    and the compiled kernels (:mod:`cnc_twin.run.servo_kernel`) work on the same records.

    Parameters
    ----------
    axes
        the six axes in order (SI configuration).
    timing
        the scenario's rates.
    power_on
        axis positions when the card powered up [m | rad]; encoders count from here.
    force_sensor
        load-cell ADC configuration.
    output
        ``analog`` (PID + DAC per axis, :meth:`tick`) or ``pulse`` (step generators,
        :meth:`tick_pulses`; the ``dac`` slots of ``frame`` then hold the pulses of the tick).
    reversal_compensation
        whether the axes' reversal compensation is set up as configured (False: off, whatever the
        configuration says; the older cards' program kinds had none).
    """

    def __init__(
        self,
        axes: Sequence[AxisConfig],
        *,
        timing: Timing,
        power_on: Sequence[float],
        force_sensor: ForceSensorConfig,
        output: str = "analog",
        reversal_compensation: bool = True,
    ):
        n = self.n_axes = len(axes)
        self.ticks_per_period = timing.ticks_per_period
        self.inv_period = 1.0 / timing.interpolation_period
        """1 / the interpolation period [1/s]"""
        self.axes = np.zeros(n, AXIS)
        """the servo channels, one :data:`AXIS` record per axis, shape ``(n,)``"""
        self.comp_tables = np.zeros((n, TABLE_ROWS, MAX_POINTS))
        """each axis's pitch-error table [counts] (:func:`~cnc_twin.dsp.compensation.setup_comp`)"""
        for i, (cfg, p0) in enumerate(zip(axes, power_on)):
            channel = self.axes[i]
            setup_encoder(channel["qep"], cfg.counts_per_unit, p0)
            setup_pid(channel["pid"], kp=cfg.kp, ki=cfg.ki, kd=cfg.kd, kvff=cfg.kvff, kaff=cfg.kaff,
                      aff_washout=cfg.aff_washout, ff_equivalent_time=cfg.ff_equivalent_time,
                      friction_ff=cfg.friction_ff, friction_ff_band=cfg.friction_ff_band,
                      speed_per_volt=cfg.speed_per_volt, counts_per_unit=cfg.counts_per_unit,
                      dt=timing.servo_period, output_limit=cfg.output_limit, integrator_limit=cfg.integrator_limit)
            setup_dac(channel["dac"])
            for field in ("deflection", "coupling"):  # SI ([s^2], -) -> counts per counts/s^2 of each axis
                for j, value in enumerate(getattr(cfg, field)):
                    channel[field][j] = value * cfg.counts_per_unit / axes[j].counts_per_unit
            setup_reversal(channel["reversal"], amplitude=cfg.reversal_amplitude if reversal_compensation else 0.0,
                           time=cfg.reversal_time,
                           speed_per_volt=cfg.speed_per_volt, dt=timing.servo_period, lead=cfg.reversal_lead,
                           rise=cfg.reversal_rise, arm_speed=cfg.reversal_min_speed, counts_per_unit=cfg.counts_per_unit,
                           standstill=cfg.reversal_standstill, start_speed=cfg.reversal_start_speed,
                           stop_speed=cfg.reversal_stop_speed, adapt_amplitude=cfg.reversal_adapt_amplitude,
                           adapt_from=cfg.reversal_adapt_from, adapt_to=cfg.reversal_adapt_to)
            comp = cfg.compensation
            if comp is not None:  # machine coordinates [m | rad] -> the card's counts from power-on
                cpu = cfg.counts_per_unit
                setup_comp(channel["comp"], self.comp_tables[i], nominal=(np.asarray(comp.nominal) - p0) * cpu,
                           forward=np.asarray(comp.forward) * cpu, reverse=np.asarray(comp.reverse) * cpu,
                           backlash=comp.backlash * cpu, step=comp.slew * cpu * timing.servo_period)
        self.load_cell = np.zeros(1, LOAD_CELL)
        """the load cell's :data:`LOAD_CELL` record, shape ``(1,)``"""
        setup_adc(self.load_cell[0]["adc"], force_sensor.range_min, force_sensor.range_max, bits=force_sensor.bits)
        self.fractions = np.array([(j + 1) / self.ticks_per_period for j in range(self.ticks_per_period)])
        """the fine interpolation's fraction of the period at each tick, shape ``(ticks_per_period,)``"""
        self.tick_commands = np.zeros((self.ticks_per_period, n))
        """a step interpolator's command per tick [counts], shape ``(ticks_per_period, n)``, used
        while :attr:`use_tick_commands`"""
        self.use_tick_commands = False
        """this period's ticks take :attr:`tick_commands` instead of the fine interpolation"""
        self.fault_hook: Callable[[], None] | None = None
        """called before every servo tick's encoder reading while an injected fault changes the
        readings per tick (encoder noise): it writes ``axes["encoder_fault"]``"""
        # command floats, actual and DAC codes ints (as the encoders and DACs produce them)
        self.frame = [0.0] * n + [0] * (2 * n) + [0.0] * (1 + len(PERIOD_FIELDS))
        """the recorder's frame, filled by every tick: command, actual and DAC code per axis,
        the force, then the per-period fields (:data:`~cnc_twin.dsp.frame.PERIOD_FIELDS`)"""
        self.period_slot = len(FRAME_FIELDS) * n + 1
        """index in ``frame`` of the first per-period field"""
        self._command, self._volts = np.zeros(n), np.zeros(n)
        self._actual, self._code = np.zeros(n, np.int64), np.zeros(n, np.int64)
        self.steppers = [StepGenerator(cfg.pulse_max_rate, timing.servo_period) for cfg in axes] \
            if output == "pulse" else []

    @property
    def force_fault(self) -> float:
        """Force added to the load cell's reading by an injected fault [N] (0 normally)."""
        return float(self.load_cell[0]["fault"])

    @force_fault.setter
    def force_fault(self, value: float) -> None:
        self.load_cell[0]["fault"] = value

    def begin_period(self, setpoint: Sequence[float], ticks: list[list[float]] | None = None,
                     path: Sequence[float] | None = None) -> None:
        """Latch the next period's end setpoint [counts] and derive the feed-forward terms.

        ``ticks`` (optional, one command per tick, each shape ``(6,)`` [counts]) replaces the
        linear fine interpolation for this period: a step interpolator's own lattice points.
        ``path`` [counts]: the setpoint without the force loop's push (None: the setpoint).
        """
        if ticks is None:
            self.use_tick_commands = False
        else:
            self.tick_commands[:] = ticks
            self.use_tick_commands = True
        latched = np.asarray(setpoint, dtype=np.float64)
        latch_setpoint(self.axes, latched, latched if path is None else np.asarray(path, dtype=np.float64),
                       self.inv_period)

    def tick(self, j: int, positions: Sequence[float], pad_force: float) -> np.ndarray:
        """One servo interrupt, tick ``j`` of the period.

        Parameters
        ----------
        positions
            the encoders' positions [m | rad], shape ``(6,)`` (an array:
            :meth:`~cnc_twin.machine.plant.Plant.encoder_positions`).
        pad_force
            load-cell force [N].

        Returns
        -------
        Drive voltages as output by the DACs [V], shape ``(6,)`` (overwritten by the next tick).
        """
        if self.fault_hook is not None:
            self.fault_hook()
        servo_tick(self.axes, self.comp_tables, self.fractions[j], self.tick_commands[j], self.use_tick_commands,
                   positions, self._command, self._actual, self._code, self._volts)
        n, frame = self.n_axes, self.frame
        frame[0:n] = self._command.tolist()
        frame[n:2 * n] = self._actual.tolist()
        frame[2 * n:3 * n] = self._code.tolist()
        frame[3 * n] = read_load_cell(self.load_cell[0], pad_force)
        return self._volts

    def tick_pulses(self, j: int, positions: Sequence[float], pad_force: float) -> list[int]:
        """One servo interrupt in pulse output: the step pulses per axis for tick ``j`` (signed)."""
        frame, n = self.frame, self.n_axes
        self.read_encoders(positions)
        fine_commands(self.axes, self.fractions[j], self.tick_commands[j], self.use_tick_commands, self._command)
        pulses = [0] * n
        for i, (stepper, command) in enumerate(zip(self.steppers, self._command.tolist())):
            a = self.axes[i]
            pulses[i] = stepper.emit(command + comp_correction(a["comp"], self.comp_tables[i], command, a["velocity"]))
            frame[i] = command
            frame[2 * n + i] = pulses[i]
        frame[3 * n] = read_load_cell(self.load_cell[0], pad_force)
        return pulses

    def tick_disabled(self, j: int, positions: Sequence[float], pad_force: float) -> list[float]:
        """One servo interrupt with the drives disabled: follow-up, 0 V out (shape ``(6,)``)."""
        frame, n = self.frame, self.n_axes
        actual = self.read_encoders(positions)
        frame[0:n] = [float(x) for x in actual]
        frame[2 * n:3 * n] = [0] * n
        frame[3 * n] = read_load_cell(self.load_cell[0], pad_force)
        return [0.0] * n

    def read_encoders(self, positions: Sequence[float]) -> list[int]:
        """Sample every encoder at ``positions`` [m | rad] (no loop runs): the readings [counts],
        also into ``frame``'s actual slots."""
        if self.fault_hook is not None:
            self.fault_hook()
        read_encoders(self.axes, positions, self._actual)
        actual = self._actual.tolist()
        n = self.n_axes
        self.frame[n:2 * n] = actual
        return actual

    def disable(self) -> None:
        """Drives off: the DACs write 0 (code 0) and the position loops forget their state."""
        disable_axes(self.axes)

    def warm_up(self) -> None:
        """Compile the functions the methods call (or load them from numba's cache) now, not in
        the timed run: each called once on copies of the records, with the run's argument types."""
        n, axes, cell = self.n_axes, self.axes.copy(), self.load_cell.copy()
        latch_setpoint(axes, np.zeros(n), np.zeros(n), self.inv_period)
        servo_tick(axes, self.comp_tables.copy(), self.fractions[0], self.tick_commands[0], False, np.zeros(n),
                   self._command.copy(), self._actual.copy(), self._code.copy(), self._volts.copy())
        read_encoders(axes, np.zeros(n), self._actual.copy())
        # the pulse output's too, whatever this run's output: a run of either kind finds all cached
        fine_commands(axes, self.fractions[0], self.tick_commands[0], False, self._command.copy())
        comp_correction(axes[0]["comp"], self.comp_tables[0].copy(), 0.0, 0.0)
        read_load_cell(cell[0], 0.0)
        disable_axes(axes)

    def frame_from(self, command: np.ndarray, force: float) -> None:
        """``frame`` as a tick leaves it, after a compiled tick that wrote the records but not the
        frame: the tick's ``command`` [counts] (shape ``(n,)``) and load-cell ``force`` [N]; the
        readings and DAC codes from :attr:`axes`."""
        n, frame, axes = self.n_axes, self.frame, self.axes
        frame[0:n] = command.tolist()
        frame[n:3 * n] = axes["qep"]["position32"].tolist() + axes["dac"]["code"].tolist()
        frame[3 * n] = float(force)

    @property
    def pulse_limited_ticks(self) -> list[int]:
        """Ticks each step generator spent at its rate limit, per axis (pulse output)."""
        return [s.limited_ticks for s in self.steppers]

    @property
    def dac_saturations(self) -> list[int]:
        """Ticks each DAC channel spent clamped, per axis."""
        return self.axes["dac"]["saturations"].tolist()

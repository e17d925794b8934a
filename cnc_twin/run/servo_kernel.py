"""The servo interrupt and the physics between interrupts, compiled: one call per period.

:class:`~cnc_twin.dsp.servo.ServoTask` (with :mod:`encoder`, :mod:`pid`, :mod:`dac`, :mod:`adc`)
is the reference: plain Python, one method call per block per tick. This module runs the same
arithmetic in a numba kernel that also calls MuJoCo's C ``mj_step`` itself and writes the
recorder's rows, so one interpolation period (``ticks_per_period`` ticks of encoder -> PID+FF ->
DAC -> drives -> physics -> record) costs one Python call instead of about a hundred. The two
agree bit for bit (``tests/test_servo_kernel.py``): the same IEEE operations in the same order,
no fast-math, the same ``mj_step``.

Per tick ``j`` of the period, for each axis ``i`` (as :meth:`ServoTask.tick`)::

    command = p_prev + (p_next - p_prev) * fraction[j]      (or the step interpolator's point)
    counter16 = (floor(qpos[i] * cpu) - zero_edges) & 0xFFFF; position32 += signed 16-bit delta
    volts = DAC(PID+FF(command, position32, v, a)); ctrl[i] = volts
    force = ADC(-sensordata[force_adr] + force_fault) - tare
    mj_step x substeps; record command, position32, DAC code, force at row t + j

Used for analog output with the drives enabled and no injected card faults; the twin falls back
to the reference path otherwise, handing the state over (:meth:`CompiledServo.store` /
:meth:`CompiledServo.load`). The state lives in small arrays while the kernel owns it.

MuJoCo is reached through :mod:`cnc_twin.machine.mujoco_c`; :func:`available` says whether it can be.
"""

from __future__ import annotations

import math

import numpy as np

from cnc_twin.machine import mujoco_c
from cnc_twin.core.kernel_cache import purge_stale

# rows of the per-axis parameter matrix (float64, shape (N_FPARAMS, 6))
CPU, KP, KI_DT, KD_OVER_DT, KVFF, KAFF, OUT_LIMIT, INT_LIMIT, CODES_PER_VOLT, VOLTS_PER_CODE, FRICTION_FF, \
    FRICTION_RATE = range(12)
N_FPARAMS = 12
# rows of the per-axis float state (float64, shape (N_FSTATE, 6))
P_PREV, P_NEXT, VELOCITY, ACCELERATION, INTEGRATOR, PREV_ERROR = range(6)
N_FSTATE = 6
# rows of the per-axis integer state (int64, shape (N_ISTATE, 6))
ZERO_EDGES, COUNTER16, POSITION32, DAC_CODE, SATURATIONS = range(5)
N_ISTATE = 5
# the scalar block (float64): ADC range_min, lsb, code_max, tare, tare taken (0/1), force fault
RANGE_MIN, LSB, CODE_MAX, TARE, TARE_SET, FORCE_FAULT = range(6)
N_SCALARS = 6

_DAC_MIN, _DAC_MAX = -2048, 2047
_INT32_HALF = 1 << 31


def available() -> bool:
    """Whether the compiled servo can run here (numba, and MuJoCo's shared library)."""
    return mujoco_c.available()


# the kernel calls MuJoCo through mujoco_c's bindings: recompile when they change
purge_stale(__file__, [mujoco_c.__file__])

if mujoco_c.IMPORT_ERROR is None:
    from numba import njit

    _mj_step = mujoco_c.mj_step

    @njit(cache=True, nogil=True)
    def run_ticks(model_ptr, data_ptr, substeps, fparams, fstate, istate, scalars, fractions, tick_commands,
                    use_tick_commands, qpos, ctrl, sensordata, force_adr, rec_command, rec_actual, rec_dac,
                    rec_force, t0):  # pragma: no cover - compiled; its Python twin is ServoTask.tick
        """Run ``len(fractions)`` servo ticks from recorder row ``t0``; returns DAC saturations added."""
        n_axes = fstate.shape[1]
        saturated = 0
        for j in range(fractions.shape[0]):
            frac = fractions[j]
            row = t0 + j
            for i in range(n_axes):
                if use_tick_commands:
                    command = tick_commands[j, i]
                else:
                    command = fstate[P_PREV, i] + (fstate[P_NEXT, i] - fstate[P_PREV, i]) * frac
                # QEP (encoder.py): 16-bit counter, extended to 32 bits
                counter16 = (np.int64(math.floor(qpos[i] * fparams[CPU, i])) - istate[ZERO_EDGES, i]) & 0xFFFF
                position32 = istate[POSITION32, i] + (((counter16 - istate[COUNTER16, i] + 0x8000) & 0xFFFF) - 0x8000)
                if position32 >= _INT32_HALF or position32 < -_INT32_HALF:
                    position32 = ((position32 + _INT32_HALF) % (2 * _INT32_HALF)) - _INT32_HALF
                istate[COUNTER16, i] = counter16
                istate[POSITION32, i] = position32
                # PID + feed-forward (pid.py), same operations in the same order
                error = command - position32
                ramp = fstate[VELOCITY, i] * fparams[FRICTION_RATE, i]
                if ramp > 1.0:
                    ramp = 1.0
                elif ramp < -1.0:
                    ramp = -1.0
                fixed = (fparams[KP, i] * error
                         + fparams[KD_OVER_DT, i] * (error - fstate[PREV_ERROR, i])
                         + fparams[KVFF, i] * fstate[VELOCITY, i]
                         + fparams[KAFF, i] * fstate[ACCELERATION, i]
                         + fparams[FRICTION_FF, i] * ramp)
                fstate[PREV_ERROR, i] = error
                limit = fparams[INT_LIMIT, i]
                integrator = fstate[INTEGRATOR, i] + fparams[KI_DT, i] * error
                if integrator > limit:
                    integrator = limit
                elif integrator < -limit:
                    integrator = -limit
                out = fixed + integrator
                umax = fparams[OUT_LIMIT, i]
                if out > umax:
                    if error <= 0.0:
                        fstate[INTEGRATOR, i] = integrator
                    out = fixed + fstate[INTEGRATOR, i]
                    if out > umax:
                        out = umax
                elif out < -umax:
                    if error >= 0.0:
                        fstate[INTEGRATOR, i] = integrator
                    out = fixed + fstate[INTEGRATOR, i]
                    if out < -umax:
                        out = -umax
                else:
                    fstate[INTEGRATOR, i] = integrator
                # 12-bit DAC (dac.py)
                code = np.int64(math.floor(out * fparams[CODES_PER_VOLT, i] + 0.5))
                if code > _DAC_MAX:
                    code = _DAC_MAX
                    istate[SATURATIONS, i] += 1
                    saturated += 1
                elif code < _DAC_MIN:
                    code = _DAC_MIN
                    istate[SATURATIONS, i] += 1
                    saturated += 1
                istate[DAC_CODE, i] = code
                ctrl[i] = code * fparams[VOLTS_PER_CODE, i]
                rec_command[row, i] = command
                rec_actual[row, i] = position32
                rec_dac[row, i] = code
            # load cell through the ADC (adc.py), tared on the first tick
            value = -sensordata[force_adr] + scalars[FORCE_FAULT]
            adc = math.floor((value - scalars[RANGE_MIN]) / scalars[LSB] + 0.5)
            if adc < 0:
                adc = 0.0
            elif adc > scalars[CODE_MAX]:
                adc = scalars[CODE_MAX]
            measured = scalars[RANGE_MIN] + adc * scalars[LSB]
            if scalars[TARE_SET] == 0.0:
                scalars[TARE] = measured
                scalars[TARE_SET] = 1.0
            rec_force[row] = measured - scalars[TARE]
            for _ in range(substeps):
                _mj_step(model_ptr, data_ptr)
        return saturated


class CompiledServo:
    """The compiled servo period for one :class:`ServoTask` on one plant.

    Parameters
    ----------
    servo : the reference servo task (analog output); its gains and converters are copied once.
    plant : the :class:`~cnc_twin.machine.plant.Plant` it drives.
    substeps : physics steps per servo tick.
    """

    def __init__(self, servo, plant, *, substeps: int):
        if not available():
            raise RuntimeError(f"compiled servo unavailable: {mujoco_c.IMPORT_ERROR or 'mujoco has no _address'}")
        self.servo = servo
        self.substeps = substeps
        n = servo.n_axes
        self.fparams = np.zeros((N_FPARAMS, n))
        for i, (encoder, loop, dac) in enumerate(zip(servo.encoders, servo.loops, servo.dacs)):
            self.fparams[:, i] = (encoder.counts_per_unit, loop.kp, loop.ki_dt, loop.kd_over_dt, loop.kvff,
                                  loop.kaff, loop.output_limit, loop.integrator_limit, dac._codes_per_volt,
                                  dac._volts_per_code, loop.friction_ff, loop.friction_rate)
        self.fstate = np.zeros((N_FSTATE, n))
        self.istate = np.zeros((N_ISTATE, n), dtype=np.int64)
        self.istate[ZERO_EDGES] = [e._zero_edges for e in servo.encoders]
        adc = servo.force_adc
        self.scalars = np.array([adc.range_min, adc.lsb, float(adc._code_max), 0.0, 0.0, 0.0])
        self.fractions = np.array(servo._fractions)
        self.tick_commands = np.zeros((servo.ticks_per_period, n))
        self.owns_state = False
        """True while the arrays, not the servo's objects, hold the loop state"""
        self._model_ptr = plant.model._address
        self._data_ptr = plant.data._address
        self._args_plant = (plant.data.qpos, plant.data.ctrl, plant.data.sensordata, plant.force_sensor_adr)

    def warm_up(self) -> None:
        """Compile the kernel (or load it from numba's cache: 0.4 s in a fresh process) now, not
        inside the timed run: a call of zero ticks with arguments of the types the run passes.
        ``Twin.run`` calls it while the planner process starts."""
        n = self.servo.n_axes
        qpos, ctrl, sensordata, force_adr = self._args_plant
        run_ticks(self._model_ptr, self._data_ptr, self.substeps, self.fparams, self.fstate.copy(),
                    self.istate.copy(), self.scalars.copy(), self.fractions[:0], self.tick_commands, False, qpos,
                    ctrl, sensordata, force_adr, np.zeros((1, n)), np.zeros((1, n), dtype=np.int32),
                    np.zeros((1, n), dtype=np.int16), np.zeros(1), 0)

    def load(self) -> None:
        """Take the loop state from the servo's objects, unless the kernel holds it already
        (before every compiled period)."""
        if self.owns_state:
            return
        servo = self.servo
        for i, (encoder, loop, dac) in enumerate(zip(servo.encoders, servo.loops, servo.dacs)):
            self.istate[COUNTER16, i] = encoder.counter16
            self.istate[POSITION32, i] = encoder.position32
            self.istate[DAC_CODE, i] = dac.code
            self.istate[SATURATIONS, i] = dac.saturations
            self.fstate[INTEGRATOR, i] = loop.integrator
            self.fstate[PREV_ERROR, i] = loop.previous_error
        tare = servo._force_tare
        self.scalars[TARE], self.scalars[TARE_SET] = (0.0, 0.0) if tare is None else (tare, 1.0)
        self.owns_state = True

    def store(self) -> None:
        """Hand the loop state back to the servo's objects, if the kernel holds it (before a
        reference-path period, and at the end of the run)."""
        if not self.owns_state:
            return
        servo = self.servo
        counter16, position32, codes, saturations = (self.istate[r].tolist() for r in
                                                     (COUNTER16, POSITION32, DAC_CODE, SATURATIONS))
        integrators, previous = self.fstate[INTEGRATOR].tolist(), self.fstate[PREV_ERROR].tolist()
        for i, (encoder, loop, dac) in enumerate(zip(servo.encoders, servo.loops, servo.dacs)):
            encoder.counter16, encoder.position32 = counter16[i], position32[i]
            dac.code, dac.saturations = codes[i], saturations[i]
            loop.integrator, loop.previous_error = integrators[i], previous[i]
        servo._force_tare = self.scalars[TARE] if self.scalars[TARE_SET] else None
        self.owns_state = False

    def run_period(self, recorder, t: int) -> None:
        """One interpolation period from recorder row ``t``: the servo ticks, the physics, the
        rows. Afterwards the servo's ``frame`` holds the last tick's signals, as the reference
        path leaves it. The servo's setpoint must be latched (``ServoTask.begin_period``)."""
        self.take_setpoint()
        ticks = self.servo._tick_commands
        if ticks is not None:
            self.tick_commands[:] = ticks
        qpos, ctrl, sensordata, force_adr = self._args_plant
        saturated = run_ticks(self._model_ptr, self._data_ptr, self.substeps, self.fparams, self.fstate,
                                self.istate, self.scalars, self.fractions, self.tick_commands, ticks is not None, qpos,
                                ctrl, sensordata, force_adr, recorder.command, recorder.actual, recorder.dac,
                                recorder.pad_force, recorder.row(t))
        self.leave_frame(recorder, recorder.row(t) + len(self.fractions) - 1, saturated=bool(saturated))

    def take_setpoint(self) -> None:
        """The setpoint and feed-forward terms the servo latched (``ServoTask.begin_period``),
        and its injected force fault, into the kernel's arrays."""
        servo, fstate = self.servo, self.fstate
        fstate[P_PREV] = servo._p_prev
        fstate[P_NEXT] = servo._p_next
        fstate[VELOCITY] = servo._velocity
        fstate[ACCELERATION] = servo._acceleration
        self.scalars[FORCE_FAULT] = servo.force_fault

    def leave_frame(self, recorder, last: int, *, saturated: bool) -> None:
        """The servo's ``frame`` from recorder row ``last`` (the last tick run), as the reference
        path leaves it; with ``saturated``, the DACs' saturation counts too (the supervisor reads
        them)."""
        servo = self.servo
        n = servo.n_axes
        frame = servo.frame
        frame[0:n] = recorder.command[last].tolist()
        frame[n:3 * n] = self.istate[POSITION32].tolist() + self.istate[DAC_CODE].tolist()
        frame[3 * n] = float(recorder.pad_force[last])
        if saturated:
            for dac, count in zip(servo.dacs, self.istate[SATURATIONS].tolist()):
                dac.saturations = count

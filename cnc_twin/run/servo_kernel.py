"""The servo interrupt and the physics between interrupts, compiled: one call per period.

:class:`~cnc_twin.dsp.servo.ServoTask` keeps the servo's state in records and runs one tick per
call of :func:`~cnc_twin.dsp.servo.servo_tick`. This module calls that same function in a numba
kernel that also calls MuJoCo's C ``mj_step`` itself and writes the recorder's rows, so one
interpolation period (``ticks_per_period`` ticks of encoder -> PID+FF -> DAC -> drives -> physics
-> record) costs one Python call instead of one per tick. There is no second copy of any block:
the kernel and the task work on the same records (``servo.axes``, ``servo.load_cell``).

Per tick ``j`` of the period::

    positions = the encoders' positions from qpos (gather_encoders)
    servo_tick(axes, fraction[j] or the step interpolator's point, positions) -> volts
    force = read_load_cell(-sensordata[force_adr])
    (screw_stiffness(qpos) -> tendon_stiffness; drive_amps(volts, qpos, qvel) -> ctrl; mj_step) x substeps;
    record command, reading, DAC code, force at row t + j

Used for analog output with the drives enabled and no injected card faults (the fault injector
changes the records between ticks from Python).

MuJoCo is reached through :mod:`cnc_twin.machine.mujoco_c`; :func:`available` says whether it can be.
"""

from __future__ import annotations

import numpy as np

from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.dsp import adc, compensation, dac, encoder, pid, reversal, servo
from cnc_twin.machine import amplifier, model_file, mujoco_c, plant, screw


def available() -> bool:
    """Whether the compiled servo can run here (numba, and MuJoCo's shared library)."""
    return mujoco_c.available()


# the kernel calls MuJoCo through mujoco_c's bindings and the servo's blocks: recompile when they change
purge_stale(__file__, [mujoco_c.__file__, servo.__file__, encoder.__file__, pid.__file__, dac.__file__,
                       adc.__file__, compensation.__file__, reversal.__file__, plant.__file__, amplifier.__file__, screw.__file__,
                       model_file.__file__])

if mujoco_c.IMPORT_ERROR is None:
    from numba import njit

    _mj_step = mujoco_c.mj_step
    _servo_tick = servo.servo_tick
    _read_load_cell = servo.read_load_cell
    _gather_encoders = plant.gather_encoders
    _drive_amps = amplifier.drive_amps
    _screw_stiffness = screw.screw_stiffness
    _mj_kinematics = mujoco_c.mj_kinematics
    _tool_pose = plant.tool_pose

    @njit(cache=True, nogil=True)
    def run_ticks(model_ptr, data_ptr, substeps, axes, comp_tables, load_cell, fractions, tick_commands,
                  use_tick_commands, qpos, qvel, taps, positions, amps, volts, ctrl, screws, tendon_stiffness,
                  sensordata, force_adr, site_xpos, xpos, xaxis, tool_ids, rec_command, rec_actual, rec_dac, rec_force,
                  rec_tool, t0):  # pragma: no cover - compiled
        """Run ``len(fractions)`` servo ticks on ``axes`` (:data:`~cnc_twin.dsp.servo.AXIS`; their
        pitch-error tables ``comp_tables``) and ``load_cell`` (:data:`~cnc_twin.dsp.servo.LOAD_CELL`,
        shape ``(1,)``) from recorder row
        ``t0``, each followed by ``substeps`` physics steps. The encoders read ``qpos`` where
        ``taps`` (:data:`~cnc_twin.machine.plant.ENCODER_TAP`) say, into ``positions``; the DACs
        write ``volts``, which the amplifiers ``amps`` (:data:`~cnc_twin.machine.amplifier.AMP`)
        turn into MuJoCo's ``ctrl`` before every physics step, as ``screws``
        (:data:`~cnc_twin.machine.screw.SCREW`) write their stiffness into the model's
        ``tendon_stiffness``. ``fractions`` are a whole period's
        ticks: at the last, the tool's true pose goes into ``rec_tool`` row ``t0 // ticks``
        (:func:`~cnc_twin.machine.plant.tool_pose`, after MuJoCo's kinematics; ``tool_ids``:
        :func:`~cnc_twin.machine.plant.tool_pose_ids`)."""
        cell = load_cell[0]
        n = fractions.shape[0]
        for j in range(n):
            row = t0 + j
            if j == n - 1:  # as the period's last tick samples its encoders
                _mj_kinematics(model_ptr, data_ptr)
                _tool_pose(site_xpos, xpos, xaxis, qpos, tool_ids, rec_tool[t0 // n])
            _gather_encoders(qpos, taps, positions)
            _servo_tick(axes, comp_tables, fractions[j], tick_commands[j], use_tick_commands, positions, rec_command[row],
                        rec_actual[row], rec_dac[row], volts)
            rec_force[row] = _read_load_cell(cell, -sensordata[force_adr])
            for _ in range(substeps):
                _screw_stiffness(screws, qpos, tendon_stiffness)
                _drive_amps(amps, volts, qpos, qvel, ctrl)
                _mj_step(model_ptr, data_ptr)


class CompiledServo:
    """The compiled servo period for one :class:`~cnc_twin.dsp.servo.ServoTask` on one plant.

    Parameters
    ----------
    servo : the servo task (analog output); the kernel works on its records.
    plant : the :class:`~cnc_twin.machine.plant.Plant` it drives.
    substeps : physics steps per servo tick.
    """

    def __init__(self, servo, plant, *, substeps: int):
        if not available():
            raise RuntimeError(f"compiled servo unavailable: {mujoco_c.IMPORT_ERROR or 'mujoco has no _address'}")
        self.servo = servo
        self.substeps = substeps
        self.plant_args = (mujoco_c.address(plant.model), mujoco_c.address(plant.data), substeps)
        """MuJoCo's model and data pointers and the physics steps per tick: the kernel's first arguments"""
        data = plant.data
        self.plant_arrays = (data.qpos, data.qvel, plant.encoder_taps, plant.encoders, plant.amps, plant.volts,
                             data.ctrl, plant.screws, plant.model.tendon_stiffness, data.sensordata,
                             plant.force_sensor_adr, data.site_xpos, data.xpos, data.xaxis,
                             plant.tool_ids)
        """MuJoCo's qpos and qvel, the encoders' taps and positions, the amplifiers and their
        voltages, MuJoCo's ctrl, the screws and the model's tendon stiffness, MuJoCo's sensordata,
        the load cell's address in sensordata, and what
        the tool's pose is read from (MuJoCo's site and body positions, joint axes; the ids)"""

    def tick_args(self) -> tuple:
        """The kernel's arguments from the servo's records to the plant's arrays, for this period."""
        servo = self.servo
        return (*self.plant_args, servo.axes, servo.comp_tables, servo.load_cell, servo.fractions, servo.tick_commands,
                servo.use_tick_commands, *self.plant_arrays)

    def warm_up(self) -> None:
        """Compile the kernel (or load it from numba's cache: 0.4 s in a fresh process) now, not
        inside the timed run: a call of zero ticks with arguments of the types the run passes.
        ``Twin.run`` calls it while the planner process starts."""
        n = self.servo.n_axes
        args = self.tick_args()
        run_ticks(*args[:6], self.servo.fractions[:0], *args[7:],
                  np.zeros((1, n)), np.zeros((1, n), dtype=np.int32), np.zeros((1, n), dtype=np.int16),
                  np.zeros(1), np.zeros((1, 6)), 0)

    def run_period(self, recorder, t: int) -> None:
        """One interpolation period from recorder row ``t``: the servo ticks, the physics, the
        rows. Afterwards the servo's ``frame`` holds the last tick's signals, as the Python path
        leaves it. The servo's setpoint must be latched (``ServoTask.begin_period``)."""
        row = recorder.row(t)
        run_ticks(*self.tick_args(), recorder.command, recorder.actual, recorder.dac, recorder.pad_force,
                  recorder.tool, row)
        last = row + self.servo.ticks_per_period - 1
        self.servo.frame_from(recorder.command[last], recorder.pad_force[last])

"""Whole interpolation periods, compiled: many periods per call.

In the steady middle of a NURBS curve block (a surface path's too, with the force loop tracking and
the spindle turning), a point-to-point move or a dwell nothing the card does per period needs
Python: the supervisor's checks pass, the feed advances at a constant time scale (the block's
S-curve, the move's trapezoid), the stepper walks the path, the setpoint stays inside the soft
limits, the state stays RUNNING, no record is exchanged (the planner has sent everything:
``solo``). :class:`~cnc_twin.run.period_batch.PeriodBatch` then runs up to :data:`MAX_BATCH`
periods in one call of :func:`run_periods`, which does per period exactly what
:meth:`DspTask.begin_period` (with :meth:`SegmentInterpolator.next_period`,
:func:`~cnc_twin.dsp.force.force_update`, :meth:`Supervisor.check` / :meth:`~Supervisor.clamp` and
:meth:`ServoTask.begin_period`), the clock's period record, :class:`~cnc_twin.run.servo_kernel.CompiledServo`
and the removal map's update do, in the same order with the same IEEE operations::

    check:   following error, limit switches, DAC saturation run, pad force   (a trip -> stop)
    force:   TRACK: setpoint(path length), PI, feed adaptation                (new feed factor -> stop)
             at a path's end: seek, ramp, ramp down, retract at the held pose (new state -> stop)
    feed:    tau += lambda T; (s, v, a) = S-curve(tau)                        (block end -> stop)
             starved-hold latch (queued path within the stopping distance)   (latch -> stop)
    path:    u, point = stepper(ds); pose: held A, B, C, the tool-axis curve's or the surface
             normal's (lead, tilt) inverse kinematics; held = (pose - power_on) * cpu
             (a move: start + s(tau) * displacement; a dwell: the held setpoint  (end -> stop))
    offsets: setpoint = held - depth * tool axis (force loop); C + spindle angle
    clamp:   soft limits                                                      (outside -> stop)
    servo:   feed-forward; ticks x (QEP, PID+FF, DAC, ADC, mj_step); rows recorded
    removal: every ``every`` periods, the removal map's update from MuJoCo's data

A period that would do anything else (trip, latch, end the block, change the feed factor, clamp)
is not committed: the batch ends before it and the card's Python task runs that period as always.
So the trace is the one the Python task gives, bit for bit (``tests/test_servo_kernel.py`` and
``tests/test_polish_batch.py`` compare whole runs against ``compiled=False``).

Not batched: the periods where the force loop changes state, a spindle changing speed, feed holds
and override changes, exchanges with the planner, injected faults, pulse output, real-time mode. A
batch starts at most once per 64 periods' liveness check of the planner, which it makes first, as
the card's task does.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.dsp import curve_stepper, feed_slew, force, servo, spindle, supervisor
from cnc_twin.geometry import kinematics, span_eval, surface_path
from cnc_twin.machine import plant
from cnc_twin.motion import scurve, trapezoid
from cnc_twin.dsp.task import SOLO_LIVENESS_PERIODS
from cnc_twin.polishing import removal_kernel
from cnc_twin.run import c_clock, servo_kernel

# the batch kernel calls the path stepper, the force loop, the servo ticks, the removal update and
# the clock: recompile when they change
purge_stale(__file__, [curve_stepper.__file__, span_eval.__file__, force.__file__, servo_kernel.__file__,
                       servo.__file__, supervisor.__file__, plant.__file__, removal_kernel.__file__,
                       c_clock.__file__, feed_slew.__file__, kinematics.__file__, surface_path.__file__,
                       spindle.__file__, scurve.__file__, trapezoid.__file__])
_latch_setpoint = servo.latch_setpoint
_force_update = force.force_update
_supervise_checks = supervisor.supervise
_switch_bits = plant.switch_bits

# the card's own plain functions, compiled here (one implementation, the same bits)
_stop_distance = njit(cache=True)(feed_slew.stop_distance)
"""the starved hold's stopping distance"""
_pose_to_axes = njit(cache=True)(kinematics.pose_to_axes)
"""the head's inverse kinematics"""
_tool_axis = njit(cache=True)(surface_path.tool_axis_leaned)
"""a surface path's tool axis: the normal with lead and tilt"""
_spindle_turn = njit(cache=True)(spindle.spindle_turn)
"""the spindle's speed ramp and angle"""
_phase_state = njit(cache=True)(scurve.phase_state)
"""a curve block's feed within one of its S-curve's phases"""
_trapezoid_state = njit(cache=True)(trapezoid.trapezoid_state)
"""a move's normalised path, (s, v, a) at a time"""

MAX_BATCH = SOLO_LIVENESS_PERIODS
"""periods per call at most (a batch holds at most one of the card's liveness checks, made first)"""

# the feed block (float64): clock, path, constant scale, and the (s, v, a) kept for the next period
TAU, S_DONE, LAM, PERIOD, QUEUED_PATH, A_STOP, OPEN_END, HAS_STATE, S_NOW, V_NOW, A_NOW, LENGTH, DURATION, V0, \
    DWELL_LEFT, T_ACC, ACCEL, T_FLAT, J_STOP = range(19)
N_FEED = 19
CURVE, MOVE, DWELL, FORCE_WAIT = 0, 1, 2, 3
"""what runs: a curve block (or a surface path's), a point-to-point move (its trapezoid), a dwell,
the force loop making or releasing contact at a path's end (its seek, ramp, ramp down, retract)"""
# the check block (float64, shape (N_CHECK, 6)): per axis
PREV_COMMAND, PREV_ACTUAL, POWER_ON, CPU, HOLD, HELD = range(6)
N_CHECK = 6
"""``HOLD``: a curve's held A, B, C [rad] (first three); ``HELD``: the path setpoint without the
force loop's and the spindle's offsets [counts] (the interpolator's ``hold_counts``)"""
# check scalars (float64)
PREV_FORCE, INV_T, SUPERVISED = range(3)
N_CHECK_SCALARS = 3
# the process block (float64): path length, spindle, force loop, the surface's tool axis, removal
PATH_S, C_OFFSET, SPIN, SPINDLE_ON, SPIN_TARGET, SPIN_STEP, FORCE_ON, SURFACE, LEANED, COS_LEAD, SIN_LEAD, COS_TILT, \
    SIN_TILT, C_HOLD, AXIS_X, AXIS_Y, AXIS_Z, EVERY, MARK = range(19)
N_PROCESS = 19
"""``AXIS_*``: the tool axis the force loop pushes along (the interpolator's ``tool_axis``); ``EVERY``:
periods between removal updates (0: none); ``MARK``: the program line of the last period"""
# the per-period outputs (float64, shape (N_OUT, MAX_BATCH))
OUT_PATH_U, OUT_PATH_DS, OUT_TARGET, OUT_DEPTH, OUT_MARK = range(5)
N_OUT = 5


@njit(cache=True)
def _scurve_state(phases, times, duration, length, v0, v1, t):
    """``(s, v, a)`` of the S-curve at ``t``: :meth:`SCurve.state`'s clamps at the block's ends,
    the phase ``t`` falls in, and the card's :func:`~cnc_twin.motion.scurve.phase_state`."""
    if t >= duration:
        return length, v1, 0.0
    if t <= 0.0:
        return 0.0, v0, 0.0
    p = span_eval.bisect_right(times, t) - 1
    return _phase_state(phases[p, 0], phases[p, 1], phases[p, 2], phases[p, 3], phases[p, 4], t)


@njit(cache=True)
def _supervise(check, cs, supervision, sensordata, axes, inputs, saturations, trial):
    """The supervisor's checks on the last tick's signals (:func:`~cnc_twin.dsp.supervisor.supervise`,
    as ``Supervisor.check`` calls it) on ``trial``, a copy of its per-axis records (committed with
    the period): True if one trips. ``supervision``: ``(settings, limits, switches)``."""
    settings, limits, switches = supervision
    trial[:] = limits
    _switch_bits(switches, sensordata, inputs)
    for i in range(axes.shape[0]):
        saturations[i] = axes[i].dac.saturations
    code, _ = _supervise_checks(settings[0], trial, check[PREV_COMMAND], check[PREV_ACTUAL], saturations, inputs,
                                cs[PREV_FORCE])
    return code != 0


@njit(cache=True)
def _force_keeps(xs, fs, measured, path_s, trial):
    """One period of the force loop on ``trial`` (a copy of its record, shape ``(1,)``), as the
    card runs it; whether the period kept the loop's state and feed factor (if not, the Python
    task runs this period: the batch ends before it)."""
    loop = trial[0]
    state, feed = loop.state, loop.feed_factor
    _force_update(loop, xs, fs, measured, path_s)
    return loop.state == state and loop.feed_factor == feed


@njit(cache=True)
def run_periods(n_max, mode, k0, servo_args, feed, phases, times, v1, curve_args, sstate, sscratch, axis_args, move,
                check, cs, supervision, process, force_args, lines, removal_args, out, timed, interp_ns,
                timespec):  # pragma: no cover - compiled
    """Run up to ``n_max`` periods from the run's period ``k0``; returns how many were committed
    (0 .. n_max).

    ``mode``: :data:`CURVE`, :data:`MOVE` or :data:`DWELL`. ``servo_args``: the arguments of
    ``servo_kernel.run_ticks`` but the first row, then the first row and the rows per period; ``feed`` / ``check`` / ``cs`` / ``process``: the
    blocks above (updated to the last committed period); ``curve_args``: the path's ``ev``
    (:mod:`cnc_twin.geometry.span_eval`) and the corrector flag; ``sstate`` the stepper's state;
    ``axis_args``: the tool-axis curve (``starts, blocks, lo, hi, d``; no spans: none) and the head
    geometry (``(2, 3)``: pivot, offset); ``move``: shape ``(2, 6)``, a move's start and
    displacement [counts] (a dwell's held setpoint in row 0); ``supervision``: the supervisor's
    settings and per-axis records (:mod:`cnc_twin.dsp.supervisor`) and the plant's switches
    (:attr:`~cnc_twin.machine.plant.Plant.switches`); ``force_args``: the force loop's profile and record ``(xs, fs, record)``
    (:mod:`cnc_twin.dsp.force`); ``lines``: a G-code path's line starts [u] and line
    numbers (empty: none); ``removal_args``: those of ``removal_kernel.tracker_update``;
    ``out``: per committed period, the path's u and ds, the force setpoint and depth, the program
    line; with ``timed``, ``interp_ns`` gets each period's interpolation time [ns] (feed, force,
    path, kinematics, setpoint: what ``DspTask`` times around ``next_period``).
    """
    (model_ptr, data_ptr, substeps, axes, load_cell, fractions, tick_commands, use_tick_commands, qpos, ctrl,
     sensordata, force_adr, rec_command, rec_actual, rec_dac, rec_force, row0, row_step) = servo_args
    ev, correct = curve_args
    d = span_eval.path_dim(ev)
    a_starts, a_blocks, a_lo, a_hi, a_d, head = axis_args
    fxs, ffs, loop = force_args
    line_us, line_numbers = lines
    tilting = a_starts.shape[0] > 0
    surface = process[SURFACE] != 0.0
    force_on = process[FORCE_ON] != 0.0
    every = int(process[EVERY])
    direction = np.empty(3)
    a_h = np.empty(3 * (a_d + 1))
    a_c1 = np.empty(a_d)
    a_c2 = np.empty(a_d)
    n = axes.shape[0]
    tpp = fractions.shape[0]
    pose = np.empty(n)
    trial = np.empty(sstate.shape[0])
    force_trial = loop.copy()
    held = np.empty(n)
    setpoint = np.empty(n)
    limits = supervision[1]
    limits_trial = limits.copy()
    inputs = np.zeros(n, np.int64)
    saturations = np.zeros(n, np.int64)
    tool = np.empty(3)
    T = feed[PERIOD]
    for k in range(n_max):
        # --- supervisor check on the last tick's signals (a trip: Python runs this period) ---
        if cs[SUPERVISED] != 0.0 and _supervise(check, cs, supervision, sensordata, axes, inputs, saturations,
                                                limits_trial):
            return k
        started = c_clock.monotonic_ns(timespec) if timed else 0
        ds = 0.0
        mark = process[MARK]
        tool[0], tool[1], tool[2] = process[AXIS_X], process[AXIS_Y], process[AXIS_Z]
        if mode == CURVE:
            # --- the force loop first, on the load cell and the path so far (ForceController.update) ---
            if force_on:
                force_trial[:] = loop
                if not _force_keeps(fxs, ffs, cs[PREV_FORCE], process[PATH_S], force_trial):
                    return k  # the feed adapts from this period on: the Python task slews it
            # --- the feed along the block (SegmentInterpolator._advance_block) ---
            if feed[HAS_STATE] != 0.0:
                s_now, v, a_now = feed[S_NOW], feed[V_NOW], feed[A_NOW]
            else:
                s_now, v, a_now = _scurve_state(phases, times, feed[DURATION], feed[LENGTH], feed[V0], v1, feed[TAU])
            if feed[OPEN_END] != 0.0:
                remaining = feed[LENGTH] - s_now + feed[QUEUED_PATH]
                lam = feed[LAM]
                if remaining <= _stop_distance(lam * v, lam * lam * a_now, feed[A_STOP], feed[J_STOP], T):
                    return k  # the starved hold latches here
            tau = feed[TAU] + feed[LAM] * T
            if not tau < feed[DURATION]:
                return k  # the block ends within this period
            s_tau, v_tau, a_tau = _scurve_state(phases, times, feed[DURATION], feed[LENGTH], feed[V0], v1, tau)
            ds = s_tau - feed[S_DONE]
            # --- the path, tentatively (committed below) ---
            trial[:] = sstate
            if ds > 0.0:
                curve_stepper.step(ev, correct, ds, trial, sscratch)
            point = trial[2 + 2 * d:2 + 3 * d]
            if surface:  # SurfaceRun.pose: the surface normal with lead and tilt, the kinematics
                tangents = trial[2 + 3 * d:2 + 3 * d + 6]
                tool[0], tool[1], tool[2] = _tool_axis(tangents[0:3], tangents[3:6], trial[2:2 + d], process[COS_LEAD],
                                                       process[SIN_LEAD], process[COS_TILT], process[SIN_TILT],
                                                       process[LEANED] != 0.0)
                pose[0], pose[1], pose[2], pose[3], pose[4] = _pose_to_axes(point, tool, head[0], head[1])
                pose[5] = process[C_HOLD]
            else:
                for i in range(n):
                    pose[i] = point[i] if i < 3 else check[HOLD, i - 3]
                if tilting:  # Curve.pose: the tool axis at u, then the head's inverse kinematics
                    span_eval.evaluate_span(a_starts, a_blocks, a_lo, a_hi, a_d, trial[0], a_h, direction, a_c1,
                                              a_c2)
                    pose[0], pose[1], pose[2], pose[3], pose[4] = _pose_to_axes(point, direction, head[0], head[1])
                if line_us.shape[0] > 0:  # Curve.line_at: the program line it runs now
                    mark = line_numbers[max(span_eval.bisect_right(line_us, trial[0]) - 1, 0)]
            for i in range(n):
                held[i] = (pose[i] - check[POWER_ON, i]) * check[CPU, i]
        elif mode == MOVE:  # SegmentInterpolator._advance_move and Trapezoid.evaluate
            tau = feed[TAU] + feed[LAM] * T
            if tau >= feed[DURATION] - 1e-9 * T:
                return k  # the move ends within this period
            s = _trapezoid_state(feed[T_ACC], feed[ACCEL], feed[T_FLAT], feed[V0], feed[DURATION], tau)[0]
            for i in range(n):
                held[i] = move[0, i] + s * move[1, i]
        elif mode == DWELL:  # a dwell holds the setpoint
            if feed[DWELL_LEFT] - 1.0 <= 0.0:
                return k  # the dwell ends in this period
            for i in range(n):
                held[i] = check[HELD, i]
        else:  # the force loop at a path's end: the pose there (move row 0) and the loop's push
            force_trial[:] = loop
            if not _force_keeps(fxs, ffs, cs[PREV_FORCE], process[PATH_S], force_trial):
                return k  # contact, or a ramp's or the retract's end: the Python task takes it on
            for i in range(n):
                held[i] = move[0, i]
        # --- the force loop's push along the tool axis, the spindle's turn of C ---
        for i in range(n):
            setpoint[i] = held[i]
        if force_on:
            depth = force_trial[0].depth
            if depth != 0.0:
                for i in range(3):
                    setpoint[i] = held[i] - depth * tool[i] * check[CPU, i]
        c_offset = process[C_OFFSET]
        spin = process[SPIN]
        if process[SPINDLE_ON] != 0.0 or spin != 0.0:  # SegmentInterpolator._turn_spindle
            spin, turned = _spindle_turn(spin, process[SPIN_TARGET], process[SPIN_STEP], T)
            c_offset += turned
        if c_offset != 0.0:
            setpoint[5] = setpoint[5] + c_offset * check[CPU, 5]
        if timed:
            interp_ns[k] = c_clock.monotonic_ns(timespec) - started
        # --- soft limits (a clamp: Python runs this period) ---
        if cs[SUPERVISED] != 0.0:
            for i in range(n):
                if setpoint[i] < limits[i].soft_lo or setpoint[i] > limits[i].soft_hi:
                    return k
        # --- commit the period ---
        if cs[SUPERVISED] != 0.0:
            limits[:] = limits_trial  # the DAC saturation runs this period's check counted
        if mode == CURVE:
            feed[TAU] = tau
            feed[S_DONE] = s_tau
            feed[S_NOW], feed[V_NOW], feed[A_NOW] = s_tau, v_tau, a_tau
            feed[HAS_STATE] = 1.0
            sstate[:] = trial
            if surface:
                process[PATH_S] += ds
                process[AXIS_X], process[AXIS_Y], process[AXIS_Z] = tool[0], tool[1], tool[2]
            out[OUT_PATH_U, k] = trial[0]
        else:
            if mode == MOVE:
                feed[TAU] = tau
            elif mode == DWELL:
                feed[DWELL_LEFT] -= 1.0
            out[OUT_PATH_U, k] = -1.0
        if force_on:
            loop[:] = force_trial
        out[OUT_PATH_DS, k] = ds
        out[OUT_TARGET, k] = loop[0].target
        out[OUT_DEPTH, k] = loop[0].depth
        out[OUT_MARK, k] = mark
        process[MARK] = mark
        process[C_OFFSET] = c_offset
        process[SPIN] = spin
        for i in range(n):
            check[HELD, i] = held[i]
        _latch_setpoint(axes, setpoint, cs[INV_T])  # ServoTask.begin_period: the feed-forward terms
        row = row0 + k * row_step
        servo_kernel.run_ticks(model_ptr, data_ptr, substeps, axes, load_cell, fractions, tick_commands, False, qpos,
                               ctrl, sensordata, force_adr, rec_command, rec_actual, rec_dac, rec_force, row)
        last = row + tpp - 1
        for i in range(n):
            check[PREV_COMMAND, i] = rec_command[last, i]
            check[PREV_ACTUAL, i] = axes[i].qep.position32
        cs[PREV_FORCE] = rec_force[last]
        # --- the removal map, after the period's ticks (as the clock calls RemovalTracker.update) ---
        if every > 0 and (k0 + k + 1) % every == 0:
            began = c_clock.monotonic_ns(timespec)
            removal_kernel.tracker_update(*removal_args)
            totals = removal_args[-1]
            totals[removal_kernel.COST_NS] += c_clock.monotonic_ns(timespec) - began
    return n_max


def kernels_cached() -> bool:
    """Whether numba's on-disk cache holds the batch and servo kernels already (False on the first
    run after installing, which compiles them: about 15 s). Looks for each kernel's index file
    (``.nbi``, one per function, named after its module, name and first line) in the cache
    directory numba reports for it (``Dispatcher.stats.cache_path``); True when that cannot be
    found out (nothing to warn about then)."""
    import sys
    from pathlib import Path

    version = f".py{sys.version_info.major}{sys.version_info.minor}"
    try:
        for kernel in (run_periods, servo_kernel.run_ticks, removal_kernel.tracker_update, *servo.TASK_FUNCTIONS,
                       force.force_update, supervisor.supervise, plant.switch_bits):
            code = kernel.py_func.__code__
            name = f"*.{kernel.py_func.__qualname__}-{code.co_firstlineno}{version}*.nbi"
            if not any(Path(kernel.stats.cache_path).glob(name)):
                return False
        return True
    except (AttributeError, OSError):  # another numba's dispatchers
        return True

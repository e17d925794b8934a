"""Whole interpolation periods, compiled: many periods per call.

In the steady middle of a NURBS curve block (a surface path's too, with the force loop tracking and
the spindle turning), a point-to-point move or a dwell nothing the card does per period needs
Python: the supervisor's checks pass, the feed advances at a constant time scale (the block's
S-curve, the move's trapezoid), the stepper walks the path, the setpoint stays inside the soft
limits, the state stays RUNNING, no record is exchanged (the planner has sent everything:
``solo``). :class:`~cnc_twin.run.period_batch.PeriodBatch` then runs up to :data:`MAX_BATCH`
periods in one call of :func:`run_periods`, which does per period exactly what
:meth:`~cnc_twin.dsp.task.DspTask.begin_period` (with
:meth:`~cnc_twin.dsp.interpolator.SegmentInterpolator.next_period`,
:func:`~cnc_twin.dsp.force.force_update`, :meth:`~cnc_twin.dsp.supervisor.Supervisor.check` /
:meth:`~cnc_twin.dsp.supervisor.Supervisor.clamp` and
:meth:`~cnc_twin.dsp.servo.ServoTask.begin_period`), the clock's period record,
:class:`~cnc_twin.run.servo_kernel.CompiledServo` and the removal map's update do, in the same
order with the same IEEE operations::

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
from cnc_twin.dsp import adc, compensation, curve_stepper, dac, encoder, feed_slew, force, pid, reversal, servo, spindle, \
    supervisor
from cnc_twin.geometry import kinematics, span_eval, surface_path
from cnc_twin.machine import amplifier, plant, screw
from cnc_twin.motion import scurve, trapezoid
from cnc_twin.dsp.task import SOLO_LIVENESS_PERIODS
from cnc_twin.polishing import removal_kernel
from cnc_twin.run import c_clock, servo_kernel

# the batch kernel calls the path stepper, the force loop, the servo ticks, the removal update and
# the clock: recompile when they change
purge_stale(__file__, [curve_stepper.__file__, span_eval.__file__, force.__file__, servo_kernel.__file__,
                       servo.__file__, supervisor.__file__, plant.__file__, removal_kernel.__file__,
                       c_clock.__file__, feed_slew.__file__, kinematics.__file__, surface_path.__file__,
                       spindle.__file__, scurve.__file__, trapezoid.__file__, amplifier.__file__,
                       encoder.__file__, pid.__file__, dac.__file__, adc.__file__, compensation.__file__,
                       reversal.__file__, screw.__file__])
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

CURVE, MOVE, DWELL, FORCE_WAIT = 0, 1, 2, 3
"""what runs: a curve block (or a surface path's), a point-to-point move (its trapezoid), a dwell,
the force loop making or releasing contact at a path's end (its seek, ramp, ramp down, retract)"""

# The batch's own state: typed records, each its interface as the card's blocks have theirs
# (:class:`~cnc_twin.run.period_batch.PeriodBatch` fills them from the card's objects before a call
# and reads them back after it; ``run_periods`` reads and advances them per committed period).
FEED = np.dtype([
    ("tau", np.float64),          # s      the running item's clock (lambda-scaled)     batch <-> kernel
    ("s_done", np.float64),       # m      path length done in the block (a curve)      batch <-> kernel
    ("lam", np.float64),          # -      the feed override in effect (constant)       batch
    ("period", np.float64),       # s      the interpolation period T                   set up
    ("queued_path", np.float64),  # m      path queued behind the block (starved hold)  batch
    ("a_stop", np.float64),       # m/s^2  the starved hold's deceleration              batch
    ("j_stop", np.float64),       # m/s^3  and jerk                                     batch
    ("open_end", np.bool_),       # -      the block ends at speed (nothing queued may stop it)  batch
    ("has_state", np.bool_),      # -      (s_now, v_now, a_now) hold the last period's   batch <-> kernel
    ("s_now", np.float64),        # m      the S-curve's s at tau                       batch <-> kernel
    ("v_now", np.float64),        # m/s    its v                                        batch <-> kernel
    ("a_now", np.float64),        # m/s^2  its a                                        batch <-> kernel
    ("length", np.float64),       # m      the block's length (a curve)                 batch
    ("duration", np.float64),     # s      the block's or move's duration               batch
    ("v0", np.float64),           # m/s    a curve block's entry speed; a move's peak (normalised)  batch
    ("dwell_left", np.float64),   # -      a dwell's periods left                       batch <-> kernel
    ("t_acc", np.float64),        # s      a move's trapezoid: acceleration time        batch
    ("accel", np.float64),        # 1/s^2  its normalised acceleration                  batch
    ("t_flat", np.float64),       # s      its constant-speed time                      batch
])
"""the feed of the running item: shape ``(1,)``"""

AXIS_STATE = np.dtype([
    ("prev_command", np.float64),     # counts  the last tick's setpoint (supervisor)   batch <-> kernel
    ("prev_actual", np.float64),      # counts  the last tick's encoder count           batch <-> kernel
    ("power_on", np.float64),         # m|rad   the axis at power-on (counts' zero)     set up
    ("counts_per_unit", np.float64),  # 1/m|1/rad                                       set up
    ("hold", np.float64),             # rad     a curve's held A, B, C (first three rows) batch
    ("held", np.float64),             # counts  the path setpoint without the force loop's and the
                                      #         spindle's offsets (the interpolator's hold_counts)  batch <-> kernel
])
"""per axis, what the period's check and setpoint keep: shape ``(n_axes,)``"""

CHECK = np.dtype([
    ("prev_force", np.float64),   # N      the last tick's load-cell force              batch <-> kernel
    ("inv_period", np.float64),   # 1/s    1 / T (the feed-forward's differences)      set up
    ("supervised", np.bool_),     # -      the supervisor checks the periods             set up
])
"""the card's scalars for the checks and the feed-forward: shape ``(1,)``"""

PROCESS = np.dtype([
    ("path_s", np.float64),       # m      a surface path's length so far (force profile)  batch <-> kernel
    ("c_offset", np.float64),     # rad    the spindle's turn added to C                batch <-> kernel
    ("spin", np.float64),         # rad/s  the spindle's speed                          batch <-> kernel
    ("spindle_on", np.bool_),     # -      the spindle is commanded on                  batch
    ("spin_target", np.float64),  # rad/s  its commanded speed                          batch
    ("spin_step", np.float64),    # rad/s  its speed change per period                  batch
    ("force_on", np.bool_),       # -      the force loop runs (not OFF)                batch
    ("surface", np.bool_),        # -      the path is a surface section                batch
    ("leaned", np.bool_),         # -      the surface's tool axis has lead or tilt      batch
    ("cos_lead", np.float64),     # -      the lead and tilt angles' cosines and sines   batch
    ("sin_lead", np.float64),
    ("cos_tilt", np.float64),
    ("sin_tilt", np.float64),
    ("c_hold", np.float64),       # rad    a surface path's held C                      batch
    ("axis", np.float64, (3,)),   # -      the tool axis the force loop pushes along (world, unit;
                                  #        the interpolator's tool_axis)                batch <-> kernel
    ("every", np.int64),          # -      periods between removal updates (0: none)     set up
    ("mark", np.float64),         # -      the program line of the last period          batch <-> kernel
])
"""the process around the path: spindle, force loop, surface tool axis, removal map, line marks:
shape ``(1,)``"""

OUT = np.dtype([
    ("path_u", np.float64),       # -      the path parameter (-1: not on a curve)
    ("path_ds", np.float64),      # m      the path length advanced
    ("target", np.float64),       # N      the force setpoint in effect
    ("depth", np.float64),        # m      the force loop's push
    ("mark", np.float64),         # -      the program line
])
"""what each committed period recorded (the kernel writes row k): shape ``(MAX_BATCH,)``"""


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
def _supervise(axis_state, prev_force, supervision, sensordata, axes, inputs, saturations, trial):
    """The supervisor's checks on the last tick's signals (:func:`~cnc_twin.dsp.supervisor.supervise`,
    as ``Supervisor.check`` calls it) on ``trial``, a copy of its per-axis records (committed with
    the period): True if one trips. ``supervision``: ``(settings, limits, switches)``;
    ``axis_state``: :data:`AXIS_STATE` records; ``prev_force`` [N]."""
    settings, limits, switches = supervision
    trial[:] = limits
    _switch_bits(switches, sensordata, inputs)
    for i in range(axes.shape[0]):
        saturations[i] = axes[i].dac.saturations
    code, _ = _supervise_checks(settings[0], trial, axis_state.prev_command, axis_state.prev_actual, saturations,
                                inputs, prev_force)
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
def run_periods(n_max, mode, k0, servo_args, feed_record, profile, curve_args, axis_args, move, axis_state,
                check_record, supervision, process_record, force_args, lines, removal_args, out,
                timing):  # pragma: no cover - compiled
    """Run up to ``n_max`` periods from the run's period ``k0``; returns how many were committed
    (0 .. n_max).

    ``mode``: :data:`CURVE`, :data:`MOVE`, :data:`DWELL` or :data:`FORCE_WAIT`. ``servo_args``: the
    arguments of ``servo_kernel.run_ticks`` but the first row, then the first row and the rows per
    period. ``feed_record`` (:data:`FEED`), ``axis_state`` (:data:`AXIS_STATE`), ``check_record``
    (:data:`CHECK`), ``process_record`` (:data:`PROCESS`): the batch's records, advanced to the last
    committed period. ``profile``: a curve block's S-curve ``(phases (7, 5), phase_times (7,), v1)``;
    ``curve_args``: the path's ``ev`` (:mod:`cnc_twin.geometry.span_eval`), the corrector flag, the
    stepper's state and scratch (:mod:`cnc_twin.dsp.curve_stepper`); ``axis_args``: the tool-axis
    curve (``starts, blocks, lo, hi, d``; no spans: none) and the head geometry (``(2, 3)``: pivot,
    offset); ``move``: shape ``(2, n_axes)``, a move's start and displacement [counts] (a force
    wait's pose in row 0); ``supervision``: the supervisor's settings and per-axis records
    (:mod:`cnc_twin.dsp.supervisor`) and the plant's switches
    (:attr:`~cnc_twin.machine.plant.Plant.switches`); ``force_args``: the force loop's profile and
    record ``(xs, fs, record)`` (:mod:`cnc_twin.dsp.force`); ``lines``: a G-code path's line starts
    [u] and line numbers (empty: none); ``removal_args``: those of
    ``removal_kernel.tracker_update``; ``out``: :data:`OUT` rows, one per committed period;
    ``timing``: ``(timed, interp_ns, timespec)``: with ``timed``, ``interp_ns`` gets each period's
    interpolation time [ns] (feed, force, path, kinematics, setpoint: what ``DspTask`` times around
    ``next_period``).
    """
    (model_ptr, data_ptr, substeps, axes, comp_tables, load_cell, fractions, tick_commands, use_tick_commands, qpos,
     qvel, taps, positions, amps, volts, ctrl, screws, tendon_stiffness, sensordata, force_adr, site_xpos, xpos, xaxis,
     tool_ids, rec_command,
     rec_actual, rec_dac, rec_force, rec_tool, row0, row_step) = servo_args
    ev, correct, sstate, sscratch = curve_args
    phases, times, v1 = profile
    timed, interp_ns, timespec = timing
    feed, cs, process = feed_record[0], check_record[0], process_record[0]
    d = span_eval.path_dim(ev)
    a_starts, a_blocks, a_lo, a_hi, a_d, head = axis_args
    fxs, ffs, loop = force_args
    line_us, line_numbers = lines
    tilting = a_starts.shape[0] > 0
    surface = process.surface
    force_on = process.force_on
    every = process.every
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
    T = feed.period
    for k in range(n_max):
        # --- supervisor check on the last tick's signals (a trip: Python runs this period) ---
        if cs.supervised and _supervise(axis_state, cs.prev_force, supervision, sensordata, axes, inputs,
                                        saturations, limits_trial):
            return k
        started = c_clock.monotonic_ns(timespec) if timed else 0
        ds = 0.0
        mark = process.mark
        tool[0], tool[1], tool[2] = process.axis[0], process.axis[1], process.axis[2]
        if mode == CURVE:
            # --- the force loop first, on the load cell and the path so far (ForceController.update) ---
            if force_on:
                force_trial[:] = loop
                if not _force_keeps(fxs, ffs, cs.prev_force, process.path_s, force_trial):
                    return k  # the feed adapts from this period on: the Python task slews it
            # --- the feed along the block (SegmentInterpolator._advance_block) ---
            if feed.has_state:
                s_now, v, a_now = feed.s_now, feed.v_now, feed.a_now
            else:
                s_now, v, a_now = _scurve_state(phases, times, feed.duration, feed.length, feed.v0, v1, feed.tau)
            if feed.open_end:
                remaining = feed.length - s_now + feed.queued_path
                lam = feed.lam
                if remaining <= _stop_distance(lam * v, lam * lam * a_now, feed.a_stop, feed.j_stop, T):
                    return k  # the starved hold latches here
            tau = feed.tau + feed.lam * T
            if not tau < feed.duration:
                return k  # the block ends within this period
            s_tau, v_tau, a_tau = _scurve_state(phases, times, feed.duration, feed.length, feed.v0, v1, tau)
            ds = s_tau - feed.s_done
            # --- the path, tentatively (committed below) ---
            trial[:] = sstate
            if ds > 0.0:
                curve_stepper.step(ev, correct, ds, trial, sscratch)
            point = trial[2 + 2 * d:2 + 3 * d]
            if surface:  # SurfaceRun.pose: the surface normal with lead and tilt, the kinematics
                tangents = trial[2 + 3 * d:2 + 3 * d + 6]
                tool[0], tool[1], tool[2] = _tool_axis(tangents[0:3], tangents[3:6], trial[2:2 + d], process.cos_lead,
                                                       process.sin_lead, process.cos_tilt, process.sin_tilt,
                                                       process.leaned)
                pose[0], pose[1], pose[2], pose[3], pose[4] = _pose_to_axes(point, tool, head[0], head[1])
                pose[5] = process.c_hold
            else:
                for i in range(n):
                    pose[i] = point[i] if i < 3 else axis_state[i - 3].hold
                if tilting:  # Curve.pose: the tool axis at u, then the head's inverse kinematics
                    span_eval.evaluate_span(a_starts, a_blocks, a_lo, a_hi, a_d, trial[0], a_h, direction, a_c1,
                                              a_c2)
                    pose[0], pose[1], pose[2], pose[3], pose[4] = _pose_to_axes(point, direction, head[0], head[1])
                if line_us.shape[0] > 0:  # Curve.line_at: the program line it runs now
                    mark = line_numbers[max(span_eval.bisect_right(line_us, trial[0]) - 1, 0)]
            for i in range(n):
                held[i] = (pose[i] - axis_state[i].power_on) * axis_state[i].counts_per_unit
        elif mode == MOVE:  # SegmentInterpolator._advance_move and Trapezoid.evaluate
            tau = feed.tau + feed.lam * T
            if tau >= feed.duration - 1e-9 * T:
                return k  # the move ends within this period
            s = _trapezoid_state(feed.t_acc, feed.accel, feed.t_flat, feed.v0, feed.duration, tau)[0]
            for i in range(n):
                held[i] = move[0, i] + s * move[1, i]
        elif mode == DWELL:  # a dwell holds the setpoint
            if feed.dwell_left - 1.0 <= 0.0:
                return k  # the dwell ends in this period
            for i in range(n):
                held[i] = axis_state[i].held
        else:  # the force loop at a path's end: the pose there (move row 0) and the loop's push
            force_trial[:] = loop
            if not _force_keeps(fxs, ffs, cs.prev_force, process.path_s, force_trial):
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
                    setpoint[i] = held[i] - depth * tool[i] * axis_state[i].counts_per_unit
        c_offset = process.c_offset
        spin = process.spin
        if process.spindle_on or spin != 0.0:  # SegmentInterpolator._turn_spindle
            spin, turned = _spindle_turn(spin, process.spin_target, process.spin_step, T)
            c_offset += turned
        if c_offset != 0.0:
            setpoint[5] = setpoint[5] + c_offset * axis_state[5].counts_per_unit
        if timed:
            interp_ns[k] = c_clock.monotonic_ns(timespec) - started
        # --- soft limits (a clamp: Python runs this period) ---
        if cs.supervised:
            for i in range(n):
                if setpoint[i] < limits[i].soft_lo or setpoint[i] > limits[i].soft_hi:
                    return k
        # --- commit the period ---
        if cs.supervised:
            limits[:] = limits_trial  # the DAC saturation runs this period's check counted
        row_out = out[k]
        if mode == CURVE:
            feed.tau = tau
            feed.s_done = s_tau
            feed.s_now, feed.v_now, feed.a_now = s_tau, v_tau, a_tau
            feed.has_state = True
            sstate[:] = trial
            if surface:
                process.path_s += ds
                process.axis[0], process.axis[1], process.axis[2] = tool[0], tool[1], tool[2]
            row_out.path_u = trial[0]
        else:
            if mode == MOVE:
                feed.tau = tau
            elif mode == DWELL:
                feed.dwell_left -= 1.0
            row_out.path_u = -1.0
        if force_on:
            loop[:] = force_trial
        row_out.path_ds = ds
        row_out.target = loop[0].target
        row_out.depth = loop[0].depth
        row_out.mark = mark
        process.mark = mark
        process.c_offset = c_offset
        process.spin = spin
        for i in range(n):
            axis_state[i].held = held[i]
        _latch_setpoint(axes, setpoint, held, cs.inv_period)  # ServoTask.begin_period: the feed-forward terms
        row = row0 + k * row_step
        servo_kernel.run_ticks(model_ptr, data_ptr, substeps, axes, comp_tables, load_cell, fractions, tick_commands,
                               False, qpos, qvel, taps, positions, amps, volts, ctrl, screws, tendon_stiffness,
                               sensordata, force_adr, site_xpos,
                               xpos, xaxis, tool_ids, rec_command, rec_actual, rec_dac, rec_force, rec_tool, row)
        last = row + tpp - 1
        for i in range(n):
            axis_state[i].prev_command = rec_command[last, i]
            axis_state[i].prev_actual = axes[i].qep.position32
        cs.prev_force = rec_force[last]
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

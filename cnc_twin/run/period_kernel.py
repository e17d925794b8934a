"""Whole interpolation periods, compiled: many periods per call.

In the steady middle of a NURBS curve block, a point-to-point move or a dwell nothing the card
does per period needs Python: the supervisor's checks pass, the feed advances at a constant time
scale (the block's S-curve, the move's trapezoid), the stepper walks the curve, the setpoint
stays inside the soft limits, the state stays RUNNING, no record is exchanged (the planner has
sent everything: ``solo``). :class:`PeriodBatch` then runs up to
:data:`MAX_BATCH` periods in one call of :func:`run_periods`, which does per period
exactly what :meth:`DspTask.begin_period` (with :meth:`SegmentInterpolator.next_period`,
:meth:`Supervisor.check` / :meth:`~Supervisor.clamp` and :meth:`ServoTask.begin_period`), the
clock's period record and :class:`~cnc_twin.run.servo_kernel.CompiledServo` do, in the same
order with the same IEEE operations::

    check:   following error, limit switches, DAC saturation run, pad force   (a trip -> stop)
    feed:    tau += lambda T; (s, v, a) = S-curve(tau)                        (block end -> stop)
             starved-hold latch (queued path within the stopping distance)   (latch -> stop)
    curve:   u, point = stepper(ds); setpoint = (pose - power_on) * cpu
             (a move: start + s(tau) * displacement; a dwell: the held setpoint  (end -> stop))
    clamp:   soft limits                                                      (outside -> stop)
    servo:   feed-forward; ticks x (QEP, PID+FF, DAC, ADC, mj_step); rows recorded

A period that would do anything else (trip, latch, end the block, clamp) is not committed: the
batch ends before it and the card's Python task runs that period as always. So the trace is the
one the Python task gives, bit for bit (``tests/test_servo_kernel.py`` compares whole runs
against ``compiled=False``).

A curve with a tool-axis curve runs the head's inverse kinematics per period in the batch too.
Not batched: surfaces and the force loop, the spindle, feed holds and override changes,
exchanges with the planner, injected faults, pulse output, real-time mode. A batch starts at most once per 64 periods' liveness check of the
planner, which it makes first, as the card's task does.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnc_twin.dsp import curve_kernel, span_kernel
from cnc_twin.run import c_clock, servo_kernel
from cnc_twin.dsp.curve_kernel import CompiledCurveStepper
from cnc_twin.dsp.force import ForceState
from cnc_twin.dsp import feed_slew
from cnc_twin.dsp.path_blocks import SLEW_MARGIN, Curve
from cnc_twin.motion.scurve import SCurve
from cnc_twin.run.servo_kernel import ACCELERATION, P_NEXT, P_PREV, POSITION32, SATURATIONS, VELOCITY
from cnc_twin.dsp.task import QUEUE_AHEAD, SOLO_LIVENESS_PERIODS
from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.motion.segments import MoveSegment
from cnc_twin.core.axes import SWITCH_LIMIT_NEG, SWITCH_LIMIT_POS
from cnc_twin.whiteboard.records import Dwell
from cnc_twin.whiteboard.status import DspState

# the batch kernel calls the curve stepper, the servo ticks and the clock: recompile when they change
purge_stale(__file__, [curve_kernel.__file__, span_kernel.__file__, servo_kernel.__file__, c_clock.__file__, feed_slew.__file__])

_stop_distance = njit(cache=True)(feed_slew.stop_distance)
"""the starved hold's stopping distance, compiled from the card's own function (the same bits)"""

MAX_BATCH = SOLO_LIVENESS_PERIODS
"""periods per call at most (a batch holds at most one of the card's liveness checks, made first)"""

# the feed block (float64): clock, path, constant scale, and the (s, v, a) kept for the next period
TAU, S_DONE, LAM, PERIOD, QUEUED_PATH, A_STOP, OPEN_END, HAS_STATE, S_NOW, V_NOW, A_NOW, LENGTH, DURATION, V0, \
    DWELL_LEFT, T_ACC, ACCEL, T_FLAT, J_STOP = range(19)
N_FEED = 19
CURVE, MOVE, DWELL = 0, 1, 2
"""what runs: a curve block, a point-to-point move (its trapezoid), a dwell"""
# the check block (float64, shape (N_CHECK, 6)): per axis
FERR_LIMIT, SOFT_LO, SOFT_HI, PREV_COMMAND, PREV_ACTUAL, SAT_SEEN, SAT_RUN, POWER_ON, CPU, HOLD = range(10)
N_CHECK = 10
# check scalars (float64)
CHECK_SWITCHES, SAT_LIMIT, TICKS, MAX_FORCE, PREV_FORCE, INV_T, SUPERVISED = range(7)
N_CHECK_SCALARS = 7


@njit(cache=True)
def _scurve_state(phases, times, duration, length, v0, v1, t, out):
    """``(s, v, a)`` of the S-curve at ``t`` into ``out``, as :meth:`SCurve.state`."""
    if t >= duration:
        out[0], out[1], out[2] = length, v1, 0.0
        return
    if t <= 0.0:
        out[0], out[1], out[2] = 0.0, v0, 0.0
        return
    p = span_kernel.bisect_right(times, t) - 1
    t0, s0, pv0, a0, jk = phases[p, 0], phases[p, 1], phases[p, 2], phases[p, 3], phases[p, 4]
    dt = t - t0
    out[0] = s0 + dt * (pv0 + dt * (0.5 * a0 + dt * jk / 6.0))
    out[1] = pv0 + dt * (a0 + 0.5 * jk * dt)
    out[2] = a0 + jk * dt


@njit(cache=True)
def _pose_to_axes(tip, n, pivot, offset, out):
    """X, Y, Z, A, B into ``out[:5]``, as :func:`cnc_twin.geometry.kinematics.pose_to_axes`."""
    nx, ny, nz = n[0], n[1], n[2]
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    b = math.asin(max(-1.0, min(1.0, nx * inv)))
    a = math.atan2(-ny * inv, nz * inv)
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    ox, oy, oz = offset[0], offset[1], offset[2]
    x1, z1 = cb * ox + sb * oz, -sb * ox + cb * oz
    rx, ry, rz = x1, ca * oy - sa * z1, sa * oy + ca * z1
    out[0] = tip[0] - pivot[0] - rx
    out[1] = tip[1] - pivot[1] - ry
    out[2] = tip[2] - pivot[2] - rz
    out[3] = a
    out[4] = b


@njit(cache=True)
def run_periods(n_max, mode, servo_args, feed, phases, times, v1, curve_args, sstate, sscratch, axis_args, move,
                check, cs, switches, path_u, path_ds, timed, interp_ns, timespec):  # pragma: no cover - compiled
    """Run up to ``n_max`` periods; returns how many were committed (0 .. n_max).

    ``mode``: :data:`CURVE`, :data:`MOVE` or :data:`DWELL`. ``servo_args``: the arguments of
    ``servo_kernel.run_ticks`` but the first row; ``feed`` / ``check`` / ``cs``: the blocks
    above (updated to the last committed period); ``curve_args``: the path's ``ev``
    (:mod:`cnc_twin.dsp.span_kernel`) and the corrector flag; ``sstate`` the stepper's state; ``axis_args``:
    the tool-axis curve (``starts, blocks, lo, hi, d``; no spans: the tool axis is held) and the
    head geometry (``(2, 3)``: pivot, offset); ``move``: shape ``(2, 6)``, a move's start and
    displacement [counts] (a dwell's held setpoint in row 0); ``switches``: (axis, bit,
    sensordata address, sign) rows; ``path_u`` / ``path_ds``: per committed period; with ``timed``,
    ``interp_ns`` gets each period's interpolation time [ns] (feed, curve, kinematics, setpoint:
    what ``DspTask`` times around ``next_period``).
    """
    (model_ptr, data_ptr, substeps, fparams, fstate, istate, scalars, fractions, tick_commands, qpos, ctrl,
     sensordata, force_adr, rec_command, rec_actual, rec_dac, rec_force, row0, row_step) = servo_args
    ev, correct = curve_args
    d = span_kernel.path_dim(ev)
    a_starts, a_blocks, a_lo, a_hi, a_d, head = axis_args
    tilting = a_starts.shape[0] > 0
    direction = np.empty(3)
    a_h = np.empty(3 * (a_d + 1))
    a_c1 = np.empty(a_d)
    a_c2 = np.empty(a_d)
    n = fstate.shape[1]
    tpp = fractions.shape[0]
    pose = np.empty(n)
    state = np.empty(3)
    trial = np.empty(sstate.shape[0])
    setpoint = np.empty(n)
    seen = np.empty(n)
    run = np.empty(n)
    T = feed[PERIOD]
    for k in range(n_max):
        # --- supervisor check on the last tick's signals (a trip: Python runs this period) ---
        if cs[SUPERVISED] != 0.0:
            for i in range(n):
                error = check[PREV_COMMAND, i] - check[PREV_ACTUAL, i]
                limit = check[FERR_LIMIT, i]
                if limit > 0.0 and (error > limit or -error > limit):
                    return k
            if cs[CHECK_SWITCHES] != 0.0:
                for r in range(switches.shape[0]):
                    if (switches[r, 3] * sensordata[int(switches[r, 2])] >= 0.0
                            and int(switches[r, 1]) & (SWITCH_LIMIT_POS | SWITCH_LIMIT_NEG)):
                        return k
            if cs[SAT_LIMIT] != 0.0:
                for i in range(n):
                    count = istate[SATURATIONS, i]
                    run[i] = check[SAT_RUN, i] + 1 if count - check[SAT_SEEN, i] >= cs[TICKS] else 0.0
                    seen[i] = count
                    if run[i] >= cs[SAT_LIMIT]:
                        return k
            if cs[MAX_FORCE] > 0.0 and cs[PREV_FORCE] > cs[MAX_FORCE]:
                return k
        started = c_clock.monotonic_ns(timespec) if timed else 0
        if mode == CURVE:
            # --- the feed along the block (SegmentInterpolator._advance_block) ---
            if feed[HAS_STATE] != 0.0:
                s_now, v, a_now = feed[S_NOW], feed[V_NOW], feed[A_NOW]
            else:
                _scurve_state(phases, times, feed[DURATION], feed[LENGTH], feed[V0], v1, feed[TAU], state)
                s_now, v, a_now = state[0], state[1], state[2]
            if feed[OPEN_END] != 0.0:
                remaining = feed[LENGTH] - s_now + feed[QUEUED_PATH]
                lam = feed[LAM]
                if remaining <= _stop_distance(lam * v, lam * lam * a_now, feed[A_STOP], feed[J_STOP], T):
                    return k  # the starved hold latches here
            tau = feed[TAU] + feed[LAM] * T
            if not tau < feed[DURATION]:
                return k  # the block ends within this period
            _scurve_state(phases, times, feed[DURATION], feed[LENGTH], feed[V0], v1, tau, state)
            ds = state[0] - feed[S_DONE]
            # --- the curve, tentatively (committed below) ---
            trial[:] = sstate
            if ds > 0.0:
                curve_kernel.step(ev, correct, ds, trial, sscratch)
            for i in range(n):
                pose[i] = trial[2 + 2 * d + i] if i < 3 else check[HOLD, i - 3]
            if tilting:  # Curve.pose: the tool axis at u, then the head's inverse kinematics
                span_kernel.evaluate_span(a_starts, a_blocks, a_lo, a_hi, a_d, trial[0], a_h, direction, a_c1, a_c2)
                _pose_to_axes(trial[2 + 2 * d:2 + 3 * d], direction, head[0], head[1], pose)
            for i in range(n):
                setpoint[i] = (pose[i] - check[POWER_ON, i]) * check[CPU, i]
        elif mode == MOVE:  # SegmentInterpolator._advance_move and Trapezoid.evaluate
            tau = feed[TAU] + feed[LAM] * T
            if tau >= feed[DURATION] - 1e-9 * T:
                return k  # the move ends within this period
            t_acc, a = feed[T_ACC], feed[ACCEL]
            if tau <= 0.0:
                s = 0.0
            elif tau < t_acc:
                s = 0.5 * a * tau * tau
            elif tau < t_acc + feed[T_FLAT]:
                s = 0.5 * a * t_acc * t_acc + feed[V0] * (tau - t_acc)
            else:
                rest = feed[DURATION] - tau
                s = 1.0 - 0.5 * a * rest * rest if rest > 0.0 else 1.0
            for i in range(n):
                setpoint[i] = move[0, i] + s * move[1, i]
        else:  # a dwell holds the setpoint
            if feed[DWELL_LEFT] - 1.0 <= 0.0:
                return k  # the dwell ends in this period
            for i in range(n):
                setpoint[i] = move[0, i]
        if timed:
            interp_ns[k] = c_clock.monotonic_ns(timespec) - started
        # --- soft limits (a clamp: Python runs this period) ---
        if cs[SUPERVISED] != 0.0:
            for i in range(n):
                if setpoint[i] < check[SOFT_LO, i] or setpoint[i] > check[SOFT_HI, i]:
                    return k
        # --- commit the period ---
        if cs[SUPERVISED] != 0.0 and cs[SAT_LIMIT] != 0.0:
            for i in range(n):
                check[SAT_SEEN, i] = seen[i]
                check[SAT_RUN, i] = run[i]
        if mode == CURVE:
            feed[TAU] = tau
            feed[S_DONE] = state[0]
            feed[S_NOW], feed[V_NOW], feed[A_NOW] = state[0], state[1], state[2]
            feed[HAS_STATE] = 1.0
            sstate[:] = trial
            path_u[k] = trial[0]
            path_ds[k] = ds
        else:
            if mode == MOVE:
                feed[TAU] = tau
            else:
                feed[DWELL_LEFT] -= 1.0
            path_u[k] = -1.0
            path_ds[k] = 0.0
        inv_t = cs[INV_T]
        for i in range(n):  # ServoTask.begin_period: the feed-forward terms
            fstate[P_PREV, i] = fstate[P_NEXT, i]
            fstate[P_NEXT, i] = setpoint[i]
            velocity = (fstate[P_NEXT, i] - fstate[P_PREV, i]) * inv_t
            fstate[ACCELERATION, i] = (velocity - fstate[VELOCITY, i]) * inv_t
            fstate[VELOCITY, i] = velocity
        row = row0 + k * row_step
        servo_kernel.run_ticks(model_ptr, data_ptr, substeps, fparams, fstate, istate, scalars, fractions,
                                 tick_commands, False, qpos, ctrl, sensordata, force_adr, rec_command, rec_actual,
                                 rec_dac, rec_force, row)
        last = row + tpp - 1
        for i in range(n):
            check[PREV_COMMAND, i] = rec_command[last, i]
            check[PREV_ACTUAL, i] = istate[POSITION32, i]
        cs[PREV_FORCE] = rec_force[last]
    return n_max


class PeriodBatch:
    """Runs the steady middle of curve blocks, moves and dwells many periods per call (see the
    module docstring). ``periods`` counts the periods it ran.

    Parameters
    ----------
    dsp : the card's period task; its servo must be driven by ``kernel``.
    kernel : the compiled servo period.
    recorder : the run's recorder.
    """

    def __init__(self, dsp, kernel, recorder):
        self.dsp, self.kernel, self.recorder = dsp, kernel, recorder
        self.interp = dsp.interpolator
        self.servo = dsp.servo
        n = self.servo.n_axes
        self.check = np.zeros((N_CHECK, n))
        self.cs = np.zeros(N_CHECK_SCALARS)
        self.feed = np.zeros(N_FEED)
        self.move = np.zeros((2, n))
        self.path_u = np.zeros(MAX_BATCH)
        self.path_ds = np.zeros(MAX_BATCH)
        self.interp_ns = np.zeros(MAX_BATCH, dtype=np.int64)
        self._timespec = c_clock.timespec()
        interp = self.interp
        self.check[POWER_ON] = interp.power_on
        self.check[CPU] = interp.counts_per_unit
        self.cs[INV_T] = self.servo._inv_period
        self.feed[PERIOD] = interp.period
        sup = dsp.supervisor
        self.check[SOFT_LO], self.check[SOFT_HI] = -np.inf, np.inf
        if sup is not None:
            self.cs[SUPERVISED] = 1.0
            for i, limit in sup._ferr_limit:
                self.check[FERR_LIMIT, i] = limit
            for i, lo, hi in sup._soft:
                self.check[SOFT_LO, i], self.check[SOFT_HI, i] = lo, hi
            self.cs[SAT_LIMIT] = sup._sat_limit
            self.cs[TICKS] = sup.ticks_per_period
            self.cs[MAX_FORCE] = sup.config.max_force
            self.cs[CHECK_SWITCHES] = 1.0 if sup.check_switches and dsp.read_inputs is not None else 0.0
        plant_switches = getattr(getattr(dsp.read_inputs, "__self__", None), "_switches", [])
        self.switches = np.array([(i, bit, adr, sign) for i, bit, adr, sign in plant_switches],
                                 dtype=np.float64).reshape(-1, 4)
        self._segment = None
        self._no_curve = (curve_kernel.NO_PATH, True)
        self._no_stepper = (np.zeros(curve_kernel.state_size(3)), np.zeros(curve_kernel.scratch_size(3)))
        self._no_phases = (np.zeros((7, 5)), np.zeros(7))
        self._no_axis = (np.zeros(0), np.zeros((0, 2, 12)), 0.0, 1.0, 3, np.zeros((2, 3)))
        self.periods = 0
        """periods run in batches so far"""

    def warm_up(self) -> None:
        """Compile the batch kernel (or load it from numba's cache) now, not in the timed run: a
        call of no periods with arguments of the run's types."""
        rec = self.recorder
        servo_args = self._servo_args((rec.command[:0], rec.actual[:0], rec.dac[:0], rec.pad_force[:0]), 0, 0)
        # no periods: nothing is read or written, only the argument types count
        run_periods(0, CURVE, servo_args, self.feed, *self._no_phases, 0.0, self._no_curve, *self._no_stepper,
                    self._no_axis, self.move, self.check, self.cs, self.switches, self.path_u, self.path_ds, False,
                    self.interp_ns, self._timespec)

    def _servo_args(self, columns: tuple, row0: int, row_step: int) -> tuple:
        """``servo_args`` of :func:`run_periods`: the compiled servo's arrays, the recorder's
        ``columns`` (command, actual, dac, pad_force) and the first row and rows per period."""
        kernel = self.kernel
        return (kernel._model_ptr, kernel._data_ptr, kernel.substeps, kernel.fparams, kernel.fstate, kernel.istate,
                kernel.scalars, kernel.fractions, kernel.tick_commands, *kernel._args_plant, *columns, row0, row_step)

    def _mode(self, k: int) -> int | None:
        """What period ``k`` would run, if it can be batched; else None."""
        dsp, interp = self.dsp, self.interp
        if (dsp.state != DspState.RUNNING or dsp.stop is not None or not dsp.drives_enabled or dsp.planner_lost
                or dsp.retract is not None or not dsp.port.solo):
            return None
        # the card's liveness check of this period, as DspTask.begin_period makes it: a lost
        # planner leaves the period to the Python task, which raises the fault
        if k % SOLO_LIVENESS_PERIODS == 0 and not dsp.port.planner_alive():
            return None
        current = interp._current
        if current is None or interp.hold or interp._starved_hold or interp.spindle_on or interp._spin != 0.0 \
                or interp._c_offset != 0.0 or interp.force.state != ForceState.OFF:
            return None
        if interp.wants_records(QUEUE_AHEAD) and dsp.port.fifo.fill() != 0:
            return None
        segment = current[1]
        if isinstance(segment, MoveSegment):
            return MOVE if interp.override == min(interp.override_target, interp._lam_max) else None
        if isinstance(segment, Dwell):
            return DWELL
        curve = getattr(segment, "curve", None)
        if (isinstance(curve, Curve) and isinstance(curve.stepper, CompiledCurveStepper)
                and isinstance(segment.profile, SCurve) and interp._path_accel is None
                and interp.override == interp.override_target * interp.force.feed_factor):
            return CURVE
        return None

    def run(self, k: int, t: int, n_max: int) -> int:
        """Run up to ``n_max`` periods from period ``k``, recorder tick ``t``; how many ran (0 when
        period ``k`` cannot be batched: the caller runs it on the Python task)."""
        n_max = min(n_max, MAX_BATCH, SOLO_LIVENESS_PERIODS - k % SOLO_LIVENESS_PERIODS)  # one check per batch
        mode = self._mode(k) if n_max > 0 else None
        if mode is None:
            return 0
        dsp, interp, servo, kernel, rec = self.dsp, self.interp, self.servo, self.kernel, self.recorder
        kernel.load()
        segment = interp._current[1]
        feed, check, cs, move = self.feed, self.check, self.cs, self.move
        feed[TAU], feed[LAM] = interp._tau, interp.override
        phases, times, v1 = self._no_phases[0], self._no_phases[1], 0.0
        curve_args, (sstate, sscratch), axis_args = self._no_curve, self._no_stepper, self._no_axis
        if mode == CURVE:
            prof = segment.profile
            if self._segment is not segment:
                self._segment = segment
                self._phases = np.array(prof._starts, dtype=np.float64)
                self._times = np.array(prof._times, dtype=np.float64)
                check[HOLD, :3] = segment.curve.hold
                tool_axis = segment.curve.axis
                self._axis_args = self._no_axis if tool_axis is None else (
                    tool_axis.starts, np.ascontiguousarray(tool_axis.blocks), float(tool_axis.domain[0]),
                    float(tool_axis.domain[1]), tool_axis.dim,
                    np.array([segment.curve.pivot, segment.curve.offset], dtype=np.float64))
            axis_args = self._axis_args
            stepper = segment.curve.stepper
            phases, times, v1 = self._phases, self._times, prof.v1
            curve_args, sstate, sscratch = (stepper._args, stepper.correct), stepper._state, stepper._scratch
            feed[S_DONE] = interp._s
            feed[QUEUED_PATH] = interp._queued_path
            feed[A_STOP], feed[J_STOP] = SLEW_MARGIN * prof.a_max, SLEW_MARGIN * prof.j_max
            open_end = interp._path_open if interp._queue else prof.v1 > 0.0
            feed[OPEN_END] = 1.0 if open_end else 0.0
            feed[LENGTH], feed[DURATION], feed[V0] = prof.length, prof.duration, prof.v0
            state = interp._block_state
            feed[HAS_STATE] = 0.0 if state is None else 1.0
            if state is not None:
                feed[S_NOW], feed[V_NOW], feed[A_NOW] = state
        elif mode == MOVE:
            prof = segment.profile
            feed[DURATION], feed[T_ACC], feed[ACCEL] = prof.duration, prof.t_acc, prof.accel
            feed[T_FLAT], feed[V0] = prof.t_flat, prof.v_peak
            move[0], move[1] = interp._start_counts, interp._delta_counts
        else:
            feed[DWELL_LEFT] = interp._dwell_left
            move[0] = interp._hold_counts
        n = servo.n_axes
        frame = servo.frame
        check[PREV_COMMAND] = frame[0:n]
        check[PREV_ACTUAL] = frame[n:2 * n]
        cs[PREV_FORCE] = frame[3 * n]
        sup = dsp.supervisor
        if sup is not None:
            check[SAT_SEEN], check[SAT_RUN] = sup._sat_seen, sup._sat_run
        kernel.take_setpoint()
        servo_args = self._servo_args((rec.command, rec.actual, rec.dac, rec.pad_force), rec.row(t),
                                      0 if rec.scratch else len(kernel.fractions))
        # DspTask times the interpolation on a curve and on the way to one (its first block queued)
        timed = c_clock.AVAILABLE and (interp.path_u >= 0.0 or interp.on_curve)
        done = run_periods(n_max, mode, servo_args, feed, phases, times, v1, curve_args, sstate, sscratch, axis_args,
                           move, check, cs, self.switches, self.path_u, self.path_ds, timed, self.interp_ns,
                           self._timespec)
        if done:
            self._commit(mode, segment, k, t, done)
            if timed:
                dsp.interpolator_ns.extend(self.interp_ns[:done].tolist())
            self.periods += done
        return done

    def _commit(self, mode: int, segment, k: int, t: int, done: int) -> None:
        """Leave every object as the Python task would after period ``k + done - 1``."""
        dsp, interp, servo, kernel, rec = self.dsp, self.interp, self.servo, self.kernel, self.recorder
        feed, check = self.feed, self.check
        if mode == CURVE:
            stepper = segment.curve.stepper
            stepper.u = float(stepper._state[0])
            stepper.point = stepper._state[stepper._point].tolist()
            interp._tau, interp._s = float(feed[TAU]), float(feed[S_DONE])
            interp._block_state = (float(feed[S_NOW]), float(feed[V_NOW]), float(feed[A_NOW]))
        elif mode == MOVE:
            interp._tau = float(feed[TAU])
        else:
            interp._dwell_left = int(feed[DWELL_LEFT])
        interp.path_u, interp.path_ds = float(self.path_u[done - 1]), float(self.path_ds[done - 1])
        fstate = kernel.fstate
        interp._hold_counts = fstate[P_NEXT].tolist()  # the last setpoint: no force, spindle or offset
        interp.tick_commands = None
        interp.events = []
        servo._p_prev, servo._p_next = fstate[P_PREV].tolist(), fstate[P_NEXT].tolist()
        servo._velocity, servo._acceleration = fstate[VELOCITY].tolist(), fstate[ACCELERATION].tolist()
        servo._tick_commands = None
        sup = dsp.supervisor
        if sup is not None and sup._sat_limit:
            sup._sat_seen[:] = [int(x) for x in check[SAT_SEEN]]
            sup._sat_run[:] = [int(x) for x in check[SAT_RUN]]
        # the servo frame as the last period left it: the last tick, then the per-period fields
        kernel.leave_frame(rec, rec.row(t + done * len(kernel.fractions) - 1), saturated=True)
        dsp.write_period_fields(0)  # a batched period raises no events
        # the period records: the fields that stay constant, then the path
        periods = rec.periods[0:1] if rec.scratch else rec.periods[k:k + done]
        periods[:] = tuple(servo.frame[servo.period_slot:])
        if not rec.scratch:
            periods["path_u"] = self.path_u[:done]
            periods["path_ds"] = self.path_ds[:done]


def kernels_cached() -> bool:
    """Whether numba's on-disk cache holds the batch and servo kernels already (False on the first
    run after installing, which compiles them: about 8 s). Reads numba's cache index paths; True
    when they cannot be found out (nothing to warn about then)."""
    try:
        from pathlib import Path

        return all(Path(kernel._cache._cache_file._index_path).exists()
                   for kernel in (run_periods, servo_kernel.run_ticks))
    except AttributeError:  # another numba's internals
        return True

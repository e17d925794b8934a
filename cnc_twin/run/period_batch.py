"""The card's side of the period batch: when a period can be batched, the kernel's arguments from
the card's objects, and the objects left as the Python task would leave them.

:func:`cnc_twin.run.period_kernel.run_periods` runs the periods (see that module for what a batch
does and where it ends); :class:`PeriodBatch` decides per period whether one may start
(``PeriodBatch._mode``), hands the kernel the state of the card, the force loop, the spindle,
the path and the removal map, and after the call writes back everything the Python task would
have changed (``PeriodBatch._commit``), so the next period, batched or not, starts from the
same state.
"""

from __future__ import annotations

import math

import numpy as np

from cnc_twin.dsp import curve_stepper
from cnc_twin.dsp.force import ForceState
from cnc_twin.dsp.path_blocks import SLEW_MARGIN, Block, ForceWait, SurfaceRun
from cnc_twin.dsp.supervisor import LIMITS, SUPERVISOR
from cnc_twin.dsp.task import QUEUE_AHEAD, SOLO_LIVENESS_PERIODS, TIMED_PERIODS
from cnc_twin.motion.segments import MoveSegment
from cnc_twin.polishing import removal_kernel
from cnc_twin.run import c_clock
from cnc_twin.run.period_kernel import (AXIS_STATE, CHECK, CURVE, DWELL, FEED, FORCE_WAIT, MAX_BATCH, MOVE, OUT,
                                         PROCESS, run_periods)
from cnc_twin.whiteboard.records import Dwell
from cnc_twin.whiteboard.status import DspState


_NO_SWITCHES = np.zeros((0, 4), dtype=np.int64)


class PeriodBatch:
    """Runs the steady middle of curve blocks (surface paths with the force loop tracking and the
    spindle at speed included), moves and dwells many periods per call. ``periods`` counts the
    periods it ran.

    Parameters
    ----------
    dsp
        the card's period task; its servo must be driven by ``kernel``.
    kernel
        the compiled servo period.
    recorder
        the run's recorder.
    removal
        the run's removal map (:class:`~cnc_twin.polishing.polish.RemovalTracker`, compiled),
        updated inside the batch every ``removal.every`` periods; None without one.
    switches
        the plant's switches (:attr:`~cnc_twin.machine.plant.Plant.switches`); None: none.
    """

    def __init__(self, dsp, kernel, recorder, removal=None, *, switches: np.ndarray = None):
        self.dsp, self.kernel, self.recorder, self.removal = dsp, kernel, recorder, removal
        self.interp = dsp.interpolator
        self.servo = dsp.servo
        n = self.servo.n_axes
        # the kernel's records (cnc_twin.run.period_kernel documents their fields)
        self.axis_state = np.zeros(n, AXIS_STATE)
        self.check = np.zeros(1, CHECK)
        self.feed = np.zeros(1, FEED)
        self.move = np.zeros((2, n))
        self.process = np.zeros(1, PROCESS)
        self.out = np.zeros(MAX_BATCH, OUT)
        self.interp_ns = np.zeros(MAX_BATCH, dtype=np.int64)
        self._timespec = c_clock.timespec()
        interp = self.interp
        self.axis_state["power_on"] = interp.power_on
        self.axis_state["counts_per_unit"] = interp.counts_per_unit
        self.check[0]["inv_period"] = self.servo.inv_period
        self.feed[0]["period"] = interp.period
        sup = dsp.supervisor
        if sup is not None:
            self.check[0]["supervised"] = True
            # the plant's switches, read by the card when it has the inputs (DspTask.read_inputs)
            with_inputs = switches is not None and dsp.read_inputs is not None
            self.supervision = (sup.settings, sup.limits, switches if with_inputs else _NO_SWITCHES)
        else:  # nothing is checked (supervised False): records of the right types
            self.supervision = (np.zeros(1, SUPERVISOR), np.zeros(n, LIMITS), _NO_SWITCHES)
        if removal is not None:
            self.process[0]["every"] = removal.every
            self._removal_args = removal.kernel_args()
        else:
            self._removal_args = removal_kernel.no_tracker()
        self._segment = None
        self._no_curve = (curve_stepper.NO_PATH, True, np.zeros(curve_stepper.state_size(3)),
                          np.zeros(curve_stepper.scratch_size(3)))
        self._no_profile = (np.zeros((7, 5)), np.zeros(7), 0.0)
        self._no_axis = (np.zeros(0), np.zeros((0, 2, 12)), 0.0, 1.0, 3, np.zeros((2, 3)))
        self._no_lines = (np.zeros(0), np.zeros(0))
        self.periods = 0
        """periods run in batches so far"""

    def warm_up(self) -> None:
        """Compile the batch kernel (or load it from numba's cache) now, not in the timed run: a
        call of no periods with arguments of the run's types."""
        rec = self.recorder
        servo_args = self._servo_args((rec.command[:0], rec.actual[:0], rec.dac[:0], rec.pad_force[:0], rec.tool[:0]),
                                      0, 0)
        # no periods: nothing is read or written, only the argument types count
        run_periods(0, CURVE, 0, servo_args, self.feed, self._no_profile, self._no_curve, self._no_axis, self.move,
                    self.axis_state, self.check, self.supervision, self.process, self._force_args(), self._no_lines,
                    self._removal_args, self.out, (False, self.interp_ns, self._timespec))

    def _force_args(self) -> tuple:
        """``force_args`` of :func:`run_periods`: the force loop's profile and its record (the
        kernel commits each period into the record itself)."""
        force = self.interp.force
        return force.profile_s, force.profile_f, force.record

    def _servo_args(self, columns: tuple, row0: int, row_step: int) -> tuple:
        """``servo_args`` of :func:`run_periods`: the compiled servo's arguments, the recorder's
        ``columns`` (command, actual, dac, pad_force, tool) and the first row and rows per period."""
        return (*self.kernel.tick_args(), *columns, row0, row_step)

    def _mode(self, k: int) -> int | None:
        """What period ``k`` would run, if it can be batched; else None."""
        dsp, interp = self.dsp, self.interp
        if (dsp.state != DspState.RUNNING or dsp.stop is not None or not dsp.drives_enabled or dsp.planner_lost
                or dsp.retract is not None):
            return None
        # no exchange due: the program all sent, or none under way and the PC waiting for room
        if dsp.port.exchange_due():
            return None
        # the card's liveness check of this period, as DspTask.begin_period makes it: a lost
        # planner leaves the period to the Python task, which raises the fault
        if k % SOLO_LIVENESS_PERIODS == 0 and not dsp.port.planner_alive():
            return None
        current = interp.current
        if current is None or interp.hold or interp.starved_hold:
            return None
        force = interp.force
        if force.frozen:
            return None
        tracking = force.state == ForceState.TRACK
        if self.removal is not None and not self.removal.compiled:
            return None
        if interp.wants_records(QUEUE_AHEAD) and dsp.port.fifo.fill() != 0:
            return None
        segment = current[1]
        mode = BATCHED.get(type(segment))
        if mode == FORCE_WAIT:  # seek, ramp, ramp down, retract (until the state changes)
            return FORCE_WAIT if force.state not in (ForceState.OFF, ForceState.TRACK) else None
        if mode is None or force.state not in (ForceState.OFF, ForceState.TRACK):
            return None
        if mode == MOVE:
            return MOVE if not tracking and interp.override == min(interp.override_target, interp.lam_max) else None
        if mode == DWELL:
            return None if tracking else DWELL
        # a curve block (its profile an S-curve, its path a curve or a surface section)
        if (segment.curve.stepper.compiled and interp.path_accel is None
                and interp.override == interp.override_target * force.feed_factor):
            return CURVE
        return None

    def _curve_args(self, segment) -> None:
        """The per-curve arguments (S-curve phases, held axes or the head's kinematics, line marks),
        once per block."""
        self._segment = segment
        prof, curve, process = segment.profile, segment.curve, self.process
        self._profile = (np.array(prof.phases, dtype=np.float64), np.array(prof.phase_times, dtype=np.float64),
                         prof.v1)
        self._lines = self._no_lines
        process = process[0]
        process["surface"] = False
        if type(curve) is SurfaceRun:
            sf = curve.surface
            process["surface"], process["c_hold"] = True, curve.c_hold
            process["leaned"] = not (sf.lead == 0.0 and sf.tilt == 0.0)
            process["cos_lead"], process["sin_lead"] = math.cos(sf.lead), math.sin(sf.lead)
            process["cos_tilt"], process["sin_tilt"] = math.cos(sf.tilt), math.sin(sf.tilt)
            self._axis_args = (*self._no_axis[:5], np.array([sf.pivot, sf.offset], dtype=np.float64))
            return
        self.axis_state["hold"][:3] = curve.hold
        tool_axis = curve.axis
        self._axis_args = self._no_axis if tool_axis is None else (
            *tool_axis.path[:5], np.array([curve.pivot, curve.offset], dtype=np.float64))
        if curve.line_us:
            self._lines = (np.array(curve.line_us, dtype=np.float64), np.array(curve.line_numbers, dtype=np.float64))

    def run(self, k: int, t: int, n_max: int) -> int:
        """Run up to ``n_max`` periods from period ``k``, recorder tick ``t``; how many ran (0 when
        period ``k`` cannot be batched: the caller runs it on the Python task)."""
        n_max = min(n_max, MAX_BATCH, SOLO_LIVENESS_PERIODS - k % SOLO_LIVENESS_PERIODS)  # one check per batch
        mode = self._mode(k) if n_max > 0 else None
        if mode is None:
            return 0
        dsp, interp, servo, rec = self.dsp, self.interp, self.servo, self.recorder
        segment = interp.current[1]
        feed, move, process, axis_state = self.feed[0], self.move, self.process[0], self.axis_state
        feed["tau"], feed["lam"] = interp.tau, interp.override
        profile, curve_args, axis_args, lines = self._no_profile, self._no_curve, self._no_axis, self._no_lines
        if mode == CURVE:
            prof = segment.profile
            if self._segment is not segment:
                self._curve_args(segment)
            profile, axis_args, lines = self._profile, self._axis_args, self._lines
            stepper = segment.curve.stepper
            curve_args = (stepper.path, stepper.correct, stepper.state, stepper.scratch)
            feed["s_done"] = interp.block_s
            feed["queued_path"] = interp.queued_path
            feed["a_stop"], feed["j_stop"] = SLEW_MARGIN * prof.a_max, SLEW_MARGIN * prof.j_max
            feed["open_end"] = interp.path_open if interp.queue else prof.v1 > 0.0
            feed["length"], feed["duration"], feed["v0"] = prof.length, prof.duration, prof.v0
            state = interp.block_state
            feed["has_state"] = state is not None
            if state is not None:
                feed["s_now"], feed["v_now"], feed["a_now"] = state
        elif mode == MOVE:
            prof = segment.profile
            feed["duration"], feed["t_acc"], feed["accel"] = prof.duration, prof.t_acc, prof.accel
            feed["t_flat"], feed["v0"] = prof.t_flat, prof.v_peak
            move[0], move[1] = interp.start_counts, interp.delta_counts
        elif mode == DWELL:
            feed["dwell_left"] = interp.dwell_left
        else:  # the pose at the path's end, along its tool axis
            move[0] = interp.counts_of(segment.base)
        axis_state["held"] = interp.hold_counts
        force = interp.force
        process["force_on"] = force.state != ForceState.OFF
        process["path_s"], process["c_offset"], process["mark"] = interp.path_s, interp.c_offset, interp.mark
        process["spindle_on"] = interp.spindle_on
        process["spin"] = interp.spin
        process["spin_target"] = interp.spindle_speed if interp.spindle_on else 0.0
        process["spin_step"] = interp.spindle_accel * interp.period
        # the axis the force loop pushes along: a force wait's own (as its periods set it), else the last
        process["axis"] = segment.axis if mode == FORCE_WAIT else interp.tool_axis
        force_args = self._force_args()
        n = servo.n_axes
        frame = servo.frame
        axis_state["prev_command"] = frame[0:n]
        axis_state["prev_actual"] = frame[n:2 * n]
        self.check[0]["prev_force"] = frame[3 * n]
        servo_args = self._servo_args((rec.command, rec.actual, rec.dac, rec.pad_force, rec.tool), rec.row(t),
                                      0 if rec.scratch else servo.ticks_per_period)
        # DspTask times the interpolation on a curve and on the way to one (its first block queued)
        timed = (c_clock.AVAILABLE and (interp.path_u >= 0.0 or interp.on_curve)
                 and len(dsp.interpolator_ns) < TIMED_PERIODS)
        done = run_periods(n_max, mode, k, servo_args, self.feed, profile, curve_args, axis_args, move, axis_state,
                           self.check, self.supervision, self.process, force_args, lines, self._removal_args,
                           self.out, (timed, self.interp_ns, self._timespec))
        if done:
            self._commit(mode, segment, k, t, done)
            if timed:
                dsp.interpolator_ns.extend(self.interp_ns[:done].tolist())
            self.periods += done
        return done

    def _commit(self, mode: int, segment, k: int, t: int, done: int) -> None:
        """Leave every object as the Python task would after period ``k + done - 1``."""
        dsp, interp, servo, rec = self.dsp, self.interp, self.servo, self.recorder
        feed, process, out = self.feed[0], self.process[0], self.out
        if mode == CURVE:
            curve = segment.curve
            curve.stepper.sync()
            interp.tau, interp.block_s = float(feed["tau"]), float(feed["s_done"])
            interp.block_state = (float(feed["s_now"]), float(feed["v_now"]), float(feed["a_now"]))
            if type(curve) is SurfaceRun:
                interp.path_s = float(process["path_s"])
                curve.axis = tuple(process["axis"].tolist())
        elif mode == MOVE:
            interp.tau = float(feed["tau"])
        elif mode == DWELL:
            interp.dwell_left = int(feed["dwell_left"])
        interp.path_u, interp.path_ds = float(out[done - 1]["path_u"]), float(out[done - 1]["path_ds"])
        interp.mark = int(process["mark"])
        interp.tool_axis = tuple(process["axis"].tolist())
        interp.c_offset = float(process["c_offset"])
        interp.spin = float(process["spin"])
        interp.hold_counts = self.axis_state["held"].tolist()  # the last path setpoint: no force or spindle offset
        interp.tick_commands = None
        interp.events = []
        servo.use_tick_commands = False
        # the servo frame as the last period left it: the last tick, then the per-period fields
        last = rec.row(t + done * servo.ticks_per_period - 1)
        servo.frame_from(rec.command[last], rec.pad_force[last])
        dsp.write_period_fields(0)  # a batched period raises no events
        # the period records: the fields that stay constant, then those that change per period
        periods = rec.periods[0:1] if rec.scratch else rec.periods[rec.period_row(k):rec.period_row(k) + done]
        periods[:] = tuple(servo.frame[servo.period_slot:])
        if not rec.scratch:
            periods["path_u"] = out["path_u"][:done]
            periods["path_ds"] = out["path_ds"][:done]
            periods["force_setpoint"] = out["target"][:done]
            periods["force_depth"] = out["depth"][:done]
            periods["mark"] = out["mark"][:done]


BATCHED = {Block: CURVE, MoveSegment: MOVE, Dwell: DWELL, ForceWait: FORCE_WAIT}
"""the running items whose periods may be batched, and how; the others (step runs, chip commands)
always run on the card's Python task"""

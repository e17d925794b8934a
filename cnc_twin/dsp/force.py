"""The card's grinding-force loop: seek contact, ramp, hold the force along the path, retract.

Runs once per interpolation period on the load-cell force from the 12-bit ADC (tared at
servo-on). Its output is ``depth`` [m]: how far the tool is pushed along the tool axis beyond the
nominal pose (the pad face on the surface); the interpolator adds ``-depth * axis`` to the X/Y/Z
setpoint, so the position loops carry the force loop (position-based force control)::

    OFF        depth = 0
    SEEK       depth += seek_speed * T, from -standoff          until F >= contact_threshold
    RAMP       F* from the contact force to the path's setpoint over ramp_time; PI
    TRACK      F* = setpoint(path length) (linear in the profile); PI; the path runs
    RAMP_DOWN  F* from the last setpoint to 0 over ramp_time; PI
    RETRACT    depth -= retract_speed * T                        until depth = -standoff -> OFF

    PI:        e = F* - F;   I += ki e T;   depth = I + kp e
               I and depth clamped to [-standoff, max_depth]; I frozen while the sum is clamped
               in the direction of e (anti-windup)

While SEEK, RAMP, RAMP_DOWN and RETRACT run, the path holds (``path_gate``). Feed adaptation in
TRACK: when ``|e| > adapt_threshold * F*`` the feed factor drops to ``adapt_feed``; it returns
to 1 once ``|e|`` has stayed below half the threshold for ``adapt_hold`` (hysteresis, so the feed
does not chatter); the interpolator slews the feed within the path's acceleration limits.

The loop's state is a :data:`FORCE` record (its interface; :func:`force_update` is its one
algorithm, compiled with numba and called by :class:`ForceController` from Python and by the
period batch, :mod:`cnc_twin.run.period_kernel`, on the same record):

=================  =======  ==============================================  ========================
field              unit     meaning                                         written by
=================  =======  ==============================================  ========================
kp                 m/N      proportional gain                               ``start``
ki                 m/(N s)  integral gain                                   ``start``
lo                 m        -standoff: the depth's lower clamp              ``start``
hi                 m        max_depth: its upper clamp                      ``start``
adapt_threshold    -        feed adaptation's relative force error          ``start``
adapt_feed         -        the feed factor while adapting                  ``start``
adapt_hold         s        calm time before the feed returns               ``start``
setpoint           N        the force without a profile                     ``start``
period             s        the interpolation period                        set up
seek_speed         m/s      the seek's approach speed                       ``start``
retract_speed      m/s      the retract's speed                             ``start``
ramp_time          s        the ramps' duration (0: a step)                 ``start``
contact_threshold  N        the force that ends the seek                    ``start``
integral           m        the PI's integral                               :func:`force_update`
depth              m        the push along the tool axis (output)           :func:`force_update`
target             N        the force setpoint in effect                    :func:`force_update`
feed_factor        -        the feed adaptation's factor                    :func:`force_update`
calm               s        time the error has stayed small                 :func:`force_update`
t                  s        time in the state                               :func:`force_update`
state              -        :class:`ForceState`                             :func:`force_update`
ramp_from          N        the ramp's start force                          :func:`force_update`
contact_time       s        when the seek touched (NaN: not yet)            :func:`force_update`
frozen             0 / 1    depth held (the supervisor's retract)           the period task
=================  =======  ==============================================  ========================

The force profile (path lengths [m] and forces [N], empty for a constant setpoint) is two arrays
beside the record (:attr:`ForceController.profile_s`, :attr:`ForceController.profile_f`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnc_twin.core.config import ForceControl
from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.geometry import span_eval
from cnc_twin.geometry.span_eval import bisect_right

# force_update calls span_eval.bisect_right: recompile it when that changes
purge_stale(__file__, [span_eval.__file__])


class ForceState:
    """The force loop's states, the record's ``state``: 0 to 5 from ``OFF`` to ``RETRACT`` (the
    module docstring's order); ``NAMES`` their names."""

    OFF, SEEK, RAMP, TRACK, RAMP_DOWN, RETRACT = range(6)
    NAMES = ("OFF", "SEEK", "RAMP", "TRACK", "RAMP_DOWN", "RETRACT")


_PARAMS = ("kp", "ki", "lo", "hi", "adapt_threshold", "adapt_feed", "adapt_hold", "setpoint", "period",
           "seek_speed", "retract_speed", "ramp_time", "contact_threshold")
FORCE = np.dtype([(name, np.float64) for name in _PARAMS]
                 + [(name, np.float64) for name in ("integral", "depth", "target", "feed_factor", "calm", "t")]
                 + [("state", np.int64), ("ramp_from", np.float64), ("contact_time", np.float64),
                    ("frozen", np.int64)])
"""the force loop's record: see the module docstring for its fields"""

_OFF, _SEEK, _RAMP, _TRACK, _RAMP_DOWN, _RETRACT = range(6)


@njit(cache=True)
def setpoint_at(force, xs, fs, path_s):
    """The programmed force at path length ``path_s`` [m] (N): the profile ``xs`` [m], ``fs`` [N]
    interpolated linearly, held beyond its ends; empty: ``force.setpoint``."""
    n = xs.shape[0]
    if n == 0:
        return force.setpoint
    i = bisect_right(xs, path_s)
    if i == 0:
        return fs[0]
    if i == n:
        return fs[n - 1]
    x0, x1 = xs[i - 1], xs[i]
    return fs[i - 1] + (fs[i] - fs[i - 1]) * (path_s - x0) / (x1 - x0)


@njit(cache=True)
def _pi(force, error):
    """The PI step with its clamp and anti-windup (module docstring)."""
    lo, hi = force.lo, force.hi
    integral = force.integral + force.ki * error * force.period
    depth = integral + force.kp * error
    if depth > hi or depth < lo:
        depth = min(hi, max(lo, depth))
        if (depth >= hi and error > 0.0) or (depth <= lo and error < 0.0):
            integral = force.integral  # anti-windup: no further integration into the clamp
    force.integral = min(hi, max(lo, integral))
    force.depth = depth


@njit(cache=True)
def _adapt(force, error):
    """TRACK's feed adaptation with hysteresis (module docstring)."""
    limit = force.adapt_threshold * abs(force.target)
    if limit <= 0.0:
        return
    if abs(error) > limit:
        force.feed_factor = force.adapt_feed
        force.calm = 0.0
    elif force.feed_factor < 1.0:
        force.calm = force.calm + force.period if abs(error) < 0.5 * limit else 0.0
        if force.calm >= force.adapt_hold:
            force.feed_factor = 1.0


@njit(cache=True)
def force_update(force, xs, fs, measured, path_s):
    """One period of the loop in ``force`` (a :data:`FORCE` record): the new depth [m] from the
    measured force [N] and the path length so far [m]; ``xs``, ``fs`` the force profile."""
    state, T = force.state, force.period
    if state == _OFF:
        return 0.0
    if force.frozen != 0:
        return force.depth
    force.t += T
    if state == _SEEK:
        force.depth = min(force.depth + force.seek_speed * T, force.hi)
        force.integral = force.depth
        if measured >= force.contact_threshold:
            force.state = _RAMP
            force.contact_time = force.t
            force.ramp_from = measured
            force.t = 0.0
        return force.depth
    if state == _RETRACT:
        force.depth = max(force.depth - force.retract_speed * T, force.lo)
        if force.depth <= force.lo:
            force.state = _OFF
        return force.depth
    if state == _RAMP:
        goal = setpoint_at(force, xs, fs, path_s)
        frac = min(1.0, force.t / force.ramp_time) if force.ramp_time > 0 else 1.0
        force.target = force.ramp_from + (goal - force.ramp_from) * frac
        if frac >= 1.0:
            force.state = _TRACK
    elif state == _TRACK:
        force.target = setpoint_at(force, xs, fs, path_s)
    else:  # RAMP_DOWN
        frac = min(1.0, force.t / force.ramp_time) if force.ramp_time > 0 else 1.0
        force.target = force.ramp_from * (1.0 - frac)
        if frac >= 1.0:
            force.state = _RETRACT
    error = force.target - measured
    _pi(force, error)
    if state == _TRACK:
        _adapt(force, error)
    return force.depth


class ForceController:
    """Per-period force loop of the card: :func:`force_update` on its :attr:`~ForceController.record`.

    Parameters
    ----------
    period : interpolation period [s].
    """

    def __init__(self, period: float):
        self.record = np.zeros(1, FORCE)
        """the loop's :data:`FORCE` record, shape ``(1,)`` (the compiled batch works on it too)"""
        self._r = self.record[0]
        self._r["period"] = period
        self._r["feed_factor"] = 1.0
        self._r["contact_time"] = math.nan
        self.profile_s = np.zeros(0)
        """the force profile's path lengths [m] (empty: the constant setpoint)"""
        self.profile_f = np.zeros(0)
        """the force profile's forces [N]"""

    period = property(lambda self: float(self._r["period"]), doc="interpolation period [s]")
    state = property(lambda self: int(self._r["state"]), doc=":class:`ForceState`")
    depth = property(lambda self: float(self._r["depth"]),
                     doc="tool-axis offset into the surface [m] (negative: standing off)")
    target = property(lambda self: float(self._r["target"]), doc="force setpoint in effect this period [N]")
    feed_factor = property(lambda self: float(self._r["feed_factor"]), doc="the feed adaptation's factor")

    @property
    def contact_time(self) -> float | None:
        """time of first contact since the seek started [s], None before"""
        value = float(self._r["contact_time"])
        return None if math.isnan(value) else value

    @property
    def frozen(self) -> bool:
        """depth held as it is (the supervisor's retract after a force fault)"""
        return bool(self._r["frozen"])

    @frozen.setter
    def frozen(self, value: bool) -> None:
        self._r["frozen"] = 1 if value else 0

    @property
    def path_gate(self) -> bool:
        """The path must hold: contact is being made or released."""
        return self.state not in (ForceState.OFF, ForceState.TRACK)

    def start(self, params: ForceControl) -> None:
        """Begin the seek from ``standoff`` above the nominal pose."""
        r = self._r
        for name, value in zip(_PARAMS, (params.kp, params.ki, -params.standoff, params.max_depth,
                                         params.adapt_threshold, params.adapt_feed, params.adapt_hold,
                                         params.setpoint, r["period"], params.seek_speed, params.retract_speed,
                                         params.ramp_time, params.contact_threshold)):
            r[name] = value
        self.profile_s = np.array([s for s, _ in params.profile], dtype=np.float64)
        self.profile_f = np.array([f for _, f in params.profile], dtype=np.float64)
        r["state"] = ForceState.SEEK
        r["depth"] = r["integral"] = -params.standoff
        r["target"] = 0.0
        r["feed_factor"] = 1.0
        r["contact_time"] = math.nan
        r["t"] = 0.0

    def stop(self) -> None:
        """Ramp the force down, then retract to the standoff."""
        r = self._r
        if r["state"] == ForceState.OFF:
            return
        r["state"] = ForceState.RAMP_DOWN
        r["ramp_from"] = r["target"]
        r["t"] = 0.0
        r["feed_factor"] = 1.0

    def setpoint_at(self, path_s: float) -> float:
        """The programmed force at path length ``path_s`` [m] (N)."""
        return setpoint_at(self._r, self.profile_s, self.profile_f, path_s)

    def update(self, measured: float, path_s: float) -> float:
        """One period: the new depth [m] from the measured force [N] and the path length so far [m]."""
        return force_update(self._r, self.profile_s, self.profile_f, measured, path_s)

    def warm_up(self) -> None:
        """Compile :func:`force_update` (or load it from numba's cache) now, on a copy."""
        force_update(self.record.copy()[0], self.profile_s, self.profile_f, 0.0, 0.0)

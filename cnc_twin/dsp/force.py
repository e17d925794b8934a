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
"""

from __future__ import annotations

import bisect

from cnc_twin.core.config import ForceControl


class ForceState:
    OFF, SEEK, RAMP, TRACK, RAMP_DOWN, RETRACT = range(6)
    NAMES = ("OFF", "SEEK", "RAMP", "TRACK", "RAMP_DOWN", "RETRACT")


class ForceController:
    """Per-period force loop of the card.

    Parameters
    ----------
    period : interpolation period [s].
    """

    def __init__(self, period: float):
        self.period = period
        self.state = ForceState.OFF
        self.depth = 0.0
        """tool-axis offset into the surface [m] (negative: standing off)"""
        self.target = 0.0
        """force setpoint in effect this period [N]"""
        self.feed_factor = 1.0
        self.contact_time: float | None = None
        """time of first contact since the controller started [s after start]"""
        self._p: ForceControl | None = None
        self._integral = 0.0
        self._t = 0.0
        self._ramp_from = 0.0
        self._calm = 0.0
        self._profile_s: list[float] = []
        self._profile_f: list[float] = []
        self.frozen = False
        """depth held as it is (the supervisor's retract after a force fault)"""

    @property
    def path_gate(self) -> bool:
        """The path must hold: contact is being made or released."""
        return self.state not in (ForceState.OFF, ForceState.TRACK)

    def start(self, params: ForceControl) -> None:
        """Begin the seek from ``standoff`` above the nominal pose."""
        self._p = params
        self._profile_s = [s for s, _ in params.profile]
        self._profile_f = [f for _, f in params.profile]
        self.state = ForceState.SEEK
        self.depth = self._integral = -params.standoff
        self.target = 0.0
        self.feed_factor = 1.0
        self.contact_time = None
        self._t = 0.0

    def stop(self) -> None:
        """Ramp the force down, then retract to the standoff."""
        if self.state == ForceState.OFF:
            return
        self.state = ForceState.RAMP_DOWN
        self._ramp_from = self.target
        self._t = 0.0
        self.feed_factor = 1.0

    def setpoint_at(self, path_s: float) -> float:
        """The programmed force at path length ``path_s`` [m] (N)."""
        p = self._p
        xs, fs = self._profile_s, self._profile_f
        if not xs:
            return p.setpoint
        i = bisect.bisect_right(xs, path_s)
        if i == 0:
            return fs[0]
        if i == len(xs):
            return fs[-1]
        x0, x1 = xs[i - 1], xs[i]
        return fs[i - 1] + (fs[i] - fs[i - 1]) * (path_s - x0) / (x1 - x0)

    def update(self, measured: float, path_s: float) -> float:
        """One period: the new depth [m] from the measured force [N] and the path length so far [m]."""
        state, p, T = self.state, self._p, self.period
        if state == ForceState.OFF:
            return 0.0
        if self.frozen:
            return self.depth
        self._t += T
        if state == ForceState.SEEK:
            self.depth = min(self.depth + p.seek_speed * T, p.max_depth)
            self._integral = self.depth
            if measured >= p.contact_threshold:
                self.state = ForceState.RAMP
                self.contact_time = self._t
                self._ramp_from = measured
                self._t = 0.0
            return self.depth
        if state == ForceState.RETRACT:
            self.depth = max(self.depth - p.retract_speed * T, -p.standoff)
            if self.depth <= -p.standoff:
                self.state = ForceState.OFF
            return self.depth
        if state == ForceState.RAMP:
            goal = self.setpoint_at(path_s)
            frac = min(1.0, self._t / p.ramp_time) if p.ramp_time > 0 else 1.0
            self.target = self._ramp_from + (goal - self._ramp_from) * frac
            if frac >= 1.0:
                self.state = ForceState.TRACK
        elif state == ForceState.TRACK:
            self.target = self.setpoint_at(path_s)
        else:  # RAMP_DOWN
            frac = min(1.0, self._t / p.ramp_time) if p.ramp_time > 0 else 1.0
            self.target = self._ramp_from * (1.0 - frac)
            if frac >= 1.0:
                self.state = ForceState.RETRACT
        error = self.target - measured
        self._pi(error)
        if state == ForceState.TRACK:
            self._adapt(error)
        return self.depth

    def _pi(self, error: float) -> None:
        p = self._p
        lo, hi = -p.standoff, p.max_depth
        integral = self._integral + p.ki * error * self.period
        depth = integral + p.kp * error
        if depth > hi or depth < lo:
            depth = min(hi, max(lo, depth))
            if (depth >= hi and error > 0.0) or (depth <= lo and error < 0.0):
                integral = self._integral  # anti-windup: no further integration into the clamp
        self._integral = min(hi, max(lo, integral))
        self.depth = depth

    def _adapt(self, error: float) -> None:
        p = self._p
        limit = p.adapt_threshold * abs(self.target)
        if limit <= 0.0:
            return
        if abs(error) > limit:
            self.feed_factor = p.adapt_feed
            self._calm = 0.0
        elif self.feed_factor < 1.0:
            self._calm = self._calm + self.period if abs(error) < 0.5 * limit else 0.0
            if self._calm >= p.adapt_hold:
                self.feed_factor = 1.0

"""The removal map's update, compiled: the contact patch, its Preston removal and the pad's
friction wrench in one call (:func:`~cnc_twin.polishing.removal_kernel.removal_step`), and the
whole update of :class:`~cnc_twin.polishing.polish.RemovalTracker` from MuJoCo's data
(:func:`~cnc_twin.polishing.removal_kernel.tracker_update`: the pad's contact force from its
contact sensor, the tip's velocity, the ball of candidates, the step, the wrench into
``xfrc_applied``), which the polishing batch calls between periods.

:meth:`~cnc_twin.polishing.removal.PrestonModel.patch`, :meth:`~cnc_twin.polishing.removal.PrestonModel.add`
and :func:`~cnc_twin.polishing.polish.friction_wrench` are the reference (numpy over the
candidate points). :func:`removal_step` does the same arithmetic point by point in a numba
kernel: every product and sum in the same order (the references add term by term:
``sequential_sum``, no BLAS dot, no einsum), the same passes that drop the points below the pad
until the level holds, no fast-math; so the two agree bit for bit (``tests/test_removal_kernel.py``), and a
polishing run's trace is the same either way.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.machine import mujoco_c

# the whole update calls MuJoCo through mujoco_c's bindings: recompile when they change
purge_stale(__file__, [mujoco_c.__file__])

# the tracker's totals (float64): what RemovalTracker.update accumulates
CONTACT_TIME, FORCE_TIME, CALLS, COST_NS, MOST_CONTACTS = range(5)
N_TOTALS = 5
# the tracker's parameters (float64)
RADIUS, SLAB, MODULUS, K_DT, MU, FRICTION_SPEED, DT, BALL_R2, MARGIN2 = range(9)
N_PARAMS = 9
# the tracker's ids (int64): the tool site, the pad body, the contact sensor's address and slots
SITE, PAD_BODY, SENSOR_ADR, SLOTS, FIELDS = range(5)
_MJOBJ_SITE = 6
"""``mujoco.mjtObj.mjOBJ_SITE``"""


@njit(cache=True, error_model="numpy")
def removal_step(ball_idx, ball, tip, a, force, radius, slab, modulus, k_dt, v_tip, omega, centre, mu,
                 friction_speed, depth, wrench):
    """One update of the removal map ``depth`` (in place) and the pad's friction ``wrench`` (6,)
    about ``centre`` (written; zero without contact). ``ball_idx`` (m,), ``ball`` (7, m): the
    candidate points (x y z nx ny nz area) near the ``tip``; ``a`` the unit tool axis; ``force``
    [N]; ``k_dt`` Preston's k times the update's interval. Returns how many points got removal,
    or -1 when the pad touches none (no removal added, as the reference adds no patch)."""
    for i in range(6):
        wrench[i] = 0.0
    if not force > 0:
        return -1
    m = ball_idx.shape[0]
    r2max = radius * radius
    sel = np.empty(m, dtype=np.int64)
    hh = np.empty(m)
    aa = np.empty(m)
    # first h and the test of every point, branch-free (the compiler vectorises it); then the
    # candidates in index order with the sums the first level needs (sequential_sum(A),
    # sequential_sum(A * h): each its own running sum, so fused into one pass the same bits)
    a0, a1, a2, q0, q1, q2 = a[0], a[1], a[2], tip[0], tip[1], tip[2]  # the axis, the tip
    inside = np.empty(m, dtype=np.bool_)
    for j in range(m):
        r0, r1, r2 = ball[0, j] - q0, ball[1, j] - q1, ball[2, j] - q2
        h = (a0 * r0 + a1 * r1) + a2 * r2
        rho2 = ((r0 * r0 + r1 * r1) + r2 * r2) - h * h
        facing = (a0 * ball[3, j] + a1 * ball[4, j]) + a2 * ball[5, j]
        hh[j] = h
        inside[j] = (rho2 <= r2max) & (abs(h) <= slab) & (facing > 0)
    k = 0
    w_sum = 0.0
    ah = 0.0
    for j in range(m):
        if inside[j]:
            area = ball[6, j]
            h = hh[j]
            sel[k] = j
            hh[k] = h
            aa[k] = area
            w_sum += area
            ah += area * h
            k += 1
    if k == 0:
        return -1
    h = hh
    c = force / modulus
    if not w_sum > 0:
        return -1
    delta = (c - ah) / w_sum
    # drop the points below the pad at this level and solve again, until every point kept
    # touches (PrestonModel._contact: the same passes, the same sums in the same order, each
    # accumulated as its points are kept)
    while True:
        all_touch = True
        for i in range(k):  # a reduction the compiler vectorises: most levels keep every point
            all_touch &= h[i] + delta > 0
        if all_touch:
            break
        n = 0
        w_sum = 0.0
        ah = 0.0
        for i in range(k):
            if h[i] + delta > 0:
                sel[n] = sel[i]
                h[n] = h[i]
                aa[n] = aa[i]
                w_sum += aa[n]
                ah += aa[n] * h[n]
                n += 1
        if n == k:
            break
        k = n
        delta = (c - ah) / w_sum
    # the kept points' rows gathered, then per point (branch-free, vectorised) the pressure, the
    # tangential sliding, the removal and the friction force and torque, then the sums in index
    # order (friction_wrench's sequential sums)
    w = np.empty((13, k))
    d0, d1, d2 = q0 - centre[0], q1 - centre[1], q2 - centre[2]
    for i in range(k):
        j = sel[i]
        w[0, i] = ball[0, j] - q0
        w[1, i] = ball[1, j] - q1
        w[2, i] = ball[2, j] - q2
        w[3, i] = ball[3, j]
        w[4, i] = ball[4, j]
        w[5, i] = ball[5, j]
        w[6, i] = ball[6, j]
    o0, o1, o2, u0, u1, u2 = omega[0], omega[1], omega[2], v_tip[0], v_tip[1], v_tip[2]
    for i in range(k):
        r0, r1, r2, n0, n1, n2 = w[0, i], w[1, i], w[2, i], w[3, i], w[4, i], w[5, i]
        p = modulus * (h[i] + delta)
        v0 = (o1 * r2 - o2 * r1) + u0
        v1 = (o2 * r0 - o0 * r2) + u1
        v2 = (o0 * r1 - o1 * r0) + u2
        vn = (v0 * n0 + v1 * n1) + v2 * n2
        v0, v1, v2 = v0 - vn * n0, v1 - vn * n1, v2 - vn * n2
        speed = math.sqrt((v0 * v0 + v1 * v1) + v2 * v2)
        scale = -mu * p * w[6, i] / max(speed, friction_speed)
        fx, fy, fz = v0 * scale, v1 * scale, v2 * scale
        e0, e1, e2 = r0 + d0, r1 + d1, r2 + d2
        w[6, i] = p
        w[7, i] = k_dt * p * speed
        w[8, i], w[9, i], w[10, i] = fx, fy, fz
        w[11, i] = e1 * fz - e2 * fy
        w[12, i] = e2 * fx - e0 * fz
        w[0, i] = e0 * fy - e1 * fx
    touched = pressed = 0
    f0 = f1 = f2 = t0 = t1 = t2 = 0.0
    for i in range(k):
        if not w[6, i] > 0:
            continue
        pressed += 1
        inc = w[7, i]
        depth[ball_idx[sel[i]]] += inc
        if inc > 0:
            touched += 1
        f0 += w[8, i]
        f1 += w[9, i]
        f2 += w[10, i]
        t0 += w[11, i]
        t1 += w[12, i]
        t2 += w[0, i]
    if pressed == 0:  # the reference's patch is empty: no removal step, no wrench
        return -1
    wrench[0], wrench[1], wrench[2], wrench[3], wrench[4], wrench[5] = f0, f1, f2, t0, t1, t2
    return touched


@njit(cache=True, error_model="numpy")
def contact_force(sensordata, ids, ax0, ax1, ax2, totals):
    """The pad's contact normal force along the (not necessarily unit) axis ``ax`` [N], as
    :meth:`~cnc_twin.polishing.polish.RemovalTracker.contact_force`: slot by slot of the contact
    sensor, in MuJoCo's contact order; ``totals[MOST_CONTACTS]`` keeps the most contacts seen."""
    adr, slots, fields = ids[SENSOR_ADR], ids[SLOTS], ids[FIELDS]
    found = int(sensordata[adr])
    if found > totals[MOST_CONTACTS]:
        totals[MOST_CONTACTS] = found
    total = 0.0
    for i in range(min(found, slots)):
        base = adr + fields * i
        dot = (sensordata[base + 4] * ax0 + sensordata[base + 5] * ax1) + sensordata[base + 6] * ax2
        total += sensordata[base + 1] * abs(dot)
    return total


BALL_CHUNK = 32
"""consecutive grid points per bounding box of :func:`chunk_boxes`"""


def chunk_boxes(packed: np.ndarray) -> np.ndarray:
    """Bounding boxes (6, chunks) [m] (x y z low, x y z high) of every :data:`BALL_CHUNK`
    consecutive points of ``packed`` (7, m): the grid's rows run along the surface, so a chunk is
    a short strip, and a ball far from its box holds none of its points."""
    starts = np.arange(0, packed.shape[1], BALL_CHUNK)
    return np.ascontiguousarray(np.vstack([np.minimum.reduceat(packed[:3], starts, axis=1),
                                           np.maximum.reduceat(packed[:3], starts, axis=1)]))


@njit(cache=True, error_model="numpy")
def _refresh_ball(packed, boxes, tip, limit2, ball_idx, ball):
    """The grid points within the ball around ``tip`` into ``ball_idx`` / ``ball`` (their first
    columns), in index order; how many. As :meth:`PrestonModel._ball_around` and its gather, the
    same points: a chunk is skipped only when its box is farther (each difference to the box
    rounds to at most the point's own, so the box's squared distance is at most the point's)."""
    q0, q1, q2 = tip[0], tip[1], tip[2]
    m = packed.shape[1]
    n = 0
    for c in range(boxes.shape[1]):
        dx = max(boxes[0, c] - q0, q0 - boxes[3, c], 0.0)
        dy = max(boxes[1, c] - q1, q1 - boxes[4, c], 0.0)
        dz = max(boxes[2, c] - q2, q2 - boxes[5, c], 0.0)
        if (dx * dx + dy * dy) + dz * dz > limit2:
            continue
        for j in range(c * BALL_CHUNK, min((c + 1) * BALL_CHUNK, m)):
            r0, r1, r2 = packed[0, j] - q0, packed[1, j] - q1, packed[2, j] - q2
            if (r0 * r0 + r1 * r1) + r2 * r2 <= limit2:
                ball_idx[n] = j
                n += 1
    for row in range(7):
        for i in range(n):
            ball[row, i] = packed[row, ball_idx[i]]
    return n


if mujoco_c.IMPORT_ERROR is None:
    _mj_object_velocity = mujoco_c.mj_objectVelocity

    @njit(cache=True, error_model="numpy")
    def tracker_update(model_ptr, data_ptr, sensordata, xmat, site_xpos, xipos, xfrc, ids, params, packed, boxes,
                       depth, ball_idx, ball, ball_state, velocity, totals):  # pragma: no cover - compiled
        """One update of the removal map from MuJoCo's data, as
        :meth:`~cnc_twin.polishing.polish.RemovalTracker.update` on the reference path:
        ``xfrc[pad body]`` gets the friction wrench (zero without contact), ``depth`` the removal,
        ``totals`` the figures. ``ball_state``: the ball's centre (3) and size;
        ``velocity`` (6,) scratch."""
        site, body = ids[SITE], ids[PAD_BODY]
        ax0, ax1, ax2 = xmat[body, 2], xmat[body, 5], xmat[body, 8]  # the pad's z axis
        force = contact_force(sensordata, ids, ax0, ax1, ax2, totals)
        wrench = xfrc[body]
        for i in range(6):
            wrench[i] = 0.0
        if force > 0.0:
            _mj_object_velocity(model_ptr, data_ptr, _MJOBJ_SITE, site, velocity.ctypes.data, 0)
            tip = site_xpos[site]
            norm = math.sqrt((ax0 * ax0 + ax1 * ax1) + ax2 * ax2)
            a = np.empty(3)
            a[0], a[1], a[2] = ax0 / norm, ax1 / norm, ax2 / norm
            o0, o1, o2 = tip[0] - ball_state[0], tip[1] - ball_state[1], tip[2] - ball_state[2]
            if not (o0 * o0 + o1 * o1) + o2 * o2 <= params[MARGIN2]:
                ball_state[3] = _refresh_ball(packed, boxes, tip, params[BALL_R2], ball_idx, ball)
                ball_state[0], ball_state[1], ball_state[2] = tip[0], tip[1], tip[2]
            n = int(ball_state[3])
            touched = removal_step(ball_idx[:n], ball[:, :n], tip, a, force, params[RADIUS], params[SLAB],
                                   params[MODULUS], params[K_DT], velocity[3:], velocity[:3], xipos[body], params[MU],
                                   params[FRICTION_SPEED], depth, wrench)
            if touched >= 0:
                totals[CONTACT_TIME] += params[DT]
            totals[FORCE_TIME] += force * params[DT]
        totals[CALLS] += 1.0


def no_tracker() -> tuple:
    """Arguments of :func:`tracker_update`'s types for a run without a removal map (never called)."""
    return (0, 0, np.zeros(1), np.zeros((1, 9)), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 6)),
            np.zeros(5, dtype=np.int64), np.zeros(N_PARAMS), np.zeros((7, 0)), np.zeros((6, 0)), np.zeros(0),
            np.zeros(0, dtype=np.intp),
            np.zeros((7, 0)), np.zeros(4), np.zeros(6), np.zeros(N_TOTALS))

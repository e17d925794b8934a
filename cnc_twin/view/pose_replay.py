"""Body poses of many axis positions in one compiled call (numba around ``mj_kinematics``).

Used by ``cnc_twin.view.rerun_export._Kinematics`` in the twin's own process, where numba is
loaded anyway; the recording process keeps to the Python loop (5.7 us a pose) rather than pay
numba's import and load (0.3 s of CPU) for a few thousand poses.
"""

from __future__ import annotations

from numba import njit

from cnc_twin.machine import mujoco_c

_mj_kinematics = mujoco_c.mj_kinematics


@njit(cache=True)
def replay(model_ptr, data_ptr, q, adr, qpos, xpos, xquat, site_xpos, site_xmat, tool, pos, quat, tips,
           axes):  # pragma: no cover - compiled; the Python loop in _Kinematics.poses is its twin
    """For each row of ``q`` (n, 6): set the joints ``adr`` of ``qpos``, run ``mj_kinematics``
    and copy the body poses, the ``tool`` site's position and its z axis into the outputs."""
    for k in range(q.shape[0]):
        for i in range(adr.shape[0]):
            qpos[adr[i]] = q[k, i]
        _mj_kinematics(model_ptr, data_ptr)
        pos[k] = xpos
        quat[k] = xquat
        tips[k] = site_xpos[tool]
        for r in range(3):
            axes[k, r] = site_xmat[tool, 3 * r + 2]

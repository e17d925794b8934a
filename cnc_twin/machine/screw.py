"""Ball screws whose stiffness depends on where the nut is.

A feed axis's screw tendon (``<axis>_screw`` in the MJCF: L = table - (lead / 2 pi) motor angle)
carries the axial chain's stiffness: the fixed bearing pair, the nut and the housings in series
with the screw shaft between the fixed bearing and the nut. The shaft's part is E A / a, ``a`` the
nut's distance from the fixed bearing, so the chain is stiffest with the nut near the motor and
softest at the far end of the travel (a screw fixed at the motor end and supported at the other,
as catalogue stiffness formulas give it)::

    k(q) = 1 / (1 / k_rest + a(q) / EA),    a(q) = a0 + side q

with ``q`` the table's position [m]. The MJCF gives each such screw as a custom numeric
``<axis>_screw_chain`` of four values: ``k_rest`` [N/m] (bearings, nut, housings), ``EA`` [N]
(the shaft: Young's modulus x root section), ``a0`` [m] (the nut's distance from the fixed
bearing at q = 0) and ``side`` (+1: the distance grows with q; -1: it shrinks). MuJoCo's tendon
stiffness is a model constant; :func:`screw_stiffness` writes each screw's ``k(q)`` into it
before every physics step (the Python plant and the compiled servo kernel call it as they call
the amplifiers), so the resonance a tuner meets depends on where it measures, as on a real machine.
The MJCF's own ``stiffness`` attribute is the value at the home keyframe (the model as compiled is
right at home; :func:`~cnc_twin.machine.model_file.load_model` holds the two to agree). The tendon's damping stays as entered.

=========  ======  ===================================================
field      unit    meaning
=========  ======  ===================================================
tendon     -       the screw tendon's id
qpos_adr   -       the table joint's qpos address
k_rest     N/m     bearings, nut and housings
ea         N       the shaft's E A
a0         m       the nut's distance from the fixed bearing at q = 0
side       -       +1 or -1: how a grows with q
=========  ======  ===================================================
"""

from __future__ import annotations

import mujoco
import numpy as np
from numba import njit

from cnc_twin.core.axes import AXES, joint_name
from cnc_twin.machine.model_file import chain_name, chain_stiffness

_chain_stiffness = njit(cache=True, nogil=True)(chain_stiffness)

SCREW = np.dtype([("tendon", np.int64), ("qpos_adr", np.int64), ("k_rest", np.float64), ("ea", np.float64),
                  ("a0", np.float64), ("side", np.float64)])
"""one screw's record: see the module docstring"""


def setup_screws(model: mujoco.MjModel) -> np.ndarray:
    """The model's position-dependent screws, :data:`SCREW` records (shape ``(n,)``; none on a
    machine without ``<axis>_screw_chain`` numerics, such as the rigid one)."""
    rows = []
    for axis in AXES:
        numeric = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, chain_name(axis))
        if numeric < 0:
            continue
        k_rest, ea, a0, side = (float(v) for v in model.numeric(numeric).data)
        tendon = model.tendon(f"{axis.lower()}_screw").id
        rows.append((tendon, model.joint(joint_name(axis)).qposadr[0], k_rest, ea, a0, side))
    return np.array(rows, dtype=SCREW)


@njit(cache=True, nogil=True)
def screw_stiffness(screws, qpos, tendon_stiffness):
    """Each screw's chain stiffness [N/m] where its table is (``qpos``) into MuJoCo's
    ``tendon_stiffness`` (the model's array, shape ``(ntendon,)``); ``screws``: :data:`SCREW`."""
    for i in range(screws.shape[0]):
        s = screws[i]
        tendon_stiffness[s.tendon] = _chain_stiffness(s.k_rest, s.ea, s.a0, s.side, qpos[s.qpos_adr])


__all__ = ["SCREW", "screw_stiffness", "setup_screws"]

"""MuJoCo's C functions for compiled (numba) kernels: ``mj_step``, ``mj_kinematics``, ``mj_objectVelocity``.

The kernels link them by name from MuJoCo's shared library (the one the ``mujoco`` package
ships and has already loaded) and take ``MjModel._address`` / ``MjData._address`` as the
pointers. Arrays of ``MjData`` (``qpos``, ``ctrl``, ``xpos``, ...) are views of the same memory,
so a kernel reads and writes them directly between calls. :func:`available` says whether this
works here; callers keep a Python path for when it does not.

A MuJoCo error inside a compiled call is not turned into a Python exception (the bindings do
that only for their own calls): keep compiled calls to models the Python path has run.
"""

from __future__ import annotations

import os
from pathlib import Path

IMPORT_ERROR: str | None = None
try:
    import llvmlite.binding as _llvm
    import mujoco
    from numba import types

    _libs = sorted(Path(os.path.dirname(mujoco.__file__)).glob("libmujoco.so*"))
    if not _libs:
        raise ImportError("libmujoco.so not found next to the mujoco package")
    _llvm.load_library_permanently(str(_libs[0]))
    mj_step = types.ExternalFunction("mj_step", types.void(types.voidptr, types.voidptr))
    """``mj_step(model_ptr, data_ptr)`` inside a numba kernel"""
    mj_kinematics = types.ExternalFunction("mj_kinematics", types.void(types.voidptr, types.voidptr))
    """``mj_kinematics(model_ptr, data_ptr)`` inside a numba kernel"""
    mj_objectVelocity = types.ExternalFunction("mj_objectVelocity", types.void(
        types.voidptr, types.voidptr, types.int32, types.int32, types.voidptr, types.int32))
    """``mj_objectVelocity(model_ptr, data_ptr, objtype, objid, result.ctypes.data, flg_local)`` inside a
    numba kernel: ``result`` (6,) float64 gets the object's [angular, linear] velocity"""
except ImportError as exc:  # pragma: no cover - numba and mujoco are dependencies
    IMPORT_ERROR = str(exc)


def available() -> bool:
    """Whether compiled kernels can call MuJoCo here (numba, the shared library, ``_address``)."""
    return IMPORT_ERROR is None and hasattr(mujoco.MjModel, "_address")


def address(obj) -> int:
    """The C pointer of a ``mujoco.MjModel`` or ``mujoco.MjData`` for a kernel's ``voidptr``
    argument (the bindings' ``_address``, the one place the project reads it)."""
    return obj._address

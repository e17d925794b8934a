"""The warm server: one background process that has loaded numpy, MuJoCo, numba's compiled kernels
and the package once, and forks a process for each ``cnc-twin run``, ``validate``, ``gcode``,
``list`` or ``schema`` that becomes the command (with the caller's streams, directory, environment and limits),
so that a short command costs its own work instead of a new interpreter's imports. The client's
side is :mod:`cnc_twin.core.server_link`; the server is :mod:`~cnc_twin.server.daemon`; the forked
command is :mod:`~cnc_twin.server.runner`.

May import: every part below it and cli (what it loads ahead). Imported by: none (started as
``python -m cnc_twin.server.daemon``; the command that becomes a client imports
:mod:`cnc_twin.core.server_link` only).
"""

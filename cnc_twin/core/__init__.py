"""The core: what every part of the twin shares, with no heavy imports (the planner process loads it).

- :mod:`~cnc_twin.core.config`         the validated scenario in SI units: frozen dataclasses
- :mod:`~cnc_twin.core.axes`           the six axes, their order and MJCF names; the home keyframe; switch bits
- :mod:`~cnc_twin.core.units`          the unit conversion factors (scenario units -> SI)
- :mod:`~cnc_twin.core.errors`         :class:`~cnc_twin.core.errors.ScenarioError`, one line naming file, key path
  and problem
- :mod:`~cnc_twin.core.child_process`  ending a helper process (planner, recorder): EOF, SIGTERM, SIGKILL
- :mod:`~cnc_twin.core.messages`       pickled messages over a pipe to a helper process (recorder, paths helper)
- :mod:`~cnc_twin.core.kernel_cache`   numba's on-disk cache purged when a compiled kernel's other sources change
- :mod:`~cnc_twin.core.packed_text`    a long program's text held compressed, written out a piece at a time
- :mod:`~cnc_twin.core.spill`          arrays a run needs only at its end, kept in an unlinked temporary file
- :mod:`~cnc_twin.core.heap`           the heap's free pages given back before a run
- :mod:`~cnc_twin.core.phases`         where a command's time goes: marks for the start-up benchmark

May import: nothing of cnc_twin. Imported by: every other part.
"""

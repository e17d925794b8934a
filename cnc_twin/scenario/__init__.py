"""Reading a scenario: YAML in machinist units, validated strictly, converted to SI once
(:class:`cnc_twin.core.config.Scenario`). Every problem is one :class:`~cnc_twin.core.errors.ScenarioError`.

- :mod:`~cnc_twin.scenario.load`        :func:`~cnc_twin.scenario.load.load_scenario`: read, merge the machine parameters,
  validate, convert; one table of program kinds
- :mod:`~cnc_twin.scenario.machine`     axes, encoders, servo gains, the three rates, planner and whiteboard settings
- :mod:`~cnc_twin.scenario.points`, :mod:`~cnc_twin.scenario.curve`, :mod:`~cnc_twin.scenario.surface`,
  :mod:`~cnc_twin.scenario.contour`, :mod:`~cnc_twin.scenario.chip`, :mod:`~cnc_twin.scenario.gcode`  one module
  per program kind: its schema and conversion (an NC program's set-up in ``gcode_setup``, its probes in
  ``gcode_probe``, its reading as a stream into steps in ``gcode_read``)
- :mod:`~cnc_twin.scenario.faults`      the ``faults:`` and ``supervisor:`` keys
- :mod:`~cnc_twin.scenario.schema_base`, :mod:`~cnc_twin.scenario.validation`  shared schema pieces; the first error as one line
- :mod:`~cnc_twin.scenario.overrides`   dotted-path overrides (``servo.X.kp``) for scripts and sweeps
- :mod:`~cnc_twin.scenario.resources`   the bundled models and scenarios
- :mod:`~cnc_twin.scenario.program_cache`  a G-code program's preparation kept on disk, keyed by what it is made from

May import: core, motion, geometry, legacy, whiteboard, machine, planner, polishing (a program is
checked against the machine's travel and reach, and a surface path planned, before any motion).
Imported by: studies, cli.
"""

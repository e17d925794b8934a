"""RS274/NGC programs (G-code) as LinuxCNC reads them, checked call for call against its
interpreter (``scripts/fetch_linuxcnc_oracle.py``).

- :mod:`~cnc_twin.gcode.expressions`   ``[...]`` expressions, functions and parameters
- :mod:`~cnc_twin.gcode.blocks`        one line read into a block: words, comments, N, ``/``, O-words,
  parameter settings applied after the line
- :mod:`~cnc_twin.gcode.modal`         G and M codes into modal groups, refused as LinuxCNC refuses them

May import: ``core``. Imported by: (the program kind that runs G-code, to come).
"""

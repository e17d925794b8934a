"""RS274/NGC programs (G-code) as LinuxCNC reads them, checked call for call against its
interpreter (``scripts/fetch_linuxcnc_oracle.py``).

- :mod:`~cnc_twin.gcode.expressions`   ``[...]`` expressions, functions and parameters
- :mod:`~cnc_twin.gcode.long_double`   C's ``long double`` angles (numpy, imported on first use)
- :mod:`~cnc_twin.gcode.blocks`        one line read into a block: words, comments, N, ``/``, O-words,
  parameter settings applied after the line
- :mod:`~cnc_twin.gcode.modal`         G and M codes into modal groups, refused as LinuxCNC refuses them; the
  groups and codes by name (``GGroup``, ``MGroup``, ``G``, ``M``)
- :mod:`~cnc_twin.gcode.checks`        a block's words checked before it runs; what the machine lacks refused
- :mod:`~cnc_twin.gcode.source`        a file's lines (one text, their offsets), ``%`` markers, O-word lines
  for jumps
- :mod:`~cnc_twin.gcode.reading`       a line read with the refusals LinuxCNC makes while reading (codes in
  order, a bad byte named, M98 / M99 lines)
- :mod:`~cnc_twin.gcode.subfiles`      subroutine files found as LinuxCNC finds them (``name.ngc``)
- :mod:`~cnc_twin.gcode.flow`          O-word control flow: subroutines, branches, loops
- :mod:`~cnc_twin.gcode.comments`      ``(msg,...)``, ``(debug,...)``, ``(print,...)``, ``(log,...)``
- :mod:`~cnc_twin.gcode.state`         modes, current point, work offsets, tool table, read-only parameters
- :mod:`~cnc_twin.gcode.arcs`          G2 / G3 geometry and checks, bit for bit as LinuxCNC
- :mod:`~cnc_twin.gcode.nurbs`         G5.2 / G5.3 and G6.2 curves into NURBS
- :mod:`~cnc_twin.gcode.motion`        the motion step of a block
- :mod:`~cnc_twin.gcode.interpreter`   a whole program run into canonical calls (or handed out in batches)
- :mod:`~cnc_twin.gcode.outcome`       what a reading gives: its calls, or its refusal
- :mod:`~cnc_twin.gcode.limits`        the bound on a program that does not end (its calls)
- :mod:`~cnc_twin.gcode.common_lines`  a CAM program's common lines run at once (the fast path), as the
  interpreter runs them
- :mod:`~cnc_twin.gcode.canon`         canonical calls and their rs274 text
- :mod:`~cnc_twin.gcode.listing`       ``cnc-twin gcode`` (listed as it is read)
- :mod:`~cnc_twin.gcode.path_ops`, :mod:`~cnc_twin.gcode.toolpath`, :mod:`~cnc_twin.gcode.feed_paths`,
  :mod:`~cnc_twin.gcode.line_fit`, :mod:`~cnc_twin.gcode.extents`  the calls into the operations a
  machine runs, as they come: what they are, the canon's offsets, feed paths (joins, fits, blends),
  CAM's G1 runs fitted, how far the tip goes
- :mod:`~cnc_twin.gcode.paths_ahead`   a long program's feed paths fitted in a helper process while the
  reader reads on, handed out in program order

May import: ``core``, ``geometry``. Imported by: ``cli`` (and the program kind that runs G-code).
"""

"""Looking at a run in rerun: the recording (``recording.rrd``) and the viewer.

- :mod:`~cnc_twin.view.rerun_export`  a run as a rerun recording: entity tree, default blueprint, ``send_columns``
- :mod:`~cnc_twin.view.rerun_stream`  the recording process ``cnc-twin run`` feeds during the run
- :mod:`~cnc_twin.view.pose_replay`   the machine's body poses from axis positions (numba, or Python)
- :mod:`~cnc_twin.view.viewer`        starting the rerun viewer with usage analytics off

May import: core, geometry, machine, trace, whiteboard. Imported by: run (``RunResult.write``), studies, cli.
"""

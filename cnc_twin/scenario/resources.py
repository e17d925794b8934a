"""Find the bundled MJCF models and scenarios, installed or in a source checkout.

A wheel carries them inside the package (``cnc_twin/models``, ``cnc_twin/scenarios``); a source
checkout or editable install has them at the repository top level next to ``cnc_twin/``.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent.parent  # cnc_twin/

BUNDLED_MACHINES = {
    "rigid": {"machine.model": "scene_rigid.xml", "machine.parameters": "polisher_rigid.yaml"},
    "compliant": {"machine.model": "scene.xml", "machine.parameters": "polisher.yaml"},
    "uncommissioned": {"machine.model": "scene.xml", "machine.parameters": "polisher_uncommissioned.yaml"},
}
"""The bundled machines by name, each as the scenario overrides that select it: ``rigid`` (every axis
one rigid joint, the drives ideal velocity sources) and ``compliant`` (two-mass feed axes, harmonic
drives, the bridge's rocking mode, drives with their own loops; models/polisher.xml), commissioned
(polisher.yaml: what ``cnc-twin commission`` wrote from polisher_uncommissioned.yaml, the axes'
dynamics matched and reversal and backlash compensation set), and ``uncommissioned``: the same machine
before commissioning. ``cnc-twin run --machine NAME`` runs a scenario on any of them, so they can be
compared."""


def bundled_machine_names(text: str) -> list[str]:
    """A comma-separated list of :data:`BUNDLED_MACHINES` names (a script's ``--machines``), in
    its order; ValueError naming the unknown ones."""
    names = text.split(",")
    unknown = [name for name in names if name not in BUNDLED_MACHINES]
    if unknown:
        raise ValueError(f"{', '.join(unknown)} unknown; the machines are {', '.join(BUNDLED_MACHINES)}")
    return names


def _bundled_dir(name: str) -> Path:
    for candidate in (_PACKAGE_DIR / name, _PACKAGE_DIR.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"bundled '{name}' directory not found next to {_PACKAGE_DIR}")


def models_dir() -> Path:
    """Directory holding the bundled MJCF files and machine parameter files."""
    return _bundled_dir("models")


def bundled_tool_table() -> Path:
    """The bundled machine's LinuxCNC tool table (T1 the pad, T2-T99 generic; lengths in mm),
    which its parameter file names."""
    return models_dir() / "polisher.tbl"


def scenarios_dir() -> Path:
    """Directory holding the bundled scenarios."""
    return _bundled_dir("scenarios")


def programs_dir() -> Path:
    """Directory holding the bundled NC programs."""
    return _bundled_dir("programs")


BUNDLED_SUFFIXES = (".yaml", ".ngc")
"""what a bundled input's name may leave off: a scenario's, a program's"""


def folder_list(text: str) -> tuple[Path, ...]:
    """Folders named on the command line as LinuxCNC's ``SUBROUTINE_PATH`` names them: a
    colon-separated list, in order, ``~`` expanded as LinuxCNC expands it (``subs:~/lib``)."""
    return tuple(Path(part).expanduser() for part in text.split(":") if part)


def input_path(text: str) -> Path:
    """A scenario or NC program named on the command line: the file, where one exists at that path;
    else, for a bare name (no folder in it), the bundled scenario or program of that name, with or
    without its suffix (``nurbs_circle``, ``nurbs_circle.yaml``, ``cam_raster.ngc``,
    ``published/farfalla``); else the path as given, whose loading then says it does not exist.
    A file of the name in the current folder comes first."""
    path = Path(text)
    if path.exists() or path.is_absolute() or text.startswith("."):
        return path
    for folder in (scenarios_dir(), programs_dir()):
        for candidate in (folder / text, *(folder / (text + suffix) for suffix in BUNDLED_SUFFIXES)):
            if candidate.is_file():
                return candidate
    return path


def default_scenario() -> Path:
    """The scenario ``cnc-twin run`` runs when no file is given."""
    return scenarios_dir() / "jog_axes.yaml"


def resolve_model_file(name: str, relative_to: Path | None) -> Path | None:
    """Resolve ``name`` against the scenario's folder first, then the bundled models.

    Returns ``None`` when neither holds the file.
    """
    path = Path(name)
    if path.is_absolute():
        return path if path.is_file() else None
    if relative_to is not None and (relative_to / path).is_file():
        return (relative_to / path).resolve()
    bundled = models_dir() / path
    return bundled if bundled.is_file() else None

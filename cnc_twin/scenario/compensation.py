"""An axis's ``compensation`` key: backlash and a pitch-error table in LinuxCNC's ``COMP_FILE``
format, read into the card's :class:`~cnc_twin.core.axis_config.Compensation`.

The file (LinuxCNC's ``[JOINT_n] COMP_FILE``): one row per line, three numbers separated by
blanks, in the axis's units (mm | deg, machine coordinates): the nominal position, then with
``comp_file_type: 0`` (LinuxCNC's ``COMP_FILE_TYPE = 0``) the positions the axis reaches there
moving forward and in reverse, with ``comp_file_type: 1`` the trims (nominal - position reached)
forward and in reverse. Nominal positions increase; 2 to 256 rows. Blank lines and lines
starting with ``#`` are skipped (LinuxCNC stops reading at the first line that is not three
numbers; here such a line is an error that names it).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from cnc_twin.core import units
from cnc_twin.core.axis_config import COMP_MAX_POINTS as MAX_POINTS
from cnc_twin.core.config import Compensation
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.resources import resolve_model_file
from cnc_twin.scenario.schema_base import KeyedValueError, Strict
from cnc_twin.scenario.yaml_input import read_text


class CompensationSpec(Strict):
    """The card's leadscrew compensation of one axis (LinuxCNC's BACKLASH, COMP_FILE, COMP_FILE_TYPE)."""

    backlash: float = Field(0.0, ge=-10.0, le=10.0, description="[mm | deg] added half each way, by the direction "
                                                                "of motion; negative where the tool leads the motor's "
                                                                "encoder (Siemens' negative backlash)")
    comp_file: str | None = Field(None, description="pitch-error table in LinuxCNC's COMP_FILE format, next to the "
                                                    "scenario or the bundled models")
    comp_file_type: Literal[0, 1] = Field(0, description="0: the file gives the positions reached forward and in "
                                                         "reverse; 1: the trims (nominal - reached)")
    slew: float = Field(10.0, gt=0.0, le=1e4, description="[mm/s | deg/s] the fastest the correction changes")

    @model_validator(mode="after")
    def _one_source_of_backlash(self) -> "CompensationSpec":
        if self.backlash != 0.0 and self.comp_file is not None:
            raise KeyedValueError(("backlash",), "give the backlash in the comp file's forward and reverse columns "
                                                 "or here, not both")
        return self


def read_comp_file(path: Path, file_type: int, factor: float, label: Path, key: str) -> tuple[tuple, tuple, tuple]:
    """``(nominal, forward trim, reverse trim)`` in SI (``factor``: SI per file unit) from the
    table at ``path``; ScenarioError naming the file and line for what is not a table."""
    rows = []
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        try:
            values = [float(word) for word in text.split()]
        except ValueError:
            values = []
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise ScenarioError(label, key, f"{path} line {number}: expected three numbers (nominal, forward, "
                                            f"reverse), got {text[:60]!r}")
        rows.append(values)
    if not 2 <= len(rows) <= MAX_POINTS:
        raise ScenarioError(label, key, f"{path}: expected 2 to {MAX_POINTS} rows, got {len(rows)}")
    for (a, *_), (b, *_), number in zip(rows, rows[1:], range(2, len(rows) + 1)):
        if not b > a:
            raise ScenarioError(label, key, f"{path} row {number}: nominal positions must increase ({a:g} then {b:g})")
    nominal = tuple(r[0] * factor for r in rows)
    if file_type == 0:
        forward = tuple((r[0] - r[1]) * factor for r in rows)
        reverse = tuple((r[0] - r[2]) * factor for r in rows)
    else:
        forward = tuple(r[1] * factor for r in rows)
        reverse = tuple(r[2] * factor for r in rows)
    return nominal, forward, reverse


def convert_compensation(spec: CompensationSpec | None, axis: str, rotary: bool, folder: Path | None,
                         label: Path) -> Compensation | None:
    """The card's :class:`~cnc_twin.core.axis_config.Compensation` of ``axis`` in SI, or None."""
    if spec is None:
        return None
    factor = units.position_factor(rotary)
    key = f"axes.{axis}.compensation.comp_file"
    table: tuple[tuple, tuple, tuple] = ((), (), ())
    if spec.comp_file is not None:
        path = resolve_model_file(spec.comp_file, folder)
        if path is None:
            raise ScenarioError(label, key, f"file '{spec.comp_file}' not found next to the scenario or in the "
                                            "bundled models")
        table = read_comp_file(path, spec.comp_file_type, factor, label, key)
    return Compensation(*table, backlash=spec.backlash * factor, slew=spec.slew * factor)

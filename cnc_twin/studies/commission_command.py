"""``cnc-twin commission``: a machine parameter file commissioned on the circular tests
(:mod:`cnc_twin.studies.commission`), written with its report into a folder."""

from __future__ import annotations

import shutil
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import yaml

from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.resources import models_dir, scenarios_dir

DEFAULT_SOURCE = "polisher_uncommissioned.yaml"
"""the bundled parameter file commissioning starts from by default (the drives and each position
loop tuned on their own, nothing else): what it writes is the bundled default, ``polisher.yaml``"""
SUFFIX = "_uncommissioned"


def commission_command(parameters: Path | None, out: Path | None) -> int:
    """Commission ``parameters`` (default: the bundled :data:`DEFAULT_SOURCE`) and write the
    commissioned parameter file, ``report.md`` and the overlaid polar plots into ``out`` (default
    ``runs/commission-<UTC time>``). Bad input: ScenarioError before any run."""
    from cnc_twin.studies.commission import commission, write_parameters
    from cnc_twin.studies.commission_report import write_report

    source = Path(parameters) if parameters is not None else models_dir() / DEFAULT_SOURCE
    if not source.is_file():
        raise ScenarioError(source, "", "no such parameter file")
    try:
        text = yaml.safe_load(source.read_text())
    except yaml.YAMLError as exc:
        raise ScenarioError(source, "", f"not YAML: {str(exc).splitlines()[0]}") from None
    if not isinstance(text, dict) or not isinstance(text.get("axes"), dict):
        raise ScenarioError(source, "axes", "a machine parameter file with the six axes was expected")
    if out is None:
        out = Path("runs") / f"commission-{datetime.now(timezone.utc):%Y%m%d-%H%M%S}"
    if out.exists() and any(out.iterdir()):
        raise ScenarioError(out, "", "the output folder exists and is not empty")
    out.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()

    def say(line: str) -> None:
        print(f"[{time.monotonic() - started:5.0f} s] {line}", file=sys.stderr, flush=True)

    result = commission(source, scenarios=scenarios_dir(), report=say)
    header = (f"# Commissioned by `cnc-twin commission` from {source.name}: the interpolating axes' dynamics\n"
              "# matched (report.md's first step says how), the acceleration feed-forward as the drives' speed-loop\n"
              "# inverse on the identified inertia (servo.kaff, aff_washout) with the CAD model's inertia coupling\n"
              "# (servo.coupling), the tip's deflection measured on fast circular tests (servo.deflection), reversal\n"
              "# compensation (servo.reversal_*) and backlash compensation (compensation.backlash) set on the\n"
              "# circular tests XY, XZ, YZ; the figures: docs/tuning.md.\n"
              "# Below: the source's own comments, which describe it before commissioning.\n")
    name = source.name.replace(SUFFIX, "") if SUFFIX in source.stem else f"{source.stem}_commissioned{source.suffix}"
    written = write_parameters(source, result.overrides, out / name, header=header)
    table = text.get("tool_table")
    if isinstance(table, str) and (source.parent / table).is_file():  # what the copy names, beside it
        shutil.copy(source.parent / table, out / table)
    for line in result.steps:
        print(line)
    print(f"commissioned parameter file: {written}")
    for path in write_report(result, out):
        print(f"report: {path}")
    return 0

"""Commissioning a machine's parameter file to acceptance on the circular test, as a machine-tool
builder does after the drives: matched position loops, then the reversal compensation, each
step's effect measured on the circular tests XY, XZ, YZ (ISO 230-4, the bundled ``ballbar_*``).

Steps (each callable on its own)::

    before     the three circular tests with the file as it is
    matched    the axes that interpolate together (X Y Z, and A B with them in 5-axis work) get one
               position-loop gain: the lowest of theirs, since each axis's own is the highest its
               margins allow (Siemens and Heidenhain both ask for one kv on interpolating axes: a
               difference draws a 45 deg ellipse of v (1/kv_1 - 1/kv_2) / 2 without feed-forward)
    reversal   X Y Z's reversal compensation (:mod:`cnc_twin.studies.reversal_tuning`)
    after      the three circular tests with the commissioned settings

The result is a set of scenario overrides (``servo.<axis>.<key>``) and the figures before and
after; :func:`write_parameters` writes them into a copy of the parameter file, comments kept.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cnc_twin.studies import reversal_tuning
from cnc_twin.studies.reversal_tuning import PLANES, ReversalSetting

INTERPOLATING = ("X", "Y", "Z", "A", "B")
"""the axes that interpolate together; C (the spindle) runs on its own"""
COMPENSATED = ("X", "Y", "Z")
"""the axes whose reversal compensation the circular tests set (A / B have no circular test here)"""


@dataclass
class Commissioning:
    """What commissioning found: ``overrides`` to apply (``servo.<axis>.<key>``: value, the
    scenario's units), ``before`` / ``after`` the circular tests' metrics per plane, ``steps``
    one line per step saying what it did and why, ``reversal`` each axis's setting."""

    parameters: Path
    overrides: dict[str, float] = field(default_factory=dict)
    before: dict[str, "CircularTest"] = field(default_factory=dict)
    after: dict[str, "CircularTest"] = field(default_factory=dict)
    steps: list[str] = field(default_factory=list)
    reversal: dict[str, ReversalSetting] = field(default_factory=dict)


def machine_overrides(parameters: Path) -> dict[str, str]:
    """The overrides that run a bundled scenario on ``parameters`` (its path made absolute)."""
    return {"machine.parameters": str(Path(parameters).resolve())}


@dataclass(frozen=True)
class CircularTest:
    """One circular test's ``figures`` (metrics.json's ``ballbar``), its ``passes``
    (:class:`~cnc_twin.run.ballbar.BallbarPass`) and its ``test`` (the scenario's
    :class:`~cnc_twin.core.config.BallbarTest`)."""

    figures: dict[str, Any]
    passes: list
    test: Any


def circular_tests(base: Mapping[str, Any], *, scenarios: Path) -> dict[str, CircularTest]:
    """The three circular tests with ``base`` overrides, per plane."""
    from cnc_twin.run.ballbar import ballbar_passes

    out = {}
    for plane in PLANES:
        scenario, result = reversal_tuning.circular_run(plane, base, scenarios=scenarios)
        passes = ballbar_passes(result.trace, scenario.ballbar, scenario.timing.interpolation_period)
        out[plane] = CircularTest(result.metrics["ballbar"], passes, scenario.ballbar)
    return out


def matched_gain(parameters: Path, *, scenarios: Path) -> tuple[float, str]:
    """The common position-loop gain of :data:`INTERPOLATING` [1/s] and a line saying why."""
    from cnc_twin.scenario.load import load_scenario

    scenario = load_scenario(scenarios / "ballbar_xy.yaml", overrides=machine_overrides(parameters))
    gains = {axis: scenario.axis(axis).kp for axis in INTERPOLATING}
    slowest = min(gains, key=gains.get)
    line = (f"matched position loops: {' '.join(f'{a} {g:g}' for a, g in gains.items())} 1/s -> "
            f"{gains[slowest]:g} 1/s on {' '.join(INTERPOLATING)} ({slowest}'s, the lowest: each axis's own is "
            "the highest its margins allow, and axes that interpolate together need one gain)")
    return gains[slowest], line


def commission(parameters: Path, *, scenarios: Path, report: Callable[[str], None] = lambda line: None,
               coulomb: Mapping[str, float] | None = None) -> Commissioning:
    """Run the steps of the module docstring on ``parameters`` (a machine parameter file) with the
    bundled circular tests in ``scenarios``; ``coulomb`` [N | N m] per axis skips identifying it."""
    from cnc_twin.scenario.load import load_scenario

    result = Commissioning(Path(parameters))
    machine = machine_overrides(parameters)
    report("circular tests before commissioning ...")
    result.before = circular_tests(machine, scenarios=scenarios)
    kv, line = matched_gain(parameters, scenarios=scenarios)
    result.steps.append(line)
    report(line)
    result.overrides.update({f"servo.{axis}.kp": kv for axis in INTERPOLATING})
    base = {**machine, **result.overrides}
    scenario = load_scenario(scenarios / "ballbar_xy.yaml", overrides=base)
    for axis in COMPENSATED:
        c = None if coulomb is None else coulomb.get(axis)
        result.reversal[axis] = reversal_tuning.first_setting(scenario, axis, c)
        s = result.reversal[axis]
        report(f"{axis}: first reversal setting from the drive and the identified friction: "
               f"{reversal_tuning.describe(s)}")
    reversal_tuning.search(result.reversal, base, scenarios=scenarios, report=report)
    result.steps.append("reversal compensation on the circular tests XY, XZ, YZ: " + ", ".join(
        f"{a} {reversal_tuning.describe(s)}" for a, s in result.reversal.items()))
    for s in result.reversal.values():
        result.overrides.update(s.overrides())
    report("circular tests after commissioning ...")
    result.after = circular_tests({**machine, **result.overrides}, scenarios=scenarios)
    return result


def yaml_number(value: float) -> str:
    """``value`` as YAML reads it back as a number: plain decimals, never an exponent (PyYAML
    takes ``2e-05`` for a string), at most 6 decimals."""
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return text if text not in ("", "-0") else "0"


def set_flow_keys(text: str, axis: str, mapping: str, values: Mapping[str, float]) -> str:
    """``text`` (a parameter file) with ``values`` set in ``axis``'s ``mapping: {...}`` flow
    mapping (``servo``, ``compensation``): each key's value replaced where it is, added before the
    closing brace where it is not; a mapping the axis lacks is added on a line of its own after its
    ``servo`` mapping. ValueError when the axis (or its servo mapping) is not found."""
    head = re.search(rf"^  {axis}:\s*$", text, re.M)
    if head is None:
        raise ValueError(f"no axis {axis} in the parameter file")
    following = re.search(r"^  \S", text[head.end():], re.M)  # the next axis, or the next top-level key
    end = head.end() + following.start() if following else len(text)
    found = re.compile(rf"({mapping}:\s*\{{)([^}}]*)(\}})", re.S).search(text, head.end(), end)
    if found is None:
        servo = re.compile(r"servo:\s*\{[^}]*\}", re.S).search(text, head.end(), end)
        if servo is None:
            raise ValueError(f"no servo: {{...}} under {axis} in the parameter file")
        line_end = text.index("\n", servo.end())
        values = {key: value for key, value in values.items() if value != 0}
        if not values:  # nothing to add: the mapping's defaults stand
            return text
        body = ", ".join(f"{key}: {yaml_number(value)}" for key, value in values.items())
        return text[:line_end + 1] + f"    {mapping}: {{{body}}}\n" + text[line_end + 1:]
    body = found.group(2)
    added = []
    for key, value in values.items():
        pattern = re.compile(rf"(\b{key}:\s*)([^,}}\s]+)")
        if pattern.search(body):
            body = pattern.sub(lambda m, v=value: m.group(1) + yaml_number(v), body, count=1)
        else:
            added.append(f"{key}: {yaml_number(value)}")
    if added:
        body = body.rstrip() + ",\n             " + ", ".join(added)
    return text[:found.start(2)] + body + text[found.end(2):]


def write_parameters(source: Path, overrides: Mapping[str, float], out: Path, *, header: str = "") -> Path:
    """Write ``source`` with ``overrides`` (``servo.<axis>.<key>``, ``axes.<axis>.<mapping>.<key>``)
    applied to ``out``, ``header`` (comment lines) first; returns it."""
    text = header + Path(source).read_text()
    per_mapping: dict[tuple[str, str], dict[str, float]] = {}
    for path, value in overrides.items():
        parts = path.split(".")
        axis, mapping, key = (parts[1], "servo", parts[2]) if parts[0] == "servo" else parts[1:4]
        per_mapping.setdefault((axis, mapping), {})[key] = value
    for (axis, mapping), values in per_mapping.items():
        text = set_flow_keys(text, axis, mapping, values)
    out.write_text(text)
    return out

"""Commissioning a machine's parameter file to acceptance on the circular test, as a machine-tool
builder does after the drives: matched dynamics, then the reversal compensation, each
step's effect measured on the circular tests XY, XZ, YZ (ISO 230-4, the bundled ``ballbar_*``).

Steps (each callable on its own)::

    before     the three circular tests with the file as it is
    matched    the axes that interpolate together (X Y Z, and A B with them in 5-axis work) follow
               their commands alike: with full velocity feed-forward and equivalent times within
               MISMATCH_LIMIT on the circular tests each keeps its own gain, else all get the
               lowest (:func:`matched_dynamics`; a difference draws a 45 deg ellipse of
               v (1/kv_1 - 1/kv_2) / 2 without feed-forward)
    feed-forward  X Y Z A B's acceleration feed-forward as the inverse of their drives' speed loops
               on the identified inertia, with the CAD model's inertia coupling between them
               (:mod:`cnc_twin.studies.feedforward`)
    deflection the tip's acceleration-dependent deflection against the motor encoders on the
               circular tests, X Y Z, corrected on the card (:mod:`cnc_twin.studies.deflection`)
    reversal   X Y Z's reversal compensation (:mod:`cnc_twin.studies.reversal_tuning`), for moves of
               at least MIN_SPEED_SHARE of the tests' feed, with STANDSTILL_SHARE of its pulse at
               stops and starts (:mod:`cnc_twin.dsp.reversal`); then its pulse's adaptation to the
               acceleration at the reversal, on the tests at twice their feed
               (:func:`~cnc_twin.studies.reversal_tuning.adapt`)
    after      the three circular tests with the commissioned settings

The result is a set of scenario overrides (``servo.<axis>.<key>``) and the figures before and
after; :func:`write_parameters` writes them into a copy of the parameter file, comments kept.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core.config import Scenario
from cnc_twin.studies import reversal_tuning
from cnc_twin.studies.deflection import FEED_FACTOR, deflection_overrides, fast_circular_traces, fit_deflection
from cnc_twin.studies.commissioning import identify_rigid_body
from cnc_twin.studies.feedforward import FeedForward, feed_forward
from cnc_twin.studies.reversal_tuning import CircularTest, ReversalSetting, circular_tests

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
    overrides: dict[str, Any] = field(default_factory=dict)
    before: dict[str, CircularTest] = field(default_factory=dict)
    after: dict[str, CircularTest] = field(default_factory=dict)
    steps: list[str] = field(default_factory=list)
    reversal: dict[str, ReversalSetting] = field(default_factory=dict)
    feed_forward: dict[str, FeedForward] = field(default_factory=dict)
    deflection: dict[str, dict[str, float]] = field(default_factory=dict)
    """[s^2] per axis, per axis whose acceleration deflects its tip"""


def machine_overrides(parameters: Path) -> dict[str, str]:
    """The overrides that run a bundled scenario on ``parameters`` (its path made absolute)."""
    return {"machine.parameters": str(Path(parameters).resolve())}


MIN_SPEED_SHARE = 0.1
"""a reversal counts for the compensation after a move of at least this share of the circular
tests' feed (300 mm/min at their 3 m/min): contouring reversals, not a force loop's small turns"""
STANDSTILL_SHARE = 0.5
"""the share of the reversal pulse given at a stop and at the start after it: the drive's integrator
holds the friction while the axis moves and about nothing at rest (the position loop bleeds it
down through MuJoCo's soft friction), so a stop and a start each swing it through half a reversal's"""
START_SPEED = 0.3e-3
STOP_SPEED = 1e-3
"""[m/s] the commanded speeds a start's pulse waits for and a stop's comes under: below about
1 mm/s MuJoCo's friction, a soft constraint, fades and the push that held it creeps the axis on
(the bundled circle's X ran 11 um past its stop); at the first tick of motion a start's pulse
pushed the circle's start 10 um inside (0.3 mm/s: X 4.7 um at most; 0.5: 7.0; 1: 10.9)"""
MISMATCH_LIMIT = 0.2e-3
"""[s] the largest difference of equivalent time between two interpolating axes left as it is:
0.2 ms draws a 45 deg ellipse of +-5 um at 3 m/min (v dT / 2), half the acceptance's G"""


def ellipse_45(p) -> float:
    """The 45 deg ellipse of one pass [um]: the sin(2 theta) term of its radial deviation, fitted by
    least squares with the offset, the centre's cos / sin theta and the cos(2 theta) terms (a
    scale difference between the axes). ``p``: a :class:`~cnc_twin.run.ballbar.BallbarPass`."""
    theta = p.angle
    basis = np.column_stack([np.ones_like(theta), np.cos(theta), np.sin(theta), np.cos(2 * theta), np.sin(2 * theta)])
    coefficients, *_ = np.linalg.lstsq(basis, p.deviation * 1e6, rcond=None)
    return float(coefficients[4])


def equivalent_time_difference(test: CircularTest) -> float:
    """How much longer the plane's first axis lags than its second [s], from the circular test's
    servo-mismatch ellipse: the sin(2 theta) term of amplitude v (T_1 - T_2) / 2, whose sign
    turns with the direction of travel (Renishaw's servo mismatch; shared/data/commissioning.md)."""
    terms = [(1.0 if p.direction == "ccw" else -1.0) * ellipse_45(p) * 1e-6 / p.feed for p in test.passes]
    return float(2.0 * np.mean(terms)) if terms else 0.0


def matched_dynamics(scenario: Scenario, before: Mapping[str, CircularTest]) -> tuple[dict[str, float], str]:
    """The position-loop gains of :data:`INTERPOLATING` commissioning sets (an empty mapping: each
    keeps its own) and a line saying which and why.

    Axes that interpolate together must follow their commands alike: the same gain, or the same
    equivalent time (Siemens' dynamic response adaptation). With full velocity feed-forward (kvff
    1 on all of them) an axis follows its command with its drive's equivalent time, not 1 / kv:
    the circular tests measure the difference directly (:func:`equivalent_time_difference`), and
    where every pair is within :data:`MISMATCH_LIMIT` each axis keeps its own gain, the highest its
    margins allow, for the disturbances (friction, the other axes' forces, the process) that the
    feed-forward does not see. Otherwise, or without full feed-forward, every one gets the lowest
    of their gains. ``scenario``: a scenario on the machine being commissioned; ``before``: its
    circular tests."""
    gains = {axis: scenario.axis(axis).kp for axis in INTERPOLATING}
    full_ff = all(scenario.axis(axis).kvff == 1.0 for axis in INTERPOLATING)
    differences = {plane: equivalent_time_difference(test) for plane, test in before.items()}
    measured = ", ".join(f"{plane} {dt * 1e3:+.3f} ms" for plane, dt in differences.items())
    worst = max(abs(dt) for dt in differences.values())
    if full_ff and worst <= MISMATCH_LIMIT:
        return {}, (f"matched dynamics: equivalent time differences on the circular tests {measured} (the 45 deg "
                    f"ellipse, v dT / 2), within {MISMATCH_LIMIT * 1e3:g} ms with full velocity feed-forward: each "
                    f"axis keeps its own position-loop gain ({' '.join(f'{a} {g:g}' for a, g in gains.items())} 1/s)")
    slowest = min(gains, key=gains.get)
    why = "without full velocity feed-forward" if not full_ff else f"{worst * 1e3:.3f} ms apart on the circular tests"
    return ({axis: gains[slowest] for axis in INTERPOLATING},
            f"matched position loops ({why}: {measured}): {' '.join(f'{a} {g:g}' for a, g in gains.items())} "
            f"1/s -> {gains[slowest]:g} 1/s on {' '.join(INTERPOLATING)}, {slowest}'s, the lowest")


def commission(parameters: Path, *, scenarios: Path, report: Callable[[str], None] = lambda line: None,
               coulomb: Mapping[str, float] | None = None) -> Commissioning:
    """Run the steps of the module docstring on ``parameters`` (a machine parameter file) with the
    bundled circular tests in ``scenarios``; ``coulomb`` [N | N m] per axis: the friction the first
    reversal setting takes instead of the identified one."""
    from cnc_twin.scenario.load import load_scenario

    result = Commissioning(Path(parameters))
    machine = machine_overrides(parameters)
    report("circular tests before commissioning ...")
    result.before = circular_tests(machine, scenarios=scenarios)
    # the machine as given: its gains, drives and encoders (the first reversal settings take the
    # drives', which the gains do not change)
    scenario = load_scenario(scenarios / "ballbar_xy.yaml", overrides=machine)
    gains, line = matched_dynamics(scenario, result.before)
    result.steps.append(line)
    report(line)
    result.overrides.update({f"servo.{axis}.kp": kv for axis, kv in gains.items()})
    # each axis's rigid body identified once, on its drive's own signals: its inertia for the
    # feed-forward, its friction for the reversal compensation's first setting
    bodies = {axis: identify_rigid_body(scenario, axis) for axis in INTERPOLATING}
    result.feed_forward = feed_forward(scenario, bodies)
    line = "feed-forward from the drives and the identified inertia: " + "; ".join(
        f"{a} {f.describe()}" for a, f in result.feed_forward.items()) + (
        "; no symmetrising lag (servo.ff_equivalent_time 0): with the speed loops' inverse the drives add "
        "almost none, and what remains between the axes is the matched step's ellipse")
    result.steps.append(line)
    report(line)
    for f in result.feed_forward.values():
        result.overrides.update(f.overrides())
    report(f"circular tests at {FEED_FACTOR:g} x their feed with the feed-forward, for the tip's deflection ...")
    result.deflection = fit_deflection(fast_circular_traces({**machine, **result.overrides}, scenarios=scenarios))
    line = (f"the tip's deflection against the motor encoders on the circular tests at {FEED_FACTOR:g} x their feed "
            "[um per m/s^2], corrected: ") + "; ".join(
        f"{a} " + " ".join(f"{o} {c * 1e6:+.1f}" for o, c in row.items()) for a, row in result.deflection.items() if row)
    result.steps.append(line)
    report(line)
    result.overrides.update(deflection_overrides(result.deflection))
    base = {**machine, **result.overrides}
    min_speed = MIN_SPEED_SHARE * min(p.feed for test in result.before.values() for p in test.passes)
    for axis in COMPENSATED:
        c = bodies[axis].coulomb if coulomb is None else coulomb.get(axis, bodies[axis].coulomb)
        result.reversal[axis] = replace(reversal_tuning.first_setting(scenario, axis, c), min_speed=min_speed,
                                        standstill=STANDSTILL_SHARE, start_speed=START_SPEED, stop_speed=STOP_SPEED)
        s = result.reversal[axis]
        report(f"{axis}: first reversal setting from the drive and the identified friction: "
               f"{reversal_tuning.describe(s)}")
    reversal_tuning.search(result.reversal, base, scenarios=scenarios, report=report,
                           counts_per_unit={a: scenario.axis(a).counts_per_unit for a in COMPENSATED})
    accel_from = reversal_tuning.reversal_acceleration(result.before)
    report(f"the reversal pulse's adaptation to the acceleration, on the circular tests at "
           f"{reversal_tuning.ADAPT_FEED_FACTOR:g} x their feed ...")
    accel_to = reversal_tuning.adapt(result.reversal, base, scenarios=scenarios, accel_from=accel_from, report=report)
    result.steps.append(
        "reversal compensation on the circular tests XY, XZ, YZ, its pulse adapted to the acceleration at a "
        f"reversal between theirs ({accel_from * 1e3:.0f} mm/s^2) and theirs at {reversal_tuning.ADAPT_FEED_FACTOR:g} x "
        f"the feed ({accel_to * 1e3:.0f} mm/s^2): " + ", ".join(
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


def yaml_value(value: float | Mapping[str, float]) -> str:
    """A number (:func:`yaml_number`) or a mapping of numbers as a YAML flow mapping."""
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{key}: {yaml_number(v)}" for key, v in value.items()) + "}"
    return yaml_number(value)


def _closing_brace(text: str, opening: int) -> int:
    """The index of the brace that closes the one at ``opening`` (nested flow mappings counted)."""
    depth = 0
    for k in range(opening, len(text)):
        if text[k] == "{":
            depth += 1
        elif text[k] == "}":
            depth -= 1
            if depth == 0:
                return k
    raise ValueError("a flow mapping in the parameter file is not closed")


def _value_end(body: str, start: int) -> int:
    """Where the value starting at ``start`` of a flow mapping's ``body`` ends: a nested mapping's
    closing brace + 1, else the next comma or the body's end."""
    k = start
    while k < len(body) and body[k] in " \t":
        k += 1
    if k < len(body) and body[k] == "{":
        return _closing_brace(body, k) + 1
    comma = body.find(",", k)
    return len(body.rstrip()) if comma < 0 else comma


def set_flow_keys(text: str, axis: str, mapping: str, values: Mapping[str, float | Mapping[str, float]]) -> str:
    """``text`` (a parameter file) with ``values`` (numbers, or mappings of numbers) set in
    ``axis``'s ``mapping: {...}`` flow mapping (``servo``, ``compensation``): each key's value
    replaced where it is, added before the closing brace where it is not; a mapping the axis lacks
    is added on a line of its own after its ``servo`` mapping. ValueError when the axis (or its
    servo mapping) is not found."""
    head = re.search(rf"^  {axis}:\s*$", text, re.M)
    if head is None:
        raise ValueError(f"no axis {axis} in the parameter file")
    following = re.search(r"^  \S", text[head.end():], re.M)  # the next axis, or the next top-level key
    end = head.end() + following.start() if following else len(text)
    found = re.compile(rf"\b{mapping}:\s*\{{").search(text, head.end(), end)
    if found is None:
        servo = re.compile(r"\bservo:\s*\{").search(text, head.end(), end)
        if servo is None:
            raise ValueError(f"no servo: {{...}} under {axis} in the parameter file")
        line_end = text.index("\n", _closing_brace(text, servo.end() - 1))
        values = {key: value for key, value in values.items() if value}
        if not values:  # nothing to add: the mapping's defaults stand
            return text
        body = ", ".join(f"{key}: {yaml_value(value)}" for key, value in values.items())
        return text[:line_end + 1] + f"    {mapping}: {{{body}}}\n" + text[line_end + 1:]
    opening = found.end() - 1
    closing = _closing_brace(text, opening)
    body = text[opening + 1:closing]
    added = []
    for key, value in values.items():
        at = _top_level_key(body, key)
        if at is not None:
            value_end = _value_end(body, at)
            body = body[:at] + " " + yaml_value(value) + body[value_end:]
        elif not (isinstance(value, Mapping) and not value):
            added.append(f"{key}: {yaml_value(value)}")
    if added:
        body = body.rstrip() + "," + _wrapped(added)
    return text[:opening + 1] + body + text[closing:]


def _wrapped(items: list[str], indent: int = 13, width: int = 110) -> str:
    """``items`` joined by commas on lines of at most ``width`` characters, each new line indented
    by ``indent`` (under the servo mapping's first key)."""
    lines, line = [], ""
    for item in items:
        if line and indent + len(line) + 2 + len(item) > width:
            lines.append(line + ",")
            line = item
        else:
            line = f"{line}, {item}" if line else item
    lines.append(line)
    return "".join("\n" + " " * indent + text for text in lines)


def _top_level_key(body: str, key: str) -> int | None:
    """Where ``key``'s value starts (just after its colon) in a flow mapping's ``body``, at its top
    level (not inside a nested mapping); None when it is not there."""
    depth = 0
    for match in re.finditer(rf"[{{}}]|\b{re.escape(key)}:", body):
        token = match.group(0)
        if token == "{":
            depth += 1
        elif token == "}":
            depth -= 1
        elif depth == 0:
            return match.end()
    return None


def write_parameters(source: Path, overrides: Mapping[str, Any], out: Path, *, header: str = "") -> Path:
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

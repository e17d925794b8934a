"""The scenario format's JSON Schema (``cnc-twin schema``, cnc_twin/scenario/json_schema.py): a valid
draft 2020-12 schema that every bundled scenario meets and hostile files break as the loader
refuses them, committed beside the scenarios as the command writes it now."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest
import yaml

from conftest import run_cli
from test_hostile_inputs import CASES
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.json_schema import DIALECT, MODELINE, REGENERATE, SCHEMA_FILE, scenario_schema, schema_text
from cnc_twin.scenario.load import scenario_from_text
from cnc_twin.scenario.resources import scenarios_dir

BUNDLED = sorted(scenarios_dir().rglob("*.yaml"))
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def validator() -> jsonschema.Draft202012Validator:
    return jsonschema.Draft202012Validator(scenario_schema())


def test_the_schema_is_a_valid_2020_12_schema_with_a_title_and_a_description():
    schema = scenario_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    assert schema["$schema"] == DIALECT == "https://json-schema.org/draft/2020-12/schema"
    assert "$id" not in schema
    assert schema["title"] and schema["description"]


@pytest.mark.parametrize("path", BUNDLED, ids=[p.relative_to(scenarios_dir()).as_posix() for p in BUNDLED])
def test_a_bundled_scenario_validates_and_names_the_schema_on_its_first_line(path, validator):
    text = path.read_text(encoding="utf-8")
    assert [error.json_path for error in validator.iter_errors(yaml.safe_load(text))] == []
    first = text.split("\n", 1)[0]
    assert first.startswith(MODELINE.replace(SCHEMA_FILE, "")), first
    named = first.split("$schema=", 1)[1]
    assert named.endswith(SCHEMA_FILE) and not named.startswith("/"), first  # relative: a clone and a wheel alike
    assert (path.parent / named).resolve() == (scenarios_dir() / SCHEMA_FILE).resolve()


GOOD = {"name": "s", "program": {"type": "point_to_point", "moves": [{"X": 1}]}}

SCHEMA_REFUSES = {
    # the hostile files of tests/test_hostile_inputs.py a schema can tell from the file alone
    **{case: yaml.safe_load(CASES[case][0]) for case in (
        "a list at the top", "huge feed", "dwell beyond a day", "settle beyond a day", "nanosecond physics",
        "period of hours", "kp 1e308", "seed beyond 64 bits", "feed that vanishes in m/s", "stall of days",
        "name climbing out", "hidden name", "very long name")},
    "unknown key": {**GOOD, "timming": {"servo_period": 0.25}},
    "unknown key under axes": {**GOOD, "axes": {"X": {"servo": {"kp": 60, "kpp": 1}}}},
    "a string for a number": {**GOOD, "timing": {"servo_period": "0.25 ms"}},
    "a number for a string": {**GOOD, "name": 7},
    "negative period": {**GOOD, "timing": {"servo_period": -0.25}},
    "unknown program type": {**GOOD, "program": {"type": "laser", "moves": [{"X": 1}]}},
    "whiteboard not a power of two": {**GOOD, "whiteboard": {"words": 5000}},
    "no program": {"name": "s"},
}


@pytest.mark.parametrize("case", sorted(SCHEMA_REFUSES))
def test_a_file_the_loader_refuses_for_a_key_alone_the_schema_refuses_too(case, validator):
    raw = SCHEMA_REFUSES[case]
    assert not validator.is_valid(raw)
    with pytest.raises(ScenarioError):
        scenario_from_text(yaml.safe_dump(raw))


SCHEMA_ACCEPTS = {
    # the loader merges these sections over the machine parameter file first: any key may be left out
    "one gain of one axis": {**GOOD, "axes": {"X": {"servo": {"kp": 60}}}},
    "one encoder key": {**GOOD, "axes": {"C": {"encoder": {"index_offset": 1.5}}}},
    "the load cell's bits": {**GOOD, "force_sensor": {"bits": 16}},
    "every section left out": GOOD,
    "a name with dots and spaces inside": {**GOOD, "name": "plate 2.1 (rev b)"},
}


@pytest.mark.parametrize("case", sorted(SCHEMA_ACCEPTS))
def test_a_file_the_loader_accepts_the_schema_accepts(case, validator):
    raw = SCHEMA_ACCEPTS[case]
    scenario_from_text(yaml.safe_dump(raw))
    assert [error.json_path for error in validator.iter_errors(raw)] == []


def test_the_committed_schema_is_what_the_command_writes_now():
    committed = (scenarios_dir() / SCHEMA_FILE).read_text(encoding="utf-8")
    assert committed == schema_text(), f"scenarios/{SCHEMA_FILE} is out of date with the models: run `{REGENERATE}`"


def test_the_command_writes_the_schema_to_stdout_or_to_a_file(tmp_path):
    code, out, err = run_cli("schema")
    assert (code, err) == (0, "")
    assert json.loads(out) == scenario_schema()
    code, out, err = run_cli("schema", "--out", tmp_path / "mine.schema.json")
    assert (code, out, err) == (0, "", "")
    assert (tmp_path / "mine.schema.json").read_text(encoding="utf-8") == schema_text()


@pytest.mark.parametrize("where", ["no_such_folder/x.json", "."])
def test_an_unwritable_out_is_one_line_and_exit_2(tmp_path, where):
    code, out, err = run_cli("schema", "--out", tmp_path / where)  # a missing folder; a folder itself
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []

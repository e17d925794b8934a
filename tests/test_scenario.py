"""Scenario loading: units converted once, clear one-line errors naming file and key path."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.scenario.load import load_scenario

BUNDLED = sorted(scenarios_dir().glob("*.yaml"))


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_bundled_scenarios_validate(path):
    scenario = load_scenario(path)
    assert scenario.program is not None and scenario.name


def test_units_converted_to_si_once(write_scenario):
    path = write_scenario({
        "name": "u",
        "timing": {"interpolation_period": 2.0, "servo_period": 0.5, "physics_timestep": 0.25},
        "axes": {"X": {"max_velocity": 6000}, "A": {"max_velocity": 3600}},
        "program": {"type": "point_to_point", "moves": [{"X": 100, "A": 45, "feed": 1200, "dwell": 0.5}]},
    })
    s = load_scenario(path)
    assert s.timing.interpolation_period == pytest.approx(0.002)
    assert (s.timing.ticks_per_period, s.timing.substeps_per_tick) == (4, 2)
    assert s.axis("X").max_velocity == pytest.approx(0.1)          # 6000 mm/min
    assert s.axis("A").max_velocity == pytest.approx(math.pi / 3)  # 3600 deg/min = 60 deg/s
    assert s.axis("X").counts_per_unit == pytest.approx(1e6)       # 2500 lines x4 / 10 mm
    assert s.axis("A").counts_per_unit == pytest.approx(1e6 / (2 * math.pi))
    move = s.program.moves[0]
    assert move.targets[0] == pytest.approx(0.1) and move.targets[3] == pytest.approx(math.pi / 4)
    assert move.targets[1] is None
    assert move.feed == pytest.approx(0.02) and move.dwell == 0.5
    # overrides merge key by key: the rest of X's parameters come from the machine file
    assert s.axis("X").max_acceleration == pytest.approx(2.0) and s.axis("X").kp == 33.77


GOOD_PROGRAM = {"type": "point_to_point", "moves": [{"X": 10}]}

# (label, content, key path, a fragment of the message). Where pydantic words the problem
# ("a valid number", "a finite number", "list should have at least 1 item"), a wording a minor
# release of it may change, the fragment is our own end of the message: ", got" and the value.
BAD = [
    ("unknown key", {"name": "b", "program": GOOD_PROGRAM, "speling": 1}, "speling", "unknown key"),
    ("unknown nested key", {"name": "b", "program": {**GOOD_PROGRAM, "moves": [{"X": 1, "Q": 2}]}},
     "program.moves[0].Q", "unknown key"),
    ("wrong type", {"name": "b", "program": {**GOOD_PROGRAM, "moves": [{"X": "ten"}]}},
     "program.moves[0].X", ", got 'ten'"),
    ("negative feed", {"name": "b", "program": {**GOOD_PROGRAM, "moves": [{"X": 1, "feed": -100}]}},
     "program.moves[0].feed", "expected at least 0.001"),
    ("beyond travel", {"name": "b", "program": {**GOOD_PROGRAM, "moves": [{"X": 10}, {"X": 900}]}},
     "program.moves[1].X", "outside the X soft limits -385..385 mm"),
    ("rates not divisible", {"name": "b", "timing": {"servo_period": 0.3}, "program": GOOD_PROGRAM},
     "timing.servo_period", "integer multiple"),
    ("physics not divisible", {"name": "b", "timing": {"physics_timestep": 0.1}, "program": GOOD_PROGRAM},
     "timing.physics_timestep", "integer multiple"),
    ("gain override ill-typed", {"name": "b", "axes": {"Y": {"servo": {"kp": [1]}}}, "program": GOOD_PROGRAM},
     "axes.Y.servo.kp", ", got [1]"),
    ("pitch on rotary axis", {"name": "b", "axes": {"A": {"encoder": {"pitch": 5}}}, "program": GOOD_PROGRAM},
     "axes.A.encoder.pitch", "rotary axes have no screw pitch"),
    ("missing program", {"name": "b"}, "program", "required key is missing"),
    ("bool for number", {"name": "b", "program": {**GOOD_PROGRAM, "moves": [{"X": True}]}},
     "program.moves[0].X", ", got True"),
    ("nan", {"name": "b", "program": {**GOOD_PROGRAM, "moves": [{"X": float("nan")}]}},
     "program.moves[0].X", ", got nan"),
    ("missing model", {"name": "b", "machine": {"model": "nope.xml"}, "program": GOOD_PROGRAM},
     "machine.model", "not found"),
    ("no moves", {"name": "b", "program": {"type": "point_to_point", "moves": []}}, "program.moves", ", got []"),
]


@pytest.mark.parametrize("label, content, key, fragment", BAD, ids=[b[0] for b in BAD])
def test_bad_scenarios_name_file_and_key(write_scenario, label, content, key, fragment):
    path = write_scenario(content)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert err.file == str(path)
    assert err.key_path == key
    assert fragment in err.message
    assert "\n" not in str(err)


def test_yaml_syntax_error_gives_line_and_column(write_scenario):
    path = write_scenario("name: x\nprogram: [unclosed\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key_path.startswith("line ") and "not valid YAML" in info.value.message


def test_top_level_must_be_a_mapping(write_scenario):
    with pytest.raises(ScenarioError, match="expected a mapping"):
        load_scenario(write_scenario("- just\n- a list\n"))


def test_missing_file():
    with pytest.raises(ScenarioError, match="no such file"):
        load_scenario("/nonexistent/scenario.yaml")


def test_bad_mjcf_is_a_clear_error(write_scenario, tmp_path):
    import mujoco

    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><body></mujoco>")
    path = write_scenario({"name": "b", "machine": {"model": "broken.xml"}, "program": GOOD_PROGRAM})
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    # named at the scenario's key, with the model file and the parser's whole reason on one line
    # (MuJoCo's own words, whatever they are in the version installed: compared, not quoted)
    assert info.value.file == str(path) and info.value.key_path == "machine.model"
    with pytest.raises(ValueError) as parser:
        mujoco.MjModel.from_xml_path(str(tmp_path / "broken.xml"))
    reason = " ".join(line.strip() for line in str(parser.value).splitlines() if line.strip())
    assert reason and info.value.message == f"{tmp_path / 'broken.xml'}: MJCF does not compile: {reason}"


def _assert_one_line_error(code: int, out: str, err: str, path, key: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0] == f"error: {path}: {key}: " + lines[0].split(f"{key}: ", 1)[1]
    assert "Traceback" not in err and out == ""


@pytest.mark.parametrize("label, content, key, fragment", BAD[:1], ids=[b[0] for b in BAD[:1]])
def test_cli_exit_code_2_one_line_no_traceback(write_scenario, label, content, key, fragment):
    """As the program (a process of its own): exit code 2, one line on stderr, nothing on stdout."""
    path = write_scenario(content)
    for command in ("validate", "run"):
        proc = subprocess.run([sys.executable, "-m", "cnc_twin", command, str(path)],
                              capture_output=True, text=True, timeout=120)
        _assert_one_line_error(proc.returncode, proc.stdout, proc.stderr, path, key)


@pytest.mark.parametrize("label, content, key, fragment", BAD[1:6], ids=[b[0] for b in BAD[1:6]])
def test_cli_main_exit_code_2_one_line_no_traceback(write_scenario, capsys, label, content, key, fragment):
    """The same through ``cli.main`` in this process (the program's code path after its first
    lines; a process per case costs a second of start-up each)."""
    from cnc_twin.cli import main

    path = write_scenario(content)
    for command in ("validate", "run"):
        code = main([command, str(path)])
        captured = capsys.readouterr()
        _assert_one_line_error(code, captured.out, captured.err, path, key)


def test_errors_stay_one_line_whatever_the_input_held():
    """Found by the fuzzer: a control character in a value (here U+001E, a line break to
    str.splitlines) used to split the error message."""
    from cnc_twin.core.errors import ScenarioError

    text = str(ScenarioError("f.yaml", "machine.model", "file '\x1e\n\u2028x' not found"))
    assert len(text.splitlines()) == 1
    assert "\\x1e" in text and "\\n" in text


def test_validate_checks_every_file_and_reports_each_bad_one(tmp_path):
    bad_a, bad_b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    bad_a.write_text("name: a\n")
    bad_b.write_text("name: b\nprogram: {type: point_to_point, moves: [{X: 1, feed: -5}]}\n")
    good = scenarios_dir() / "jog_axes.yaml"
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "validate", str(bad_a), str(good), str(bad_b)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    errors = proc.stderr.strip().splitlines()
    assert errors[0].startswith(f"error: {bad_a}: program") and errors[1].startswith(f"error: {bad_b}: program.moves[0].feed")
    assert errors[2] == "2 of 3 scenarios refused" and len(errors) == 3
    assert proc.stdout.startswith(f"{good}: ok (jog_axes")


def test_a_scenario_with_several_problems_names_where_the_others_are(write_scenario, capsys):
    """One line still, the first problem in full, the others' key paths after it: one fix-and-retry
    round finds them all."""
    from cnc_twin.cli import main

    path = write_scenario({"name": "many", "program": {"type": "point_to_point", "moves": [
        {"X": 1, "feed": -5}, {"X": 2, "feed": -6}, {"Y": 1, "feed": -7}]}})
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    _assert_one_line_error(2, "", err, path, "program.moves[0].feed")
    assert "program.moves[1].feed" in err and "program.moves[2].feed" in err

"""Hostile and careless scenario files (docs/hostile_inputs.md is this table in words): each is
refused with exit 2 and one line naming the file, the key (or line) and the limit, before
anything runs; nothing is written anywhere."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import run_cli
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.scenario.yaml_input import MAX_FILE_BYTES

GOOD = "name: h\nprogram:\n  type: point_to_point\n  moves: [{X: 1}]\n"


def _bomb(levels: int = 9) -> str:
    """A few lines of anchors, each nine aliases of the one before: 9^9 values once expanded."""
    rows = ["  - &a0 [x, x, x, x, x, x, x, x, x]"]
    rows += [f"  - &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, levels)]
    return GOOD + "description:\n" + "\n".join(rows) + "\n"


def _nested(depth: int) -> str:
    return GOOD + "timing: " + "{a: " * depth + "1" + "}" * depth + "\n"


def _with(**top) -> str:
    raw = yaml.safe_load(GOOD)
    for path, value in top.items():
        node = raw
        keys = path.split("__")
        for key in keys[:-1]:
            node = node.setdefault(key, {})
        node[keys[-1]] = value
    return yaml.safe_dump(raw, sort_keys=False)


CASES = {
    # YAML tricks
    "duplicate key": ("name: a\nname: b\n" + GOOD.split("\n", 1)[1], "line 2", "duplicate key 'name' on lines 1 and 2"),
    "alias bomb": (_bomb(), "description", "expands to more than"),
    "recursive alias": (GOOD + "description: &r [*r]\n", "", ""),
    "deep nesting": (_nested(200), "timing", "nested more than 32 levels deep"),
    "nesting past the parser": (_nested(20000), "", None),  # the parser's words: see WORDED_BY_A_LIBRARY
    "not UTF-8": (b"name: \xff\xfe\n", "", "not UTF-8"),
    "a list at the top": ("- 1\n- 2\n", "", "expected a mapping"),
    # numbers
    "huge feed": (_with(program__moves=[{"X": 1, "feed": 1e300}]), "program.moves[0].feed", "beyond +-1e+09"),
    "dwell beyond a day": (_with(program__moves=[{"X": 1, "dwell": 1e8}]), "program.moves[0].dwell", "expected at most 86400"),
    "settle beyond a day": (_with(program__settle=1e300), "program.settle", ""),
    "nanosecond physics": (_with(timing={"physics_timestep": 1e-6}), "timing.physics_timestep", "expected at least 0.001"),
    "period of hours": (_with(timing={"interpolation_period": 1e7, "servo_period": 0.25}), "timing.interpolation_period",
                        "expected at most 100"),
    "kp 1e308": (_with(axes={"X": {"servo": {"kp": 1e308}}}), "axes.X.servo.kp", ""),
    "absurd encoder": (_with(axes={"X": {"encoder": {"lines_per_rev": 2**24}}}), "axes.X.encoder.lines_per_rev",
                       "32-bit position counter"),
    "seed beyond 64 bits": (_with(seed=2**70), "seed", "expected at most 18446744073709551615"),
    "chunk beyond the FIFO": (_with(whiteboard={"chunk": 10**9}), "whiteboard.chunk", "command FIFO"),
    "feed that vanishes in m/s": (_with(program__moves=[{"X": 1, "feed": 5e-324}]), "program.moves[0].feed",
                                  "expected at least 0.001"),
    "stall of days": (_with(faults=[{"type": "planner_stall", "at": 0.1, "duration": 1e9}]), "faults[0].duration", ""),
    "fault after the end": (_with(max_time=2.0, faults=[{"type": "planner_kill", "at": 5.0}]), "faults[0].at",
                            "after the run's end"),
    "nan": (GOOD + "max_time: .nan\n", "max_time", ", got nan"),
    # names
    "name climbing out": (_with(name="../../../tmp/x/escaped"), "name", "'/' is not allowed"),
    "hidden name": (_with(name=".x"), "name", "may not start with '.'"),
    "name with escape codes": (_with(name="a\x1b[31mred"), "", ""),
    "name with a bidi override": (_with(name="a\u202eb"), "name", "'\\u202e' is not allowed"),
    "very long name": (_with(name="x" * 500), "name",
                       ", got 'xxxxxxxxxxxxxxxxxxxxxxxxxxx...xxxxxxxxxxxxxxxxxxxxxxxxxxxx'"),
    # paths
    "model not MJCF": (_with(machine={"model": "/etc/passwd"}), "machine.model", "MJCF does not compile"),
    "model missing": (_with(machine={"model": "nothing.xml"}), "machine.model", "not found"),
    "parameters not a mapping": (_with(machine={"parameters": "list.yaml"}), "machine.parameters", ""),
}
"""case -> (text of the file, the key path the line names, a fragment of our own words in it, or
None where nothing after ``error: FILE: `` is sure to be ours)"""

WORDED_BY_A_LIBRARY = {
    "nesting past the parser": "the YAML parser",  # PyYAML 6.0.4 (libyaml) stops it before our check
    "model not MJCF": "MuJoCo's XML parser",  # the reason after "MJCF does not compile: "
    "nan": "pydantic",  # "a finite number" after our "expected"
    "very long name": "pydantic",  # "string should have at most 100 characters"
}
"""Cases whose line goes on in a library's own words, which a minor release of it may change:
the test holds the contract (exit 2, one printable line naming the file, the key and our words
where the table gives them, nothing written) and docs/hostile_inputs.md quotes our part of the
line, then "…" and the library named here, with what it printed as an example only."""


DOC_ROWS = (Path(__file__).parents[1] / "docs" / "hostile_inputs.md").read_text(encoding="utf-8").splitlines()


def _validate(path: Path) -> tuple[int, str]:
    code, _, err = run_cli("validate", path)
    return code, err


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_hostile_scenario_is_refused_in_one_line(tmp_path, case):
    text, key, fragment = CASES[case]
    path = tmp_path / "hostile.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")  # a parameter file that is not a mapping
    code, err = _validate(path)
    assert code == 2, err
    line = err.strip()
    assert "\n" not in line and "Traceback" not in line and line.startswith(f"error: {path}")
    assert line.isprintable(), line  # no raw control character from the input reaches the terminal
    assert f": {key}" in line and (fragment is None or fragment in line), line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hostile.yaml", "list.yaml"]
    # docs/hostile_inputs.md quotes this very message, or (a library's words in it) our start of it
    quoted = line.replace(str(path), "FILE").replace(str(tmp_path), "DIR").replace("|", "\\|")
    rows = [row for row in DOC_ROWS if row.startswith(f"| {case} | ") and row.endswith(" |")]
    assert len(rows) == 1, f"docs/hostile_inputs.md has {len(rows)} rows for {case!r}"
    documented = rows[0][len(f"| {case} | "):-2]
    if case in WORDED_BY_A_LIBRARY:
        ours, _, said = documented.partition("…")
        assert said.startswith(f" ({WORDED_BY_A_LIBRARY[case]}"), documented
        assert ours.startswith("error: FILE: ") and quoted.startswith(ours), (ours, quoted)
    else:
        assert documented == quoted, f"docs/hostile_inputs.md has {documented!r}, printed {quoted!r}"


@pytest.mark.parametrize("source", ["/dev/zero", "big"])
def test_a_huge_file_is_refused_without_reading_it_whole(tmp_path, source):
    path = Path(source) if source.startswith("/") else tmp_path / "big.yaml"
    if source == "big":
        path.write_bytes(b"# " + b"x" * (MAX_FILE_BYTES + 10) + b"\n" + GOOD.encode())
    code, err = _validate(path)
    assert code == 2 and "larger than 16 MiB" in err, err


def test_a_run_too_large_for_its_timestep_is_refused_before_the_clock(tmp_path):
    """Valid numbers each, too many physics steps together: exit 2 before any motion, no run
    directory, and the message says how many steps against which limit."""
    raw = yaml.safe_load(GOOD)
    raw["timing"] = {"interpolation_period": 0.05, "servo_period": 0.05, "physics_timestep": 0.001}
    raw["program"]["moves"][0]["dwell"] = 80000.0
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(raw))
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(tmp_path / "run")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert "timing.physics_timestep" in last and "physics steps" in last and "the limit is" in last
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("out", ["a_file/run", "/proc/none/run"])
def test_an_unwritable_out_is_refused_before_the_run(tmp_path, out):
    (tmp_path / "a_file").write_text("")
    target = out if out.startswith("/") else str(tmp_path / out)
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(scenarios_dir() / "jog_axes.yaml"),
                           "--out", target, "--no-rrd"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "--out" in proc.stderr and "running" not in proc.stderr, proc.stderr


def _good_with_key(key: str, value) -> dict:
    """The good scenario with ``value`` at ``key`` (a dotted path, numbers index lists)."""
    raw = yaml.safe_load(GOOD)
    node = raw
    parts = [int(p) if p.isdigit() else p for p in key.split(".")]
    for part in parts[:-1]:
        node = node[part] if isinstance(part, int) else node.setdefault(part, {})
    node[parts[-1]] = value
    return raw


numbers = st.one_of(st.floats(allow_nan=False), st.sampled_from([1e308, -1e308, 5e-324, 1e9 + 1, 0.0, -0.0]),
                    st.integers(-2**80, 2**80))
NUMERIC_KEYS = ["seed", "max_time", "timing.interpolation_period", "timing.servo_period", "timing.physics_timestep",
                "program.moves.0.feed", "program.moves.0.dwell", "program.settle", "axes.X.servo.kp",
                "axes.Y.servo.ki", "axes.Z.encoder.lines_per_rev", "axes.A.max_velocity", "whiteboard.chunk",
                "planner.lookahead", "supervisor.retract", "force_sensor.bits"]


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(NUMERIC_KEYS), value=numbers, name=st.text(max_size=120),
       depth=st.integers(0, 60), duplicate=st.booleans())
def test_fuzzed_numbers_names_nesting_and_duplicates_never_escape(tmp_path, key, value, name, depth, duplicate):
    """Huge and tiny numbers at real keys, any name, nesting and duplicate keys: exit 0 or exit 2
    with one printable line; never a traceback, never a file written."""
    raw = _good_with_key(key, value)
    raw["name"] = name
    if depth:
        raw["description"] = json.loads("[" * depth + "]" * depth)
    text = yaml.safe_dump(raw, sort_keys=False)
    if duplicate:
        text += "seed: 3\n"
    folder = tmp_path / "f"
    folder.mkdir(exist_ok=True)
    path = folder / "fuzz.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    code, err = _validate(path)
    assert code in (0, 2), err
    if code == 2:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and err.strip().isprintable()
    assert [p.name for p in folder.iterdir()] == ["fuzz.yaml"]


def test_the_docs_axis_table_states_the_ranges_the_schema_enforces(tmp_path):
    """The 'accepted' column of docs/scenarios.md's machine-parameter table is the schema's own bounds; a
    value just beyond each stated upper bound is refused at that key."""
    from cnc_twin.scenario.machine import AxisSpec, ForceSensorSpec
    from cnc_twin.scenario.ranges import accepted_range

    readme = (Path(__file__).parents[1] / "docs" / "scenarios.md").read_text()
    table = readme.split("Machine parameters (", 1)[1].split("\n\n")[1].splitlines()
    assert table[0].startswith("| key | unit (linear / rotary) | accepted |")
    rows = [[cell.strip() for cell in line.strip("|").split(" | ")] for line in table[2:]]
    assert len(rows) >= 20
    for key, _unit, stated, *_ in rows:
        key = key.strip("`")
        model = ForceSensorSpec if key.startswith("force_sensor.") else AxisSpec
        assert stated == accepted_range(model, key.removeprefix("force_sensor.")), key
    path = tmp_path / "kp.yaml"
    path.write_text(_with(axes={"X": {"servo": {"kp": 1.000001e5}}}))
    code, err = _validate(path)
    assert code == 2 and "axes.X.servo.kp" in err and "100000" in err, err


odd_but_plausible = st.one_of(st.floats(-1e3, 1e4, allow_nan=False), st.integers(-10, 10**6),
                              st.sampled_from([0.0, 5e-324, 1e-9, 0.05, 0.001, 2**24, 86400.0]))
RUN_BUDGET_S = 8.0


@settings(max_examples=3, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.filter_too_much])
@given(key=st.sampled_from(NUMERIC_KEYS), value=odd_but_plausible)
def test_fuzzed_scenarios_that_validate_also_run_cleanly(tmp_path, key, value):
    """What `validate` accepts, `run` runs to one of the clean ends: complete (0), a named fault
    (3) with a whole run directory, or, stopped by SIGINT after a wall budget, a whole run
    directory marked interrupted (130); a refusal is one line (2). Never a traceback, never a
    file outside the run directory."""
    import os
    import shutil
    import signal
    import time

    from hypothesis import assume

    raw = _good_with_key(key, value)
    folder = tmp_path / "f"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    path = folder / "fuzz.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    code, err = _validate(path)
    assume(code == 0)  # refusals are the other fuzz test's part
    proc = subprocess.Popen([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(folder / "run"),
                             "--no-rrd", "--quiet"], cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=RUN_BUDGET_S)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:  # no orphan writing into the folder of Hypothesis's next try
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            from cnc_twin.whiteboard.block import creator_pid, leftover_segments

            for name in leftover_segments():  # nor its whiteboard left for the next tests to trip on
                if creator_pid(name) == proc.pid:
                    os.unlink(f"/dev/shm/{name}")
            pytest.fail("the run did not stop within 60 s of SIGINT")
    assert "Traceback" not in err, err
    assert proc.returncode in (0, 2, 3, 130), (proc.returncode, err)
    if proc.returncode == 2:
        assert len(err.strip().splitlines()) == 1 and not (folder / "run").exists(), err
        assert sorted(p.name for p in folder.iterdir()) == ["fuzz.yaml"]
        return
    if proc.returncode == 130 and not (folder / "run").exists():  # stopped before the run began
        assert sorted(p.name for p in folder.iterdir()) == ["fuzz.yaml"]
        return
    metrics = json.loads((folder / "run" / "metrics.json").read_text())
    assert metrics["status"] == {0: "complete", 3: "fault", 130: "interrupted"}[proc.returncode], metrics["status"]
    assert (folder / "run" / "trace.parquet").stat().st_size > 0
    assert sorted(p.name for p in folder.iterdir()) == ["fuzz.yaml", "run"]
    from cnc_twin.whiteboard.block import creator_pid

    time.sleep(0.2)
    assert not [n for n in os.listdir("/dev/shm") if creator_pid(n) == proc.pid]

"""Subroutine files: ``o<name> call`` of a subroutine the program does not define runs the one in
``name.ngc``, looked for beside the program, then in the subroutine path's folders in order, as
LinuxCNC looks (rs274 run in the program's folder, its INI's ``[RS274NGC]SUBROUTINE_PATH``); the
calls and the messages compared with rs274's, then the CLI flag and the scenario key."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import oracle
from cnc_twin.gcode.interpreter import ProgramError, read_program
from cnc_twin.gcode.source import Source
from conftest import run_cli
from gcode_conformance import TOOLS

MAIN = "G21\no<foo> call [2] [3]\nG0 X#<_value> Y#<_value_returned>\nM2\n"
FOO = "o<foo> sub\nG0 X#1 Y#2 Z5\no<foo> endsub [#1 + #2]\n"
"""a call with two values and what the subroutine returns (their sum; _value_returned 1)"""

CASES = {
    "beside the program": (MAIN, {"foo.ngc": FOO}, None),
    "in a subroutine-path folder": (MAIN, {"subs/foo.ngc": FOO}, ["subs"]),
    "beside the program before the path": (MAIN, {"foo.ngc": FOO, "subs/foo.ngc": FOO.replace("Z5", "Z6")},
                                           ["subs"]),
    "the path's folders in order": (MAIN, {"a/foo.ngc": FOO.replace("Z5", "Z7"), "b/foo.ngc": FOO}, ["a", "b"]),
    "a file before a later definition": (MAIN + "o<foo> sub\nG0 Z9\no<foo> endsub\n", {"foo.ngc": FOO}, None),
    "missing": (MAIN, {"subs/foo.ngc": FOO}, None),
    "a file without the subroutine": (MAIN, {"foo.ngc": "(nothing here)\n"}, None),
    "an error in the file": (MAIN, {"foo.ngc": "o<foo> sub\nG0 X#1\nG0 X[1/0]\no<foo> endsub\n"}, None),
    "a file ending inside the subroutine": (MAIN, {"foo.ngc": "o<foo> sub\nG0 X#1\n"}, None),
    "called twice, read once": ("G21\no<foo> call [1]\no<foo> call [4]\nM2\n", {"foo.ngc": FOO}, None),
    "locals kept, parameters restored": (
        "G21\n#<keep>=4\n#1=8\no<foo> call [2] [3]\nG0 X#<_value> Y#<keep> Z#1\nM2\n",
        {"foo.ngc": "o<foo> sub\n#<keep>=9\n#1=5\nG0 X#1 Y#2 Z#<keep>\no<foo> endsub [#2 * 2]\n"}, None),
    "a return value from return": (MAIN, {"foo.ngc": "o<foo> sub\no<foo> return [8]\no<foo> endsub [7]\n"}, None),
    "no value returned": ("G21\no<foo> call\nG0 X#<_value_returned>\nM2\n",
                          {"foo.ngc": "o<foo> sub\no<foo> endsub\n"}, None),
    "a numbered subroutine": ("G21\nO100 CALL [2]\nM2\n", {"100.ngc": "o100 sub\nG0 X#1\no100 endsub\n"}, None),
    "upper case, lines before it": ("G21\nO<Foo> CALL [2] [3]\nM2\n",
                                    {"foo.ngc": "(header)\nG0 Z1\n" + FOO.upper() + "G0 Z2\n"}, None),
    "files calling the program's and other files": (
        "G21\no<bar> sub\nG0 Z3\no<bar> endsub\no<foo> call\nM2\n",
        {"foo.ngc": "o<foo> sub\no<bar> call\no<baz> call\no<foo> endsub\n",
         "subs/baz.ngc": "o<baz> sub\nG0 Z4\no<baz> endsub\n"}, ["subs"]),
    "a call nowhere from a file": (MAIN, {"foo.ngc": "o<foo> sub\no<qux> call\no<foo> endsub\n"}, None),
    "a definition passed over in a file": (
        MAIN, {"foo.ngc": "o<bar> sub\nG0 Z8\no<bar> endsub\no<foo> sub\no<bar> call\no<foo> endsub\n"}, None),
    "M2 in the file": (MAIN, {"foo.ngc": "o<foo> sub\nG0 X#1\nM2\no<foo> endsub\n"}, None),
    "percent lines in the file": (MAIN, {"foo.ngc": "%\n" + FOO + "%\n"}, None),
}


def _ours(folder: Path, path: list[str] | None):
    """Our calls (name, arguments as printed) and refusal of ``folder/program.ngc``."""
    try:
        reading = read_program(Source.read(folder / "program.ngc"), TOOLS,
                               subroutine_path=[folder / p for p in path or []])
        return [(c.name, c.arguments) for c in reading.calls], None
    except ProgramError as exc:
        return [(c.name, c.arguments) for c in exc.calls], exc


def _without_final_resets(calls):
    # rs274 run with an INI file prints one ON_RESET fewer as it ends
    while calls and calls[-1][0] == "ON_RESET":
        calls = calls[:-1]
    return calls


@pytest.mark.parametrize("case", list(CASES))
def test_subroutine_files_are_found_and_run_as_linuxcnc_runs_them(case, tmp_path):
    oracle.require()
    program, files, path = CASES[case]
    theirs, said = oracle.run(program, tmp_path, files=files,
                              subroutine_path=":".join(path) if path else None)
    calls, error = _ours(tmp_path, path)
    assert _without_final_resets(calls) == _without_final_resets(theirs)
    if error is None:
        assert said == []
        return
    # rs274 prints the message, then the refused line of the file it was reading
    where = error.file or tmp_path / "program.ngc"
    shown = where.read_text().split("\n")[error.line - 1].strip()
    assert said == [error.message, shown]


def test_a_refusal_in_a_file_names_the_file_and_its_line(tmp_path):
    _, files, _ = CASES["an error in the file"]
    (tmp_path / "program.ngc").write_text(MAIN)
    (tmp_path / "foo.ngc").write_text(files["foo.ngc"])
    _, error = _ours(tmp_path, None)
    assert (error.file, error.line, error.message) == (tmp_path / "foo.ngc", 3, "Attempt to divide by zero")


def _folder(tmp_path: Path) -> Path:
    """A program calling ``o<side>`` (in ``subs/``), which calls ``o<inner>`` (beside it)."""
    (tmp_path / "subs").mkdir()
    (tmp_path / "part.ngc").write_text("G21 G90\nG0 X0 Y0 Z5\no<side> call [3]\nG1 X#<_value> F600\nM2\n")
    (tmp_path / "subs" / "side.ngc").write_text("o<side> sub\nG1 X#1 Y2 F600\no<inner> call\n"
                                                "o<side> endsub [#1 * 2]\n")
    (tmp_path / "inner.ngc").write_text("o<inner> sub\nG1 Y4\no<inner> endsub\n")
    return tmp_path


def test_the_cli_reads_a_subroutine_path(tmp_path):
    """`cnc-twin gcode PART --subroutine-path DIR[:DIR] --canon`: rs274's calls; a refusal in a
    file is its FILE:LINE, a missing subroutine LinuxCNC's message, a missing folder one line."""
    oracle.require()
    folder = _folder(tmp_path)
    code, out, err = run_cli("gcode", folder / "part.ngc", "--subroutine-path", folder / "subs", "--canon")
    assert (code, err) == (0, "")
    theirs, said = oracle.run((folder / "part.ngc").read_text(), folder, subroutine_path="subs")
    listed = [line.split("N..... ", 1)[1] for line in out.splitlines()]
    assert _without_final_resets([(c.split("(")[0], c.split("(", 1)[1][:-1]) for c in listed]) == \
        _without_final_resets(theirs) and said == []
    (folder / "inner.ngc").write_text("o<inner> sub\nG1 Y[1/0]\no<inner> endsub\n")
    code, _, err = run_cli("gcode", folder / "part.ngc", "--subroutine-path", folder / "subs")
    assert (code, err) == (2, f"error: {folder / 'inner.ngc'}:2: Attempt to divide by zero\n")
    code, _, err = run_cli("gcode", folder / "part.ngc")
    assert code == 2 and err == (f"error: {folder / 'part.ngc'}:5: EOF in file:part.ngc seeking o-word: o<side> "
                                 "from line: 3\n")
    code, _, err = run_cli("gcode", folder / "part.ngc", "--subroutine-path", f"{folder / 'subs'}:{folder / 'none'}")
    assert code == 2 and len(err.splitlines()) == 1 and "none" in err


def test_the_scenario_key_and_the_run_directory_keep_the_files(tmp_path):
    """``program.subroutine_path`` (folders relative to the scenario): validated, a missing
    folder named by its key; the files a run called are kept where the scenario's folder had
    them, so the run directory reads the same program again."""
    from cnc_twin import load_scenario
    from cnc_twin.run.program_kinds import kind_of, write_run_files

    folder = _folder(tmp_path)
    scenario = {"name": "subs", "program": {"type": "gcode", "file": "part.ngc", "subroutine_path": ["subs"]}}
    (folder / "s.yaml").write_text(yaml.safe_dump(scenario))
    code, out, err = run_cli("validate", folder / "s.yaml")
    assert code == 0, err
    assert "1 feed path" in out
    loaded = load_scenario(folder / "s.yaml")
    kept = kind_of(loaded.program).run_files(loaded.program)
    assert kept["subs/side.ngc"].text() == (folder / "subs" / "side.ngc").read_text()
    assert kept["inner.ngc"].text() == (folder / "inner.ngc").read_text()
    # the run directory as written: the scenario, the program and the kept files, read again
    rerun = tmp_path / "rerun"
    write_run_files(loaded.program, rerun)
    assert sorted(p.relative_to(rerun).as_posix() for p in rerun.rglob("*.ngc")) == sorted(kept)
    (rerun / "s.yaml").write_text(yaml.safe_dump(scenario))
    again = load_scenario(rerun / "s.yaml")
    assert again.program.steps == loaded.program.steps
    scenario["program"]["subroutine_path"] = ["nowhere"]
    (folder / "bad.yaml").write_text(yaml.safe_dump(scenario))
    code, _, err = run_cli("validate", folder / "bad.yaml")
    assert code == 2 and "program.subroutine_path[0]" in err and len(err.strip().splitlines()) == 1
    scenario["program"]["subroutine_path"] = []
    (folder / "none.yaml").write_text(yaml.safe_dump(scenario))
    code, _, err = run_cli("validate", folder / "none.yaml")
    assert code == 2 and "EOF in file:part.ngc seeking o-word: o<side>" in err


@pytest.mark.slow  # a whole Sphinx build / a whole run: left out of -m "not slow"
def test_run_takes_a_subroutine_path_and_the_run_directory_runs_again(tmp_path):
    folder = _folder(tmp_path)
    code, _, err = run_cli("run", folder / "part.ngc", "--subroutine-path", folder / "subs", "--out",
                           tmp_path / "run", "--no-rrd", "--quiet")
    assert code == 0, err
    assert (tmp_path / "run" / "subs" / "side.ngc").is_file() and (tmp_path / "run" / "inner.ngc").is_file()
    code, out, err = run_cli("validate", tmp_path / "run" / "scenario.yaml")
    assert code == 0 and "1 feed path" in out, out + err

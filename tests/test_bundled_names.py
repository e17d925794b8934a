"""Bundled scenarios and programs by name, from any folder, and ``cnc-twin list``."""

from __future__ import annotations

from conftest import run_cli
from cnc_twin.scenario.resources import input_path, programs_dir, scenarios_dir


def test_list_names_every_bundled_scenario_and_program_once_and_each_name_finds_its_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # far from the checkout
    code, out, err = run_cli("list")
    assert (code, err) == (0, "")
    names = [line.split()[0] for line in out.splitlines() if line.startswith("  ")]
    scenarios = sorted(scenarios_dir().rglob("*.yaml"))
    programs = sorted(programs_dir().rglob("*.ngc"))
    assert len(names) == len(scenarios) + len(programs)
    listed_scenarios, listed_programs = names[:len(scenarios)], names[len(scenarios):]
    assert [input_path(name) for name in listed_scenarios] == scenarios
    assert [input_path(name + ".ngc") for name in listed_programs] == programs
    # each a whole sentence: none cut where its first comment line breaks (cam_raster's did, at a comma)
    described = [line.split(None, 1)[1] for line in out.splitlines() if line.startswith("  ") and len(line.split()) > 1]
    assert described and not [text for text in described if text.rstrip().endswith((",", ":"))]


def test_a_program_s_description_carries_its_sentence_over_comment_lines(tmp_path):
    from cnc_twin.scenario.catalogue import _program_description

    program = tmp_path / "p.ngc"
    program.write_text("; a raster of 11 passes,\n; 7 mm apart: a dry run.\n; written by hand\nG0 X0\n")
    assert _program_description(program) == "a raster of 11 passes, 7 mm apart: a dry run."
    program.write_text("(one comment)\n(another)\nG0 X0\n")
    assert _program_description(program) == "one comment"


def test_a_bundled_scenario_validates_by_name_from_another_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("nurbs_circle", "nurbs_circle.yaml", "published/farfalla"):
        code, out, err = run_cli("validate", name)
        assert (code, err) == (0, ""), (name, err)
        assert out.startswith(str(scenarios_dir())), out


def test_a_bundled_program_reads_by_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("gcode", "polish_force")
    assert (code, err) == (0, "")
    assert out.startswith(f"{programs_dir() / 'polish_force.ngc'}:")


def test_a_file_in_the_current_folder_comes_before_the_bundled_one(tmp_path, monkeypatch, write_scenario):
    monkeypatch.chdir(tmp_path)
    write_scenario({"name": "mine", "program": {"type": "point_to_point", "moves": [{"X": 1}]}}, name="nurbs_circle.yaml")
    code, out, err = run_cli("validate", "nurbs_circle.yaml")
    assert (code, err) == (0, "")
    assert out.startswith("nurbs_circle.yaml: ok (mine,")


def test_an_unknown_name_is_one_error_line(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("validate", "no_such_scenario")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: no_such_scenario")

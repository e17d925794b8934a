"""The docs site's own machinery, each extension of docs/_ext/ in a small site of its own built as
the docs are (warnings are errors, every reference checked): the performance page's tables come
from the benchmarks' files (bench_figures: each committed file of docs/data/ renders with what it
was measured on; a file that is missing, or says nothing of its machine, fails the build), and the
scenario keys from the JSON Schema (scenario_reference). The whole site (every page, the API
reference of every module) is built by CI (scripts/build_docs.py).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = sorted((ROOT / "docs" / "data").glob("*.json"))


def _build(tmp_path: Path, pages: dict[str, str], extension: str = "bench_figures") -> subprocess.CompletedProcess:
    """A site of ``pages`` (name -> Markdown, or rST where the name ends in ``.rst``) and an index
    listing them, with myst-parser and ``extension``, built to text in ``tmp_path / "built"``."""
    source, built = tmp_path / "site", tmp_path / "built"
    source.mkdir()
    (source / "conf.py").write_text(
        f"import sys\nsys.path[:0] = [{str(ROOT / 'docs' / '_ext')!r}, {str(ROOT)!r}]\n"
        f"extensions = ['myst_parser', {extension!r}]\n"
        "source_suffix = {'.md': 'markdown', '.rst': 'restructuredtext'}\nnitpicky = True\n", encoding="utf-8")
    names = "\n".join(name.removesuffix(".rst") for name in pages)
    (source / "index.md").write_text(f"# Figures\n\n```{{toctree}}\n{names}\n```\n", encoding="utf-8")
    for name, text in pages.items():
        (source / (name if name.endswith(".rst") else f"{name}.md")).write_text(text, encoding="utf-8")
    return subprocess.run([sys.executable, "-m", "sphinx", "-W", "-n", "-q", "-b", "text", str(source), str(built)],
                          capture_output=True, text=True, timeout=300)


def test_the_performance_page_names_only_files_that_are_committed():
    page = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    named = re.findall(r"^```\{bench-figures\} (\S+)", page, flags=re.M)
    assert named, "the performance page shows no benchmark's file"
    assert {ROOT / "docs" / name for name in named} <= set(DATA)


def test_the_figures_the_performance_page_picks_are_in_its_files():
    page = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    for name, keys in re.findall(r"^```\{bench-figures\} (\S+)\n:keys: (.+)$", page, flags=re.M):
        record = json.loads((ROOT / "docs" / name).read_text(encoding="utf-8"))
        assert set(keys.split()) <= set(record), (name, set(keys.split()) - set(record))


def test_every_committed_figures_file_renders_with_its_machine(tmp_path):
    assert DATA, "docs/data/ holds no benchmark's figures"
    pages = {f"page{i}": f"# {path.name}\n\n```{{bench-figures}} {path}\n```\n" for i, path in enumerate(DATA)}
    done = _build(tmp_path, pages)
    assert done.returncode == 0, done.stderr
    for i, path in enumerate(DATA):
        text = (tmp_path / "built" / f"page{i}.txt").read_text(encoding="utf-8")
        record = json.loads(path.read_text(encoding="utf-8"))
        when = record["measured"]["date_utc"] if "measured" in record else record["datetime"]
        assert when in text, path.name
        if "measured" in record:
            assert record["measured"]["versions"]["mujoco"] in text
        if "ratio_twin_over_bare" in record:
            assert f"{record['ratio_twin_over_bare']:.4g}" in text


def test_chosen_keys_come_in_their_order_and_an_unknown_one_fails(tmp_path):
    record = {"measured": {"date_utc": "2026-01-01T00:00:00+00:00", "command": "cnc-twin bench", "python": "3.11",
                           "machine": {"cpu": "a cpu", "cores": 2, "system": "Linux"}, "versions": {"mujoco": "9"}},
              "first": 1.23456, "second": 7, "third": "x"}
    (tmp_path / "f.json").write_text(json.dumps(record), encoding="utf-8")
    done = _build(tmp_path, {"keys": f"# K\n\n```{{bench-figures}} {tmp_path / 'f.json'}\n:keys: third first\n```\n"})
    assert done.returncode == 0, done.stderr
    text = (tmp_path / "built" / "keys.txt").read_text(encoding="utf-8")
    assert text.index("third") < text.index("first") and "1.235" in text and "second" not in text
    bad = tmp_path / "again"
    bad.mkdir()
    done = _build(bad, {"keys": f"# K\n\n```{{bench-figures}} {tmp_path / 'f.json'}\n:keys: fourth\n```\n"})
    assert done.returncode != 0


@pytest.mark.parametrize("content", [None, {"first": 1.0}], ids=["missing file", "no machine"])
def test_a_file_it_cannot_show_fails_the_build(tmp_path, content):
    path = tmp_path / "f.json"
    if content is not None:
        path.write_text(json.dumps(content), encoding="utf-8")
    done = _build(tmp_path, {"p": f"# P\n\n```{{bench-figures}} {path}\n```\n"})
    assert done.returncode != 0


def test_the_scenario_reference_builds_without_warnings_and_names_every_key(tmp_path):
    """docs/_ext/scenario_reference.py's directive in a Markdown page and an rST one: each page lists
    a path for every key of every model in the schema."""
    from cnc_twin.scenario.json_schema import scenario_schema

    done = _build(tmp_path, {"keys": "# Keys\n\n```{scenario-reference}\n```\n",
                             "again.rst": "Again\n=====\n\n.. scenario-reference::\n"}, extension="scenario_reference")
    assert done.returncode == 0, done.stderr
    schema = scenario_schema()
    keys = set(schema["properties"]) | {key for model in schema["$defs"].values() for key in model.get("properties", {})}
    for page in ("keys.txt", "again.txt"):
        paths = re.findall(r'^"([^"]+)" : ', (tmp_path / "built" / page).read_text(encoding="utf-8"), flags=re.M)
        named = {part for path in paths for part in re.split(r"[.{},\[\]]+", path) if part}
        assert keys - named == set(), page
        assert {"program.moves[].feed", "axes.{X,Y,Z,A,B,C}.servo.kp", "faults[].duration", "whiteboard.words"} <= set(paths)

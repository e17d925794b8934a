"""The lock (requirements.lock) and pyproject.toml's ranges say the same thing.

pyproject.toml keeps compatible ranges for people who install cnc-twin into their own
environment; requirements.lock holds the exact versions the suite passed on, for the README's
Quickstart commands (``pip install -c requirements.lock ...``). A range narrowed without a new
lock, or a lock written by hand, would let a newcomer install a set nobody tested.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from packaging.markers import Marker
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).parents[1]
LOCK = ROOT / "requirements.lock"
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def _locked() -> dict[str, list[tuple[Version, Marker | None]]]:
    """Each locked package (canonical name) -> its pinned versions, each with the environment
    marker that selects it (None: every environment)."""
    pins: dict[str, list[tuple[Version, Marker | None]]] = {}
    for raw in LOCK.read_text(encoding="utf-8").splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        requirement = Requirement(line)
        (spec,) = requirement.specifier  # one exact pin per line, nothing else
        assert spec.operator == "==", f"requirements.lock: {line!r} is not an exact pin"
        pins.setdefault(canonicalize_name(requirement.name), []).append((Version(spec.version), requirement.marker))
    return pins


def _declared() -> list[tuple[str, Requirement]]:
    """Every requirement pyproject.toml declares: (where, requirement)."""
    project = PYPROJECT["project"]
    rows = [("dependencies", Requirement(text)) for text in project["dependencies"]]
    for extra, texts in project.get("optional-dependencies", {}).items():
        rows += [(f"optional-dependencies.{extra}", Requirement(text)) for text in texts]
    # an extra naming another of the project's own (test takes in docs) is that one's rows, not a pin
    return [(where, r) for where, r in rows if canonicalize_name(r.name) != canonicalize_name(project["name"])]


def _supported_pythons() -> list[str]:
    """The Python versions the classifiers name, e.g. ['3.11', '3.12', '3.13']."""
    found = [re.fullmatch(r"Programming Language :: Python :: (3\.\d+)", c) for c in PYPROJECT["project"]["classifiers"]]
    return [m.group(1) for m in found if m]


def test_every_declared_requirement_is_locked_within_its_range_for_every_supported_python():
    pins = _locked()
    pythons = _supported_pythons()
    assert pythons, "pyproject.toml's classifiers name no Python version"
    for where, requirement in _declared():
        rows = pins.get(canonicalize_name(requirement.name))
        assert rows, f"pyproject.toml {where}: {requirement} is not in requirements.lock"
        for python in pythons:
            env = {"python_version": python, "python_full_version": f"{python}.0", "sys_platform": "linux",
                   "platform_system": "Linux", "extra": ""}
            chosen = [version for version, marker in rows if marker is None or marker.evaluate(env)]
            assert len(chosen) == 1, f"requirements.lock pins {requirement.name} {len(chosen)} times for Python {python}"
            assert requirement.specifier.contains(chosen[0], prereleases=True), (
                f"requirements.lock pins {requirement.name}=={chosen[0]} (Python {python}), "
                f"outside pyproject.toml {where}: {requirement}")


def test_the_supported_pythons_agree_with_requires_python():
    """requires-python's lowest version is the lowest classifier; every classifier satisfies it."""
    from packaging.specifiers import SpecifierSet

    requires = SpecifierSet(PYPROJECT["project"]["requires-python"])
    pythons = _supported_pythons()
    assert all(requires.contains(f"{p}.0") for p in pythons), (requires, pythons)
    lowest = min(pythons, key=Version)
    below = f"3.{int(lowest.split('.')[1]) - 1}.99"
    assert not requires.contains(below), f"requires-python {requires} admits {below}, below the lowest classifier"


def test_the_lock_says_how_it_is_made_and_the_quickstart_installs_from_it():
    header = LOCK.read_text(encoding="utf-8").splitlines()[:2]
    command = header[1].lstrip("# ").strip()
    assert command.startswith("uv pip compile pyproject.toml") and "--all-extras" in command \
        and "--universal" in command and command.endswith("-o requirements.lock"), header
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    quickstart = readme.split("## Quickstart", 1)[1].split("\n## ", 1)[0]
    commands = re.findall(r"```bash\n(.*?)\n```", quickstart, re.S)
    assert len(commands) == 2, commands
    assert all("pip install -c requirements.lock " in c for c in commands), commands
    contributing = (ROOT / "CONTRIBUTING.md").read_text(encoding="utf-8")
    assert command in contributing, "CONTRIBUTING.md does not say how to refresh the lock"


def test_the_newest_dependencies_pass_runs_test_files_that_exist():
    """CI's third pass runs NEWEST_SUBSET, a list of test files in .ci/run: a file renamed or
    removed there would leave the pass with nothing to run (pytest's exit 5, seen once)."""
    script = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    listed = re.search(r"NEWEST_SUBSET=\(([^)]*)\)", script)
    assert listed is not None, "NEWEST_SUBSET not found in .ci/run"
    files = listed.group(1).split()
    assert len(files) >= 10 and all(f.startswith("tests/test_") for f in files)
    missing = [f for f in files if not (ROOT / f).is_file()]
    assert missing == [], f"NEWEST_SUBSET lists files that do not exist: {missing}"

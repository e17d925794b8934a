"""Fuzzing the scenario loader: random and mutated files give a validation error or pass, never a
traceback (the CLI's contract: one line and exit 2 for bad input)."""

from __future__ import annotations


import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import run_cli
from cnc_twin.scenario.resources import scenarios_dir

BUNDLED = [p.read_text() for p in sorted(scenarios_dir().glob("*.yaml"))]

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                    st.text(max_size=12), st.just(".nan"), st.just("-inf"))
documents = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                          st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                         max_leaves=12)


def _validate(tmp_path, text: str) -> int:
    path = tmp_path / "fuzz.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    code, _, err = run_cli("validate", path)  # any uncaught exception fails the test
    assert code in (0, 2)
    if code == 2:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    return code


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(documents)
def test_random_documents(tmp_path, doc):
    _validate(tmp_path, yaml.safe_dump(doc))


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(BUNDLED), st.data())
def test_mutated_bundled_scenarios(tmp_path, text, data):
    lines = text.splitlines()
    kind = data.draw(st.sampled_from(["drop", "garble", "retype", "truncate", "swap"]))
    i = data.draw(st.integers(0, len(lines) - 1))
    if kind == "drop":
        del lines[i]
    elif kind == "garble":
        lines[i] = lines[i][: data.draw(st.integers(0, len(lines[i])))] + data.draw(st.text(max_size=6))
    elif kind == "retype" and ":" in lines[i]:
        key = lines[i].split(":", 1)[0]
        lines[i] = f"{key}: {yaml.safe_dump(data.draw(scalars)).strip().splitlines()[0]}"
    elif kind == "truncate":
        lines = lines[:i]
    elif kind == "swap":
        j = data.draw(st.integers(0, len(lines) - 1))
        lines[i], lines[j] = lines[j], lines[i]
    _validate(tmp_path, "\n".join(lines) + "\n")

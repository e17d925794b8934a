"""Real CAM programs nobody here wrote (``../shared/data/outside-gcode``: Fusion 360, FreeCAD,
Estlcam, PyCAM, CamBam, pcb2gcode, Eagle, Inkscape gcodetools, CAMotics examples, hobbyists'
LinuxCNC programs; sources and licences in its SOURCES.tsv), each read by LinuxCNC's ``rs274`` and
by ours with the bundled machine's tool table (T1-T99): matched call for call (both may refuse it
alike, e.g. a file with no program end), or refused by ours naming a feature the polishing machine
does not have, before any difference. None may differ. docs/gcode.md states the counts and names each
refusal's reason."""

from __future__ import annotations

import re
from collections import Counter

import gcode_conformance
import oracle
import shared_data
from gcode_conformance import compare
from cnc_twin.gcode.state import ToolTable
from cnc_twin.scenario.resources import models_dir

ROOT = shared_data.ROOT


def test_every_outside_program_is_matched_or_refused_with_a_reason(tmp_path, monkeypatch):
    oracle.require()
    folder = shared_data.require(shared_data.OUTSIDE_GCODE)
    table = (models_dir() / "polisher.tbl").read_text()
    monkeypatch.setattr(oracle, "TOOL_TABLE", table)  # its lengths are 0: rs274's inches do not matter
    monkeypatch.setattr(gcode_conformance, "TOOLS", ToolTable.parse(table, units=200))
    programs = sorted(folder.iterdir())
    assert len(programs) >= 90
    verdicts = {path.name: compare(path.read_text(errors="replace"), tmp_path / "w") for path in programs}
    differing = {name: v.detail for name, v in verdicts.items() if v.kind == "differs"}
    assert not differing, differing
    counts = Counter(v.kind for v in verdicts.values())
    alike = sum(1 for v in verdicts.values() if v.kind == "matched" and v.detail)
    reasons = sorted({re.sub(r"^line \d+: ", "", v.detail) for v in verdicts.values() if v.kind == "refused"})
    readme = (ROOT / "docs" / "gcode.md").read_text()
    stated = re.search(r"(\d+) outside programs: (\d+) matched call for call \((\d+) of them refused alike by both "
                       r"readers\), (\d+) refused with a reason, (\d+) differing", readme)
    assert stated, "docs/gcode.md must state the outside corpus's counts"
    assert tuple(int(g) for g in stated.groups()) == (len(programs), counts["matched"], alike, counts["refused"], 0)
    for reason in reasons:  # each refusal's reason named in docs/gcode.md (the feature, as the refusal names it)
        feature = reason.split(" is not supported")[0]
        assert feature in readme, f"docs/gcode.md must name the refusal: {reason}"

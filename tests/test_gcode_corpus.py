"""Every example program LinuxCNC ships (185 .ngc files in its Debian 12 package), read by
LinuxCNC's ``rs274`` and by ours: each is matched call for call (both readers may refuse it
alike, e.g. a tool missing from the table) or refused by ours, naming a feature the twin's machine
does not have, before any difference. None may differ. README states the counts."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

import oracle
from gcode_conformance import compare

ROOT = Path(__file__).resolve().parents[1]


def corpus() -> list[Path]:
    return sorted((oracle.ROOT / "usr" / "share" / "linuxcnc" / "ncfiles").rglob("*.ngc"))


def test_every_shipped_program_is_matched_or_refused_with_a_reason(tmp_path):
    oracle.require()
    programs = corpus()
    assert len(programs) == 185
    verdicts = {}
    for path in programs:
        verdicts[path.name if path.parent.name == "ncfiles" else str(path.relative_to(path.parents[1]))] = \
            compare(path.read_text(errors="replace"), tmp_path / "w")
    differing = {name: v.detail for name, v in verdicts.items() if v.kind == "differs"}
    assert not differing, differing
    counts = Counter(v.kind for v in verdicts.values())
    both_refused = sum(1 for v in verdicts.values() if v.kind == "matched" and v.detail)
    readme = (ROOT / "README.md").read_text()
    stated = re.search(r"LinuxCNC's 185 example programs: (\d+) matched call for call \((\d+) of them refused "
                       r"alike by both readers\), (\d+) refused with a reason, (\d+) differing", readme)
    assert stated, "README must state the corpus counts"
    assert tuple(int(g) for g in stated.groups()) == (counts["matched"], both_refused, counts["refused"], 0)

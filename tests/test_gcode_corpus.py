"""Every example program LinuxCNC ships (185 .ngc files in its Debian 12 package), read by
LinuxCNC's ``rs274`` and by ours: each is matched call for call (both readers may refuse it
alike, e.g. a tool missing from the table) or refused by ours, naming a feature the twin's machine
does not have, before any difference. None may differ. docs/gcode.md states the counts."""

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
    readme = (ROOT / "docs" / "gcode.md").read_text()
    stated = re.search(r"LinuxCNC's 185 example programs: (\d+) matched call for call \((\d+) of them refused "
                       r"alike by both readers\), (\d+) refused with a reason, (\d+) differing", readme)
    assert stated, "docs/gcode.md must state the corpus counts"
    assert tuple(int(g) for g in stated.groups()) == (counts["matched"], both_refused, counts["refused"], 0)


OWN_PROGRAMS = sorted((ROOT / "programs").rglob("*.ngc"))
NEWER = {"Unknown g code used": "G6.2", "Unknown m code used: M100": "M100", "Unknown m code used: M101": "M101"}
"""what Debian 12's rs274 (LinuxCNC 2.9) stops at in the project's programs, and the code it lacks:
Fanuc-style G6.2 NURBS came with LinuxCNC 2.10; M100-M199 are codes a machine provides"""


def test_the_projects_own_programs_are_read_as_rs274_reads_them(tmp_path):
    """Each bundled program reads whole in ours, with every line short enough for LinuxCNC; rs274
    reads it call for call up to the first code it lacks (G6.2, M100), where it stops."""
    oracle.require()
    from gcode_conformance import ours

    assert len(OWN_PROGRAMS) >= 10
    for path in OWN_PROGRAMS:
        text = path.read_text()
        calls, _, error = ours(text)
        assert error is None, f"{path.name}:{error.line}: {error.message}"
        theirs, said = oracle.run(text, tmp_path / path.stem)
        if said:
            stop, line = said[0], said[1]
            assert NEWER.get(stop) is not None and line.upper().startswith(NEWER[stop]), f"{path.name}: rs274 {said}"
            theirs = theirs[:-2]  # the two resets after its error
        assert calls[:len(theirs)] == theirs, f"{path.name}: the calls differ before rs274 stops"

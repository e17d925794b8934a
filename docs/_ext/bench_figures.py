"""Sphinx directive ``bench-figures``: a table of the figures a benchmark wrote, with what they
were measured on, rendered from the JSON file itself, so the performance page's figures are the
benchmarks' and never prose edited by hand.

    ```{bench-figures} data/bench-nurbs_circle.json
    :keys: ratio_twin_over_bare real_time_factor twin_us_per_tick
    ```

Three kinds of file, told apart by their shape:

- ``cnc-twin bench --json`` (a flat record of figures): one row per figure (``:keys:`` picks and
  orders them; default: all);
- ``cnc-twin bench --startup --json`` (``floor_s`` and ``commands``): one row per command, its
  whole wall time, its clock, the time outside it above the floor;
- pytest-benchmark's ``--benchmark-json`` (``benchmarks``): one row per benchmark, its median,
  minimum and rounds;
- ``benchmarks/bench_long_programs.py --json`` (``rows``): one row per program and step, its
  wall time and peak memory.

All but pytest-benchmark's keep ``measured`` (:mod:`cnc_twin.studies.bench_context`); pytest-benchmark keeps
``machine_info`` and ``datetime``. Both are shown above the table. A missing or unreadable file
fails the build (a warning, which ``-W`` makes an error).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.util.docutils import SphinxDirective


def _number(value: Any) -> str:
    """A figure as the table shows it: 4 significant digits for a float, else as it is."""
    if isinstance(value, bool) or not isinstance(value, float):
        return str(value)
    return f"{value:.4g}"


def _table(header: list[str], rows: list[list[str]]) -> nodes.table:
    """A docutils table of literal-free text cells."""
    table = nodes.table()
    group = nodes.tgroup(cols=len(header))
    table += group
    for column, title in enumerate(header):  # as wide as its widest cell (the text builder wraps at it)
        group += nodes.colspec(colwidth=max([len(title), *(len(row[column]) for row in rows)]))
    head = nodes.thead()
    group += head
    body = nodes.tbody()
    group += body
    for target, cells in ((head, [header]), (body, rows)):
        for cells_of_row in cells:
            row = nodes.row()
            for text in cells_of_row:
                entry = nodes.entry()
                entry += nodes.paragraph(text=text)
                row += entry
            target += row
    return table


def _context(record: dict[str, Any]) -> str:
    """One sentence: when, with what command, on what machine and versions."""
    if "measured" in record:  # cnc-twin's own record (bench --json, the benchmarks' conftest)
        measured = record["measured"]
        versions = ", ".join(f"{name} {version}" for name, version in measured["versions"].items())
        machine = measured["machine"]
        load = f", load average {machine['load_1min']} at the end" if machine.get("load_1min") is not None else ""
        return (f"Measured {measured['date_utc']} with `{measured['command']}` on {machine['cpu']} "
                f"({machine['cores']} cores{load}, {machine['system']}), Python {measured['python']}; {versions}.")
    if "machine_info" in record:
        info = record["machine_info"]
        cpu = info.get("cpu", {}).get("brand_raw", info.get("processor", ""))
        commit = record.get("commit_info", {}).get("id", "")[:10]
        return (f"Measured {record.get('datetime', '')} with pytest-benchmark {record.get('version', '')} on {cpu} "
                f"({info.get('cpu', {}).get('count', '?')} cores, {info.get('system', '')} {info.get('release', '')}), "
                f"{info.get('python_implementation', 'Python')} {info.get('python_version', '')}"
                + (f", commit {commit}." if commit else "."))
    raise ValueError("the file says nothing of what it was measured on ('measured' or 'machine_info')")


def _rows(record: dict[str, Any], keys: list[str] | None) -> tuple[list[str], list[list[str]]]:
    if "benchmarks" in record:
        rows = []
        for bench in record["benchmarks"]:
            stats = bench["stats"]
            figures = ", ".join(f"{key} {_number(value)}" for key, value in bench.get("extra_info", {}).items())
            rows.append([bench["fullname"].split("::", 1)[-1], f"{stats['median'] * 1e6:.4g}",
                         f"{stats['min'] * 1e6:.4g}", str(stats["rounds"]), figures])
        return ["benchmark", "median [us]", "min [us]", "rounds", "its own figures"], rows
    if "rows" in record:  # benchmarks/bench_long_programs.py: a row per program and step
        rows = []
        for row in record["rows"]:
            running = row.get("memory_mb") or {}
            clock = f"{row['run_clock_s']:.1f}" if row.get("run_clock_s") is not None else ""
            rows.append([f"{row['passes']} ({row['lines']} lines)", row["step"], str(row["code"]),
                         f"{row['wall_s']:.1f}", clock, f"{(row.get('rss_mb') or 0):.0f}",
                         f"{running['at_start']:.0f} -> {running['run_max']:.0f}" if running else ""])
        return ["passes (lines)", "step", "exit", "wall [s]", "run's clock [s]", "peak memory [MB]",
                "twin while running [MB]"], rows
    if "commands" in record:
        rows = [["floor: python -c \"import numpy, mujoco, numba\"", _number(record["floor_s"]), "", "", ""]]
        for name, row in record["commands"].items():
            if "failed" in row:
                rows.append([name, f"failed (exit {row['code']})", "", "", ""])
                continue
            rows.append([name, _number(row["wall_s"]), _number(row["first_s"]), _number(row["run_clock_s"]),
                         _number(row["above_floor_s"])])
        return ["command", "whole [s]", "first [s]", "run's clock [s]", "outside the clock above the floor [s]"], rows
    figures = {key: value for key, value in record.items() if key != "measured"}
    chosen = keys if keys else list(figures)
    missing = [key for key in chosen if key not in figures]
    if missing:
        raise KeyError(f"no figure {', '.join(missing)} in the file")
    return ["figure", "value"], [[key, _number(figures[key])] for key in chosen]


class BenchFigures(SphinxDirective):
    """``bench-figures PATH`` (relative to the page's folder), option ``:keys:`` (space separated)."""

    required_arguments = 1
    option_spec = {"keys": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        path = (Path(self.env.doc2path(self.env.docname)).parent / self.arguments[0]).resolve()
        self.env.note_dependency(str(path))
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
            keys = self.options.get("keys", "").split() or None
            header, rows = _rows(record, keys)
            context = _context(record)
        except (OSError, ValueError, KeyError) as problem:
            return [self.state.document.reporter.warning(f"bench-figures {self.arguments[0]}: {problem}",
                                                         line=self.lineno)]
        said = nodes.paragraph()
        for index, part in enumerate(context.split("`")):
            said += nodes.literal(text=part) if index % 2 else nodes.Text(part)
        return [said, _table(header, rows)]


def setup(app) -> dict[str, Any]:
    app.add_directive("bench-figures", BenchFigures)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}

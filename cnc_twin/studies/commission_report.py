"""The commissioning report: the circular tests' figures before and after as a Markdown table, and
each plane's polar plot with both overlaid (PNG), in the output folder of ``cnc-twin commission``.
"""

from __future__ import annotations

from pathlib import Path

from cnc_twin.run.ballbar_plot import DIRECTION_STYLE, polar_axes
from cnc_twin.studies.commission import Commissioning, yaml_value
from cnc_twin.studies.reversal_tuning import CircularTest

DIRECTIONS = ("ccw", "cw")


def figure_row(test: CircularTest) -> dict[str, float]:
    """The acceptance figures of one test [um]: G per direction, the largest reversal spike's
    size per direction, H."""
    f = test.figures
    row = {}
    for d in DIRECTIONS:
        row[f"G {d}"] = f[d]["circular_deviation_um"]
        row[f"spike {d}"] = max(abs(v) for v in f[d]["reversal_spikes_um"].values())
    row["H"] = f["hysteresis_um"]
    return row


def report_markdown(result: Commissioning) -> str:
    """The report: the steps, then one table row per plane and figure, before and after."""
    lines = [f"# Commissioning of {result.parameters.name}", "", "## Steps", ""]
    lines += [f"- {step}" for step in result.steps]
    lines += ["", "## Circular tests (ISO 230-4, the tool tip), um", "",
              "| plane | figure | before | after |", "|---|---|---|---|"]
    for plane in result.before:
        before, after = figure_row(result.before[plane]), figure_row(result.after[plane])
        for key in before:
            lines.append(f"| {plane} | {key} | {before[key]:.1f} | {after[key]:.1f} |")
    lines += ["", "G: circular deviation (least-squares circle); spike: the largest reversal spike's size at 0 / "
              "90 / 180 / 270 deg; H: hysteresis between the directions.", ""]
    lines += ["## Settings", "", "| override | value |", "|---|---|"]
    lines += [f"| `{k}` | {yaml_value(v)} |" for k, v in result.overrides.items()]
    return "\n".join(lines) + "\n"


def overlay_png(before: CircularTest, after: CircularTest, plane: str) -> bytes:
    """One plane's polar plot: each direction's radial deviation [um] before (thin, pale) and after
    (bold) commissioning, about the nominal radius."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 6.4))
    FigureCanvasAgg(fig)
    curves = [(p, "before") for p in before.passes] + [(p, "after") for p in after.passes]
    ax, span = polar_axes(fig, (0.08, 0.1, 0.84, 0.76), before.passes + after.passes, plane)
    for p, when in curves:
        bold = when == "after"
        ax.plot(p.angle, p.deviation * 1e6, color=DIRECTION_STYLE[p.direction][0], lw=1.4 if bold else 0.8,
                alpha=1.0 if bold else 0.35, label=f"{p.direction} {when}")
    ax.legend(loc="lower left", bbox_to_anchor=(-0.1, -0.14), fontsize=7, frameon=False, ncol=3)
    b, a = figure_row(before), figure_row(after)
    ax.set_title(f"circular test {plane}, before (pale) and after (bold) commissioning\n"
                 f"G {max(b['G ccw'], b['G cw']):.1f} -> {max(a['G ccw'], a['G cw']):.1f} um, "
                 f"H {b['H']:.1f} -> {a['H']:.1f} um; rings every {span / 2:g} um", fontsize=9)
    out = io.BytesIO()
    fig.savefig(out, format="png", dpi=90)
    return out.getvalue()


def write_report(result: Commissioning, out: Path) -> list[Path]:
    """``report.md`` and ``ballbar_<plane>.png`` for every plane in ``out``; the paths written."""
    written = [out / "report.md"]
    written[0].write_text(report_markdown(result))
    for plane in result.before:
        path = out / f"ballbar_{plane.lower()}.png"
        path.write_bytes(overlay_png(result.before[plane], result.after[plane], plane))
        written.append(path)
    return written

"""The circular test's polar plot, as a ballbar's software draws it: each direction's radial
deviation [um] around the nominal circle, magnified (the ring scale says by how much), with the
ISO 230-4 figures beside it. PNG bytes, for the run directory (``ballbar.png``) and the recording.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from cnc_twin.core.config import BallbarTest
from cnc_twin.run.ballbar import BallbarPass

DIRECTION_STYLE = {"ccw": ("tab:blue", "counter-clockwise"), "cw": ("tab:red", "clockwise")}


def polar_axes(fig, rect: tuple[float, float, float, float], passes: list[BallbarPass], plane: str):
    """Polar axes on ``fig`` at ``rect`` for ``passes``' radial deviations [um]: zero (the nominal
    circle, dashed) well off the centre, rings on round micrometres spanning the largest
    deviation, the plane's axes at the quadrants. Returns the axes and the span [um]."""
    ax = fig.add_axes(rect, projection="polar")
    span = max(5.0, 1.2 * max((float(np.abs(p.deviation).max()) * 1e6 for p in passes), default=0.0))
    span = float(np.ceil(span / 10.0) * 10.0)  # rings on round micrometres
    ax.set_rorigin(-3 * span)  # zero deviation (the nominal circle) well off the centre
    ax.set_ylim(-span, span)
    ax.set_rticks(np.linspace(-span, span, 5))
    ax.set_rlabel_position(22.5)
    ax.tick_params(labelsize=8)
    full = np.linspace(0, 2 * np.pi, 361)
    ax.plot(full, np.zeros_like(full), color="0.3", lw=0.8, ls="--", label="nominal radius")
    first, second = plane
    ax.set_xticks(np.radians([0, 90, 180, 270]), [f"+{first}", f"+{second}", f"-{first}", f"-{second}"])
    return ax, span


def polar_plot_png(passes: list[BallbarPass], figures: dict[str, Any], test: BallbarTest) -> bytes:
    """The plot of ``passes`` (from :func:`~cnc_twin.run.ballbar.ballbar_passes`) with
    ``figures`` (metrics.json's ``ballbar``) as PNG bytes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.6, 6.2))
    FigureCanvasAgg(fig)  # a figure of its own: no pyplot state
    ax, span = polar_axes(fig, (0.04, 0.08, 0.52, 0.8), passes, test.plane)
    deviations = [p.deviation * 1e6 for p in passes]
    seen = set()
    for p, d in zip(passes, deviations):
        colour, name = DIRECTION_STYLE[p.direction]
        ax.plot(p.angle, d, color=colour, lw=1.1, label=None if p.direction in seen else name)
        seen.add(p.direction)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.05, -0.12), fontsize=8, frameon=False)
    feed = next((figures[d]["feed_mm_min"] for d in ("ccw", "cw") if d in figures), float("nan"))
    ax.set_title(f"circular test (ISO 230-4), {test.plane} plane: R {test.radius * 1e3:g} mm, "
                 f"F {feed:.0f} mm/min\nradial deviation [um], rings every {span / 2:g} um", fontsize=10)
    fig.text(0.6, 0.86, _figure_lines(figures), va="top", family="monospace", fontsize=8.5)
    out = io.BytesIO()
    fig.savefig(out, format="png", dpi=100)
    return out.getvalue()


def _figure_lines(figures: dict[str, Any]) -> str:
    lines = []
    for direction in ("ccw", "cw"):
        f = figures.get(direction)
        if f is None:
            continue
        spikes = f["reversal_spikes_um"]
        lines += [f"{DIRECTION_STYLE[direction][1]}",
                  f"  circular deviation G {f['circular_deviation_um']:7.1f} um",
                  f"  radial deviation F  {f['radial_deviation_um']['min']:+7.1f} .. "
                  f"{f['radial_deviation_um']['max']:+.1f} um",
                  f"  radius error        {f['radius_error_um']:+7.1f} um",
                  f"  centre offset       {f['centre_offset_um'][0]:+.1f}, {f['centre_offset_um'][1]:+.1f} um",
                  "  reversal spikes at 0 / 90 / 180 / 270 deg:",
                  "    " + " / ".join(f"{spikes[q]:+.1f}" for q in ("0", "90", "180", "270")) + " um", ""]
    if "hysteresis_um" in figures:
        lines.append(f"hysteresis H {figures['hysteresis_um']:.1f} um")
    return "\n".join(lines) if lines else "no pass around the centre"

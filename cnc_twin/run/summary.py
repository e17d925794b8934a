"""The terminal summary of a finished run: timing, following error per axis, whiteboard, path
and polishing figures, limit warnings."""

from __future__ import annotations


def summary_table(metrics: dict) -> str:
    """The terminal summary: timing line and one row per axis."""
    lines = [
        f"{metrics['scenario']}: {metrics['sim_time_s']:.3f} s simulated in {metrics['wall_time_s']:.2f} s "
        f"({metrics['real_time_factor']:.1f}x real time), {metrics['physics_steps']} physics steps",
    ]
    machine = metrics.get("machine")
    if machine:  # which machine the figures are of (the compliant default or the rigid variant)
        lines.append(f"machine: {machine['model']} with {machine['parameters']}")
    # analog output: ticks each DAC spent clamped; pulse output: ticks at the pulse rate limit
    limited = metrics.get("pulse_limited_ticks") or metrics["dac_saturation_ticks"]
    lines.append(f"{'axis':<5}{'max ferr':>14}{'rms ferr':>14}{'final ferr':>14}"
                 f"{'rate lim' if 'pulse_limited_ticks' in metrics else 'DAC sat':>9}")
    for axis, fe in metrics["following_error"].items():
        final = metrics["final_following_error"][axis]
        unit = fe["unit"]
        lines.append(
            f"{axis:<5}{fe['max']:>10.4f} {unit:<3}{fe['rms']:>10.4f} {unit:<3}{fixed(final['value'], 4):>10} {unit:<3}"
            f"{limited[axis]:>9d}"
        )
    wb = metrics.get("whiteboard")
    if wb:
        lat = wb["exchange_latency_us"]
        lines.append(
            f"whiteboard ({metrics['mode']}): {wb['exchanges']} exchanges, {wb['missed_exchanges']} missed, "
            f"{wb['records_accepted']} records accepted, {wb['records_rejected']} rejected, "
            f"{wb['underrun_periods']} underrun periods"
            + (f", answer latency median {lat['median']:.1f} us" if lat["median"] is not None else "")
        )
    path = metrics.get("path")
    if path and "contour_error_um" in path:
        lines.append(path_line(path, (metrics.get("program") or {}).get("feed") or {}))
    for v in (path or {}).get("limit_violations", []):
        lines.append(f"WARNING: commanded {v['axis']} {v['quantity']} {v['ratio']:.2f}x its limit "
                     f"({v['peak']:.4g} against {v['limit']:.4g} {v['unit']}) at {v['time_s']:.3f} s")
    program = metrics.get("program")
    if program and "deviation_um" in program:
        lines.append(program_line(program))
    polish = metrics.get("polish")
    if polish:
        lines.append(polish_line(polish))
    if metrics.get("ballbar"):
        lines.append(ballbar_line(metrics["ballbar"]))
    if metrics.get("contour"):
        from cnc_twin.run.contour_metrics import format_passes

        lines.append(format_passes(metrics["contour"]))
    lines.append(f"final state: {metrics['final_state']}" if "final_state" in metrics else "")
    if metrics.get("mujoco_warnings"):
        lines.append(f"MuJoCo warnings: {metrics['mujoco_warnings']}")
    return "\n".join(lines)


def path_line(path: dict, feed: dict) -> str:
    """The path figures on one line. An NC program's are over its feed paths only (its G1 moves run
    one by one as coordinated moves, not curves): the line says how much that covers, and which
    path the largest contour error is on."""
    if "feed_paths" in path:
        what = f"feed paths: {path['feed_paths']}, {path['length_mm']:.1f} mm"
        moves = feed.get("moves_length_mm") or 0.0
        if moves > 0.05:
            what += f" (and {moves:.1f} mm of G1 moves run one by one, outside these figures)"
        worst = max(path.get("paths") or [], key=lambda p: p.get("contour_error_um") or 0.0, default=None)
        # named even when it is the only one: a CAM program's only feed path is often its plunge
        where = f" on the path from line {worst['line']}" if worst else ""
    else:
        what, where = f"path: {path['length_mm']:.1f} mm", ""
    return (f"{what}, contour error max {path['contour_error_um']['max']:.2f} um{where} "
            f"rms {path['contour_error_um']['rms']:.2f} um (by the encoders: max "
            f"{path['encoder_contour_error_um']['max']:.2f} um), chord error max {path['chord_error_um']['max']:.3f} um, "
            f"feed fluctuation max {path['feed_fluctuation']['max']:.2e}")


def ballbar_line(ballbar: dict) -> str:
    """The circular test's figures on one line (ISO 230-4's names; metrics.json's ``ballbar``)."""
    head = f"circular test {ballbar['plane']} R {ballbar['radius_mm']:g} mm"
    runs = [(d, ballbar[d]) for d in ("ccw", "cw") if d in ballbar]
    if not runs:
        return f"{head}: no pass went around the centre"
    parts = [f"{d.upper()} G {f['circular_deviation_um']:.1f} um (F {f['radial_deviation_um']['min']:+.1f} .. "
             f"{f['radial_deviation_um']['max']:+.1f}), radius error {f['radius_error_um']:+.1f} um, "
             f"largest reversal spike {max(f['reversal_spikes_um'].values(), key=abs):+.1f} um"
             for d, f in runs]
    hysteresis = f"; hysteresis H {ballbar['hysteresis_um']:.1f} um" if "hysteresis_um" in ballbar else ""
    return f"{head}: " + "; ".join(parts) + hysteresis + " (polar plot: ballbar.png)"


def fixed(value: float, digits: int) -> str:
    """``value`` with ``digits`` decimals, a value that rounds to zero shown as 0 (not ``-0.0000``:
    the sign of something too small to show is noise, not a direction)."""
    return f"{round(value, digits) + 0.0:.{digits}f}"


def polish_line(polish: dict) -> str:
    """One line of a polishing run's figures: force tracking, first contact, removed volume."""
    force, removal = polish.get("force") or {}, polish["removal"]
    parts = []
    track = force.get("tracking")
    if track:
        parts.append(f"force {force['setpoint_n']:g} N, tracking rms {track['rms_error_pct']:.2f} % "
                     f"(max {track['max_error_pct']:.1f} %)")
    if force.get("first_contact"):
        parts.append(f"first-contact overshoot {force['first_contact']['overshoot_pct']:.1f} %")
    volume = f"removed {removal['volume_mm3']:.4g} mm3"
    if "preston_by_hand_mm3" in removal:
        volume += f" (Preston by hand {removal['preston_by_hand_mm3']:.4g} mm3)"
    parts.append(volume)
    return "polish: " + ", ".join(parts)


def program_line(program: dict) -> str:
    """One line of a G-code run against its program: deviation, feed held, fits."""
    d, feed, fits = program["deviation_um"], program["feed"], program["fits"]
    p = f" (G64 P {d['tolerance_um']:g} um)" if d["tolerance_um"] is not None else ""
    text = (f"program: deviation from it max {d['max']:.2f} um, its vertices {d['vertices_max']:.2f} um{p}; "
            f"feed motion (G1, paths and moves) {feed['time_s']:.2f} s (at F: {feed['ideal_time_s']:.2f} s), "
            f"{100 * (feed['share_at_95pct'] or 0):.1f} % of it at >= 95 % of F")
    if fits["runs"]:
        text += f"; {fits['runs']} run(s) of lines fitted in {fits['spans']} spans"
    return text

"""The plane views of the path: the contour error they magnify is the distance to the commanded
path (not the lag along it), by a round factor; the planes drawn are those the program moves in."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.view.path_views import nearest_on_path, planes_moved, plane_paths, program_strips, round_factor


def circle(radius: float, angles: np.ndarray, z: float = 0.0) -> np.ndarray:
    return np.column_stack([radius * np.cos(angles), radius * np.sin(angles), np.full_like(angles, z)])


def test_a_lagging_path_off_by_a_radius_step_is_that_far_from_the_commanded_one():
    """Actual on a circle 10 um larger, 40 samples behind: every point's distance to the
    commanded polyline is the radius step (analytic: |r - R|), to the chord's sagitta."""
    angles = np.linspace(0, 2 * np.pi, 2001)
    command = circle(40.0, angles)[:, :2]
    actual = circle(40.010, angles - 40 * (angles[1] - angles[0]))[:, :2]
    distance = np.linalg.norm(actual - nearest_on_path(command, actual), axis=1)
    sagitta = 40.0 * (1 - np.cos((angles[1] - angles[0]) / 2))
    assert np.all(np.abs(distance[40:] - 0.010) <= sagitta + 1e-9)
    lag = np.linalg.norm(actual - command, axis=1)
    assert lag[40:].min() > 5.0  # the lag itself is millimetres: it is not what is drawn


@pytest.mark.parametrize("error, extent, factor", [(0.010, 80.0, 200), (0.001, 80.0, 2000), (2.0, 80.0, 2),
                                                   (10.0, 80.0, 1), (0.0, 80.0, 1)])
def test_the_factor_is_round_and_keeps_the_magnified_error_within_a_twentieth_of_the_path(error, extent, factor):
    assert round_factor(error, extent) == factor


def test_the_drawing_magnifies_the_radius_step_by_the_stated_factor():
    angles = np.linspace(0, 2 * np.pi, 2001)
    command, actual = circle(0.040, angles, 0.1), circle(0.040010, np.clip(angles - 0.02, 0, None), 0.1)  # [m]
    commands, actuals, factor, largest = plane_paths([(command, actual)], "XY")
    assert factor == 200 and largest == pytest.approx(0.010, abs=1e-4)
    radii = np.linalg.norm(actuals[0][50:], axis=1)
    assert np.allclose(radii, 40.0 + factor * 0.010, atol=factor * 1e-4)


def test_planes_and_strips():
    angles = np.linspace(0, 2 * np.pi, 200)
    flat = circle(0.04, angles)
    assert planes_moved(flat) == ["XY"]
    helix = flat + np.column_stack([np.zeros((200, 2)), np.linspace(0, 0.02, 200)])
    assert planes_moved(helix) == ["XY", "XZ", "YZ"]
    on_path = np.zeros(200, bool)
    on_path[10:60] = on_path[100:180] = True
    strips = program_strips(flat, flat, on_path)
    assert [len(c) for c, _ in strips] == [50, 80]
    assert [len(c) for c, _ in program_strips(flat, flat, np.zeros(200, bool))] == [200]  # no curve: all


def _nearest_by_definition(command: np.ndarray, actual: np.ndarray, window: int) -> np.ndarray:
    """The definition in numpy passes, one per offset (the first of equally near segments wins)."""
    n = len(command)
    best, nearest, index = np.full(n, np.inf), command.copy(), np.arange(n)
    for offset in range(-window, window + 1):
        seg = np.clip(index + offset, 0, n - 2)
        a, ab = command[seg], command[seg + 1] - command[seg]
        length2 = np.einsum("ij,ij->i", ab, ab)
        t = np.einsum("ij,ij->i", actual - a, ab) / np.where(length2 > 0, length2, 1.0)
        foot = a + np.clip(t, 0.0, 1.0)[:, None] * ab
        distance = np.linalg.norm(actual - foot, axis=1)
        closer = distance < best
        best[closer], nearest[closer] = distance[closer], foot[closer]
    return nearest


@pytest.mark.parametrize("n, d, window", [(2, 2, 64), (3, 2, 1), (10, 3, 64), (500, 2, 64), (2000, 3, 8)])
def test_the_compiled_search_is_the_definition(n, d, window):
    rng = np.random.default_rng(n + d)
    command = np.cumsum(rng.normal(size=(n, d)), axis=0)
    command[n // 3: n // 3 + 2] = command[n // 3]  # a zero-length segment
    actual = command + rng.normal(scale=0.4, size=(n, d))
    got = nearest_on_path(command, actual, window)
    assert np.allclose(got, _nearest_by_definition(command, actual, window), rtol=0, atol=1e-12)

"""f_D against hand-computed distances, for every pair of geometries."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_evolution.sdbc.distance import Discs, Segments, Workspace, entity_distance


def disc(x: float, y: float, r: float | None) -> Discs:
    """One entity (S = 1) in one trial (B = 1)."""
    return Discs(
        x=np.array([[x]]), y=np.array([[y]]), r=None if r is None else np.array([[r]])
    )


def polygon(*segments: tuple[tuple[float, float], tuple[float, float]]) -> Segments:
    """One polygon entity (S = 1, B = 1) with P segments."""
    seg = np.array(segments, dtype=float)  # (P, 2, 2)
    return Segments.between(
        ax=seg[:, 0, 0, None, None],
        ay=seg[:, 0, 1, None, None],
        bx=seg[:, 1, 0, None, None],
        by=seg[:, 1, 1, None, None],
    )


def f_d(a, b) -> float:
    return float(entity_distance(a, b).item())


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        # circle-circle: centre distance 5 minus radii 1 and 2.
        (disc(0, 0, 1), disc(3, 4, 2), 2.0),
        # overlapping circles touch: floored at 0.
        (disc(0, 0, 3), disc(3, 4, 3), 0.0),
        # circle-point: 5 minus the radius 1.
        (disc(0, 0, 1), disc(3, 4, None), 4.0),
        # point-point.
        (disc(1, 1, None), disc(4, 5, None), 5.0),
    ],
)
def test_disc_distances(a: Discs, b: Discs, expected: float) -> None:
    assert f_d(a, b) == pytest.approx(expected, abs=1e-12)
    assert f_d(b, a) == pytest.approx(expected, abs=1e-12)


L_SHAPE = polygon(((0, 0), (4, 0)), ((4, 0), (4, 4)))


@pytest.mark.parametrize(
    ("point", "expected"),
    [
        # Above the first segment's interior: perpendicular distance 2, radius 0.5.
        ((1.0, 2.0, 0.5), 1.5),
        # Beyond the first segment's start (0, 0): distance to that end, 5.
        ((-3.0, -4.0, 1.0), 4.0),
        # Right of the second segment: 3 - 1.
        ((7.0, 2.0, 1.0), 2.0),
        # Nearest to the shared corner (4, 0): sqrt(2^2 + 2^2) - 0.
        ((6.0, -2.0, None), 8**0.5),
        # A circle cutting a segment is touching it: 0.
        ((2.0, 0.5, 1.0), 0.0),
    ],
)
def test_circle_polygon(point: tuple, expected: float) -> None:
    a = disc(*point)
    assert f_d(a, L_SHAPE) == pytest.approx(expected, abs=1e-12)
    assert f_d(L_SHAPE, a) == pytest.approx(expected, abs=1e-12)


def test_degenerate_segment_is_its_end_point() -> None:
    dot = polygon(((3.0, 4.0), (3.0, 4.0)))
    assert f_d(disc(0, 0, 1), dot) == pytest.approx(4.0)


@pytest.mark.parametrize(
    ("other", "expected"),
    [
        # Crossing segments.
        (polygon(((2, -1), (2, 1))), 0.0),
        # Parallel, 3 apart.
        (polygon(((0, 3), (4, 3))), 3.0),
        # Collinear, 2 beyond the end.
        (polygon(((6, 0), (9, 0))), 2.0),
        # A segment whose nearest point is an end of the other: (5, 2) to (4, 0).
        (polygon(((5, 2), (5, 6))), 5**0.5),
        # Touching at an end point.
        (polygon(((4, 0), (4, 5))), 0.0),
    ],
)
def test_polygon_polygon(other: Segments, expected: float) -> None:
    line = polygon(((0, 0), (4, 0)))
    assert f_d(line, other) == pytest.approx(expected, abs=1e-12)
    assert f_d(other, line) == pytest.approx(expected, abs=1e-12)


def test_polygon_distance_is_to_the_nearest_segment() -> None:
    # Two polygons: the least over all segment pairs.
    a = polygon(((0, 0), (1, 0)), ((10, 10), (11, 10)))
    b = polygon(((0, 5), (1, 5)), ((10, 12), (11, 12)))
    assert f_d(a, b) == pytest.approx(2.0)


def test_batch_broadcast_and_workspace_reuse() -> None:
    # Three trials, two circles each against a shared (B = 1) polygon.
    x = np.array([[0.0, 1.0, 2.0], [5.0, 6.0, 7.0]])  # (S, B)
    y = np.full((2, 3), 3.0)
    circles = Discs(x=x[:, None], y=y[:, None], r=np.full((2, 1, 3), 1.0))
    floor = Segments.between(
        ax=np.full((1, 1, 1, 1), -100.0),
        ay=np.zeros((1, 1, 1, 1)),
        bx=np.full((1, 1, 1, 1), 100.0),
        by=np.zeros((1, 1, 1, 1)),
    )
    ws = Workspace()
    first = entity_distance(circles, floor, ws, "k").copy()
    assert first.shape == (2, 1, 3)
    np.testing.assert_allclose(first, 2.0)
    # The same key reuses the same scratch arrays, with the new values.
    lifted = Discs(x=circles.x, y=circles.y + 1.0, r=circles.r)
    np.testing.assert_allclose(entity_distance(lifted, floor, ws, "k"), 3.0)

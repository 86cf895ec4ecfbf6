"""Eqs. 3 to 5 fused with f_D (eq. 1) into compiled loops, one call per feature.

:class:`~sdbc_evolution.sdbc.features.StepFeatures` computes a feature as a chain
of whole-array numpy operations (:mod:`.distance`, then a masked sum over slots).
At the batch sizes evolution runs (a generation is a few hundred trials), each of
those operations costs more in numpy's per-call overhead than in arithmetic, and a
step of predator-prey makes about 350 of them. The loops here do the same IEEE
operations in the same order for the common shapes, so their totals are the same
to the bit:

- :func:`occupancy`: a group's absent slots and its size (eq. 2, and the counts
  of eqs. 3 to 5);
- :func:`mean_state_totals`: every attribute's sum over a group's present
  entities (the numerators of eq. 3);
- :func:`disc_pair_total`: the sum of f_D over a list of disc pairs (circles or
  points), the numerator of eq. 4 (pairs i < j of one group) or of eq. 5 (every
  pair of two groups);
- :func:`disc_segment_total`: the same for pairs of a disc and a polygon;
- :func:`size_features`: from the groups' sizes, eq. 2 and the counts of
  eqs. 3 to 5 that are not constant, the numpy operations of a handful of calls.

A pair or an entity that is absent adds 0, the sums run in slot order starting
from the first term, as ``features._slot_sum`` adds them, and the floor at 0 keeps
a NaN, as ``np.maximum`` does. Distances between two polygons stay in numpy
(:func:`.distance.segment_segment_distance2`): no task has two moving polygons.
``StepFeatures(fused=False)`` computes every feature the numpy way, which the tests
use as the oracle.

Arrays are slot-major with the batch last, as :mod:`.distance` lays them out; a
batch axis of 1 is shared by every trial.
"""

from __future__ import annotations

import functools

import numpy as np
from sdbc_sim.compiled import compiled


# Made once per size and shared (the loops only read them): they stand in at
# every step for what points and full groups lack.
@functools.cache
def no_radius(slots: int) -> np.ndarray:
    """The (S, 1) radii of points: subtracting +0 leaves every float as it is."""
    return np.zeros((slots, 1))


@functools.cache
def none_absent(slots: int) -> np.ndarray:
    """The (S, 1) absence mask of a group whose slots are always full."""
    return np.zeros((slots, 1), dtype=np.bool_)


def pair_slots(first: int, second: int) -> tuple[np.ndarray, np.ndarray]:
    """Every pair of a slot of one group (``first`` slots) with a slot of another,
    in the row-major order of eq. 5's sum: ``(0, 0), (0, 1), ..., (1, 0), ...``."""
    return (
        np.repeat(np.arange(first, dtype=np.int64), second),
        np.tile(np.arange(second, dtype=np.int64), first),
    )


@compiled("void(boolean[:, :], boolean[:, ::1], float64[::1])")
def occupancy(
    present: np.ndarray, absent: np.ndarray, size: np.ndarray
) -> None:  # pragma: no cover - compiled; tested through StepFeatures
    """``absent[s, b] = not present[b, s]`` and ``size[b]`` the number of slots
    present in trial ``b``, in one pass instead of numpy's transpose, negation,
    conversion and sum over slots (the sizes are whole numbers, exact in any
    order).

    Args:
        present: (B|1, S), a group's presence as the task state holds it.
        absent: (S, B|1), the slot-major absence the other loops take.
        size: (B|1,), the group's size as a float.
    """
    for b in range(present.shape[0]):
        n = 0.0
        for s in range(present.shape[1]):
            here = present[b, s]
            absent[s, b] = not here
            if here:
                n += 1.0
        size[b] = n


GROUP_SIZE, SIZE_COUNT, PAIR_COUNT, CROSS_COUNT = range(4)
"""What a row of :func:`size_features`' plan writes."""


@compiled(
    "void(float64[:, ::1], int64[::1], int64[:, ::1], float64[:, :], float64[:, :])"
)
def size_features(
    sizes: np.ndarray,
    width: np.ndarray,
    plan: np.ndarray,
    total: np.ndarray,
    count: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through StepFeatures
    """Writes what the groups' sizes give, a plan row ``(what, f, g, h, rows)`` at
    a time, with the IEEE operations of the numpy formulation in its order:

    - ``GROUP_SIZE``: eq. 2, ``total[f] = (n_g - h) / rows`` (h the group's
      min_size, rows its max_size less its min_size);
    - ``SIZE_COUNT``: ``count[f:f + rows] = n_g`` (eq. 3's entities);
    - ``PAIR_COUNT``: ``count[f] = n_g (n_g - 1) / 2`` (eq. 4's pairs);
    - ``CROSS_COUNT``: ``count[f] = n_g n_h`` (eq. 5's pairs).

    Args:
        sizes: (G, B) each group's size per trial, in its first ``width[g]``
            columns: B, or 1 where one value holds for every trial (then
            copied over the row).
        width: (G,) see ``sizes``.
        plan: (K, 5) the rows.
        total, count: (F, B) the features' sums and counts.
    """
    n_trials = total.shape[1]
    # Shared sizes spread over their row first: the loops below then read
    # plain rows, which the compiler vectorises.
    for g in range(sizes.shape[0]):
        if width[g] == 1:
            for b in range(1, n_trials):
                sizes[g, b] = sizes[g, 0]
    for k in range(plan.shape[0]):
        what, f, g, h, rows = plan[k, 0], plan[k, 1], plan[k, 2], plan[k, 3], plan[k, 4]
        n = sizes[g]
        if what == GROUP_SIZE:
            low = float(h)
            span = float(rows)
            for b in range(n_trials):
                total[f, b] = (n[b] - low) / span
        elif what == SIZE_COUNT:
            for r in range(rows):
                for b in range(n_trials):
                    count[f + r, b] = n[b]
        elif what == PAIR_COUNT:
            for b in range(n_trials):
                c = n[b] - 1.0
                c = n[b] * c
                count[f, b] = c / 2.0
        else:
            other = sizes[h]
            for b in range(n_trials):
                count[f, b] = n[b] * other[b]


def batch_row(array: np.ndarray, slot: int, spare: np.ndarray) -> np.ndarray:
    """Row ``slot`` of an (S, B|1) array as B values: the row itself, or its one
    value copied into ``spare`` (B,) when the array is shared by every trial. The
    loops below then run over plain contiguous rows, which the compiler turns into
    vector instructions (each trial's operations stay the same and in order)."""
    if array.shape[1] == spare.shape[0]:
        return array[slot]
    spare[:] = array[slot, 0]
    return spare


@compiled("void(float64[:, :, :], boolean[:, :], float64[:, :])", calls=(batch_row,))
def mean_state_totals(
    attributes: np.ndarray, absent: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled; tested through StepFeatures
    """``out[a, b] = sum_s attributes[b, s, a]`` over the slots ``s`` present in
    trial ``b``.

    Args:
        attributes: (B|1, S, A), a group's state attributes as the task state
            holds them.
        absent: (S, B|1), True where a slot holds no entity.
        out: (A, B), the attributes' rows of the feature totals.
    """
    # A slot at a time over every trial's row, as the distance loops go: the
    # compiler turns the rows into vector instructions; trial by trial (the
    # sum over a trial's slots innermost) they stayed scalar.
    n = out.shape[1]
    spare = np.empty(n)
    spare_absent = np.empty(n, dtype=np.bool_)
    for a in range(out.shape[0]):
        slots = attributes[:, :, a].T
        total = out[a]
        for s in range(slots.shape[0]):
            values = batch_row(slots, s, spare)
            skip = batch_row(absent, s, spare_absent)
            if s == 0:
                for b in range(n):
                    total[b] = 0.0 if skip[b] else values[b]
            else:
                for b in range(n):
                    total[b] = total[b] + (0.0 if skip[b] else values[b])


def add_term(
    out: np.ndarray, b: int, first: bool, d: float, absent1: bool, absent2: bool
) -> None:
    """Adds one pair's f_D, ``d`` less the radii, to trial ``b``'s total: floored
    at 0 (``np.maximum``: a NaN stays), 0 for a pair with an absent entity, and
    the first term stored rather than added, as ``features._slot_sum`` does."""
    if d < 0.0:
        d = 0.0
    if absent1 or absent2:
        d = 0.0
    out[b] = d if first else out[b] + d


@compiled(
    "void(float64[:, ::1], float64[:, ::1], float64[:, ::1], boolean[:, ::1], "
    "float64[:, ::1], float64[:, ::1], float64[:, ::1], boolean[:, ::1], "
    "int64[::1], int64[::1], float64[::1])",
    calls=(batch_row, add_term),
)
def disc_pair_total(
    ax: np.ndarray,
    ay: np.ndarray,
    ar: np.ndarray,
    a_absent: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    br: np.ndarray,
    b_absent: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through StepFeatures
    """``out[b] = sum_p f_D(a[first[p]], b[second[p]])`` in trial ``b``, a pair
    with an absent entity adding 0.

    Args:
        ax, ay, ar: (S, B|1) centres and radii of the first group's discs
            (:func:`no_radius` for points).
        a_absent: (S, B|1) absence of the first group (:func:`none_absent` if
            full).
        bx, by, br, b_absent: The same for the second group (the first again for
            a dispersion).
        first, second: The pairs' slots, in the order of the sum.
        out: (B,) the feature's row of the totals.
    """
    n = out.shape[0]
    spare = np.empty((6, n))
    spare_absent = np.empty((2, n), dtype=np.bool_)
    if first.shape[0] == 0:
        out[:] = 0.0
    for p in range(first.shape[0]):
        i = first[p]
        j = second[p]
        x1 = batch_row(ax, i, spare[0])
        y1 = batch_row(ay, i, spare[1])
        r1 = batch_row(ar, i, spare[2])
        x2 = batch_row(bx, j, spare[3])
        y2 = batch_row(by, j, spare[4])
        r2 = batch_row(br, j, spare[5])
        absent1 = batch_row(a_absent, i, spare_absent[0])
        absent2 = batch_row(b_absent, j, spare_absent[1])
        for b in range(n):
            dx = x1[b] - x2[b]
            dy = y1[b] - y2[b]
            d = np.sqrt(dx * dx + dy * dy)
            d = d - r1[b]
            d = d - r2[b]
            add_term(out, b, p == 0, d, absent1[b], absent2[b])


def shared_least(
    px: np.ndarray,
    py: np.ndarray,
    ax: float,
    ay: float,
    abx: float,
    aby: float,
    inv: float,
    first: bool,
    least: np.ndarray,
) -> None:
    """One segment's step of :func:`disc_segment_total` for a segment shared by
    every trial: the squared distance of each centre (``px``, ``py``) to it,
    kept in ``least`` where smaller (the first segment's stored), with the
    operations of the general path on the same values."""
    for b in range(px.shape[0]):
        dx = px[b] - ax
        dy = py[b] - ay
        t = (dx * abx + dy * aby) * inv
        if t < 0.0:
            t = 0.0
        elif t > 1.0:
            t = 1.0
        dx = dx - t * abx
        dy = dy - t * aby
        d2 = dx * dx + dy * dy
        if first or (not np.isnan(least[b]) and not least[b] <= d2):
            least[b] = d2


@compiled(
    "void(float64[:, ::1], float64[:, ::1], float64[:, ::1], boolean[:, ::1], "
    "float64[:, :, ::1], float64[:, :, ::1], float64[:, :, ::1], float64[:, :, ::1], "
    "float64[:, :, ::1], boolean[:, ::1], int64[::1], int64[::1], float64[::1])",
    calls=(batch_row, add_term, shared_least),
)
def disc_segment_total(
    cx: np.ndarray,
    cy: np.ndarray,
    cr: np.ndarray,
    c_absent: np.ndarray,
    sax: np.ndarray,
    say: np.ndarray,
    sabx: np.ndarray,
    saby: np.ndarray,
    inverse: np.ndarray,
    s_absent: np.ndarray,
    disc: np.ndarray,
    polygon: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through StepFeatures
    """``out[b] = sum_p f_D(disc[p], polygon[p])`` in trial ``b``: the least
    distance from the disc's centre to the polygon's segments, less its radius,
    floored at 0; a pair with an absent entity adds 0.

    Args:
        cx, cy, cr, c_absent: (S, B|1) the discs, as in :func:`disc_pair_total`.
        sax, say, sabx, saby, inverse: (P, S, B|1) the polygons' segments: first
            end point, end-to-end vector and ``1 / |b - a|^2`` (0 if degenerate),
            as :class:`.distance.Segments` holds them.
        s_absent: (S, B|1) absence of the polygons' group.
        disc, polygon: The pairs' slots, in the order of the sum.
        out: (B,) the feature's row of the totals.
    """
    n = out.shape[0]
    spare = np.empty((8, n))
    spare_absent = np.empty((2, n), dtype=np.bool_)
    least = np.empty(n)
    # Polygons shared by every trial (walls): their values as scalars rather
    # than rows of copies, the same operations on the same values.
    shared = sax.shape[2] == 1 and n > 1
    if disc.shape[0] == 0:
        out[:] = 0.0
    for p in range(disc.shape[0]):
        i = disc[p]
        k = polygon[p]
        px = batch_row(cx, i, spare[0])
        py = batch_row(cy, i, spare[1])
        for q in range(sax.shape[0]):
            if shared:
                shared_least(
                    px,
                    py,
                    sax[q, k, 0],
                    say[q, k, 0],
                    sabx[q, k, 0],
                    saby[q, k, 0],
                    inverse[q, k, 0],
                    q == 0,
                    least,
                )
                continue
            ax = batch_row(sax[q], k, spare[2])
            ay = batch_row(say[q], k, spare[3])
            abx = batch_row(sabx[q], k, spare[4])
            aby = batch_row(saby[q], k, spare[5])
            inv = batch_row(inverse[q], k, spare[6])
            for b in range(n):
                dx = px[b] - ax[b]
                dy = py[b] - ay[b]
                t = (dx * abx[b] + dy * aby[b]) * inv[b]
                # np.clip: NaN stays NaN.
                if t < 0.0:
                    t = 0.0
                elif t > 1.0:
                    t = 1.0
                dx = dx - t * abx[b]
                dy = dy - t * aby[b]
                d2 = dx * dx + dy * dy
                # np.minimum: a NaN, once met, stays.
                if q == 0 or (not np.isnan(least[b]) and not least[b] <= d2):
                    least[b] = d2
        r = batch_row(cr, i, spare[7])
        absent_disc = batch_row(c_absent, i, spare_absent[0])
        absent_polygon = batch_row(s_absent, k, spare_absent[1])
        for b in range(n):
            d = np.sqrt(least[b])
            d = d - r[b]
            add_term(out, b, p == 0, d, absent_disc[b], absent_polygon[b])

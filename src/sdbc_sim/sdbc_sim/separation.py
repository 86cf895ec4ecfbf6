"""The overlap projection: bodies that a step left overlapping are moved apart.

Chipmunk integrates positions before it looks for contacts, so a body that meets
a wall or another body during a step ends the step overlapping it (see
:mod:`sdbc_sim.physics`). :func:`project_apart` moves such bodies apart in the
trials where chipmunk found a deep contact.

It runs at almost every step (robots that press on a wall overlap it again each
step), on a few bodies of a few trials at a time: whole-array numpy paid a call's
overhead for every one of its ~40 operations per pass, which made the projection
the largest part of a gate-escape step. So it is a compiled loop
(:mod:`sdbc_sim.compiled`): every operation is the IEEE one numpy would do, in the
same order, so the results are those of the array formulation to the bit, which
``tests/sdbc_sim/test_separation.py`` checks against it.
"""

from __future__ import annotations

import numpy as np

from sdbc_sim.compiled import compiled
from sdbc_sim.sensors import segment_offset


def project_apart(
    pos: np.ndarray,
    enabled: np.ndarray,
    radii: np.ndarray,
    walls: np.ndarray,
    tolerance: float,
    iterations: int,
    anchored: np.ndarray | None = None,
) -> np.ndarray:
    """Moves overlapping bodies apart until no overlap exceeds ``tolerance``.

    Jacobi passes: in each, two bodies i, j overlapping by o = r_i + r_j - d_ij >
    tolerance move apart along their centre line by (o - tolerance / 2) / 2 each
    (by all of it the one that is not anchored, if the other is), and a body
    overlapping a wall by o = r_i - dist > tolerance moves out along the wall's
    normal by o - tolerance / 2; the moves of a pass are summed in index
    order (so a trial's result never depends on its batch-mates) and applied
    together. A trial's passes stop when nothing of it overlaps or after
    ``iterations``.

    Args:
        pos: (S, R, 2) centres of the bodies of S trials.
        enabled: (S, R) bool; switched-off bodies neither move nor push.
        radii: (R,) radii.
        walls: (P, 2, 2) wall segments.
        tolerance: Largest overlap left in place; half of it stays after a move.
        iterations: Most passes.
        anchored: (S, R) bool, anchored bodies, or None for none.

    Returns:
        (S, R, 2) new centres.
    """
    if anchored is None:
        anchored = np.zeros(enabled.shape, dtype=np.bool_)
    return _project_apart(
        np.ascontiguousarray(pos, dtype=np.float64),
        np.ascontiguousarray(enabled, dtype=np.bool_),
        np.ascontiguousarray(radii, dtype=np.float64),
        np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 2, 2),
        float(tolerance),
        int(iterations),
        np.ascontiguousarray(anchored, dtype=np.bool_),
    )


@compiled(
    "float64[:, :, ::1](float64[:, :, ::1], boolean[:, ::1], float64[::1],"
    " float64[:, :, ::1], float64, int64, boolean[:, ::1])",
    calls=(segment_offset,),
)
def _project_apart(
    pos: np.ndarray,
    enabled: np.ndarray,
    radii: np.ndarray,
    walls: np.ndarray,
    tolerance: float,
    iterations: int,
    anchored: np.ndarray,
) -> np.ndarray:  # pragma: no cover - compiled; tested through project_apart
    out = pos.copy()
    n_trials, n = enabled.shape
    target = 0.5 * tolerance
    shift = np.empty((n, 2))
    for b in range(n_trials):
        p = out[b]
        for _ in range(iterations):
            moving = False
            for i in range(n):
                # Pairs: sum over j, in index order, of k_ij (p_j - p_i); zero
                # terms included, since numpy's sum adds them too.
                sx = 0.0
                sy = 0.0
                for j in range(n):
                    dx = p[j, 0] - p[i, 0]
                    dy = p[j, 1] - p[i, 1]
                    d = np.sqrt(dx * dx + dy * dy)
                    over = (radii[i] + radii[j]) - d
                    k = 0.0
                    if (
                        i != j
                        and enabled[b, i]
                        and enabled[b, j]
                        and over > tolerance
                        and d > 0.0
                    ):
                        # Share of the overlap body i takes: 1/2, 0 (i anchored,
                        # j not) or 1 (j anchored, i not).
                        a_j = 1.0 if anchored[b, j] else 0.0
                        a_i = 1.0 if anchored[b, i] else 0.0
                        share = 0.5 + 0.5 * (a_j - a_i)
                        k = (over - target) * share / d
                        moving = True
                    if j == 0:
                        sx = k * dx
                        sy = k * dy
                    else:
                        sx += k * dx
                        sy += k * dy
                sx = -sx
                sy = -sy
                # Walls: out along the offset from the nearest point of each.
                if walls.shape[0]:
                    wsx = 0.0
                    wsy = 0.0
                    for q in range(walls.shape[0]):
                        ox, oy = segment_offset(p[i, 0], p[i, 1], walls, q)
                        dist = np.sqrt(ox * ox + oy * oy)
                        over_w = radii[i] - dist
                        kw = 0.0
                        if enabled[b, i] and over_w > tolerance and dist > 0.0:
                            kw = (over_w - target) / dist
                            moving = True
                        if q == 0:
                            wsx = kw * ox
                            wsy = kw * oy
                        else:
                            wsx += kw * ox
                            wsy += kw * oy
                    sx += wsx
                    sy += wsy
                shift[i, 0] = sx
                shift[i, 1] = sy
            if not moving:
                break
            for i in range(n):
                p[i, 0] += shift[i, 0]
                p[i, 1] += shift[i, 1]
    return out

"""The C library's ``hypot``, computed inside a compiled loop to the same bits.

Every step takes each robot's speed |v| (the task state's linear speed,
resource sharing's docking rule). The C library's ``hypot``, which numba calls
and numpy's ``np.hypot`` calls too, cost about 16 ns a call on this project's
machines: a call the loop cannot inline, with a branch on its arguments that
random velocities take either way. :func:`hypot` does the same operations
inline and without that branch, in about a third of the time.

The algorithm is Borges' corrected one (C. F. Borges, "An improved algorithm for
hypot(a, b)", arXiv:1904.09481, 2019): h = sqrt(a^2 + b^2) with a <= b, then
one correction step from the rounding error of a^2 + b^2, computed in one of two
ways depending on whether h <= 2 b. The GNU C library (glibc) computes hypot so
since version 2.35, without fused multiply-adds on x86-64; this module does the
same IEEE operations in the same order, so its results are glibc's there to the
bit (``tests/sdbc_sim/test_libm.py`` compares them over millions of pairs). It
keeps glibc's shortcut (b <= a 2^-54 gives a + b) and leaves the rest of
glibc's cases to the C library itself: an infinite or NaN argument, one above
2^511, or a smaller one below 2^-459 but not zero, which glibc rescales.
"""

from __future__ import annotations

import math

_LARGE = 2.0**511
"""Above this, glibc scales the arguments down before squaring them."""
_TINY = 2.0**-459
"""Below this (and not zero), glibc scales the smaller argument up."""
_EPS = 2.0**-54
"""The smaller argument at most the larger's times this: the sum is the result."""


def hypot(x: float, y: float) -> float:  # pragma: no cover - compiled into loops
    """sqrt(x^2 + y^2), the bits of glibc's ``hypot`` (module docstring); a
    helper of compiled loops (``calls=(..., hypot)``), inlined into them."""
    ax0 = abs(x)
    ay0 = abs(y)
    ax = max(ax0, ay0)
    ay = min(ax0, ay0)
    h = math.sqrt(ax * ax + ay * ay)
    # Both corrections, then a select: a branch on h <= 2 ay is taken at random.
    d1 = h - ay
    t1 = ax * (2.0 * d1 - ax)
    t2 = (d1 - 2.0 * (ax - ay)) * d1
    d2 = h - ax
    u1 = 2.0 * d2 * (ax - 2.0 * ay)
    u2 = (4.0 * d2 - ay) * ay + d2 * d2
    error = (t1 + t2) if h <= 2.0 * ay else (u1 + u2)
    result = h - error / (2.0 * h)
    if ay <= ax * _EPS:
        result = ax + ay
    if not (ax0 <= _LARGE and ay0 <= _LARGE and (ay >= _TINY or ay == 0.0)):
        result = math.hypot(x, y)
    return result

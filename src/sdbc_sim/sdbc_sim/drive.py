"""The drive: from a robot's commanded speed and turn to its new heading and
commanded velocity, the same for every physics model.

A body turns at once, theta' = theta + turn (headings are kinematic), and is
commanded the velocity v* = speed (cos theta', sin theta'). Bodies switched off
and trials that have ended are brought to rest: their turn and speed count as
zero. :meth:`sdbc_sim.engine.BatchSimulation._drive` writes the drive rows the
rigid model takes (:func:`drive_rows`); the kinematic model moves each body as
soon as its drive is known, in the same pass (``sdbc_sim.kinematic``), so both
share :func:`drive_body`.

Unlike most loops (:mod:`sdbc_sim.compiled` names the exceptions), these take
the cosine and sine from the C library numba calls rather than from numpy: as
whole arrays they were most of the drive's cost, and on the platforms we build
for both call the same C library (glibc; ``tests/sdbc_sim/test_engine.py``
compares them to the bit). Every path to a heading's cosine after the first step
goes through :func:`drive_body`, so a trial alone, in a batch and live still
agree whatever that library.
"""

from __future__ import annotations

import math

import numpy as np

from sdbc_sim.compiled import compiled


def drive_body(
    angle: np.ndarray,
    speed: np.ndarray,
    turn: np.ndarray,
    enabled: np.ndarray,
    running: np.ndarray,
    dt: float,
    turn_rate: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    t: int,
    i: int,
) -> tuple[float, float, float]:  # pragma: no cover - compiled into its loops
    """Body ``i`` of trial ``t`` (arrays (B, R)): with m = 1 if it is enabled in
    a running trial and 0 otherwise, writes its turn rate t m / dt and the
    cosine and sine of its heading h = angle + t m, and returns (h, v cos h,
    v sin h) with v = speed m: the operations of the array form
    (``tests/sdbc_sim/test_engine.py``) in its order."""
    m = 1.0 if enabled[t, i] and running[t] else 0.0
    tm = turn[t, i] * m
    turn_rate[t, i] = tm / dt
    h = angle[t, i] + tm
    c = math.cos(h)
    s = math.sin(h)
    cos_h[t, i] = c
    sin_h[t, i] = s
    v = speed[t, i] * m
    return h, v * c, v * s


@compiled(
    "void(float64[:, :], float64[:, :], float64[:, :], boolean[:, :], boolean[::1], "
    "float64, float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], "
    "intp, intp, intp, intp)",
    calls=(drive_body,),
)
def drive_rows(
    angle: np.ndarray,
    speed: np.ndarray,
    turn: np.ndarray,
    enabled: np.ndarray,
    running: np.ndarray,
    dt: float,
    turn_rate: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    drive: np.ndarray,
    col_angle: int,
    col_angular_velocity: int,
    col_x: int,
    col_y: int,
) -> None:  # pragma: no cover - compiled; tested against the numpy form
    """:func:`drive_body` for bodies (B, R), each writing its drive row (h, 0,
    vx, vy) in the columns named."""
    n = angle.shape[1]
    for t in range(angle.shape[0]):
        for i in range(n):
            h, vx, vy = drive_body(
                angle, speed, turn, enabled, running, dt, turn_rate, cos_h, sin_h, t, i
            )
            row = t * n + i
            drive[row, col_angle] = h
            drive[row, col_angular_velocity] = 0.0
            drive[row, col_x] = vx
            drive[row, col_y] = vy

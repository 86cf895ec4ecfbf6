"""Loops compiled by numba, on first use.

The engine compiles a few small loops whose whole-array numpy form paid a call's
overhead on many tiny arrays at every step (the overlap projection, the wall
rays). Importing numba costs about 0.5 s of CPU and loading compiled code from
its cache 0.7 s more, so the compilation waits for the first call: a process
that never steps the physics (a controller node, a command-line tool) never
pays it.

Every loop is compiled without fast-math: its additions, multiplications,
divisions, square roots and comparisons are the IEEE operations numpy does, and
each loop does them in the order of the array formulation it replaces, so its
results are the same to the bit (each module's tests keep that formulation as
the oracle). Transcendental functions stay in numpy, whose implementations may
differ from the ones numba calls in the last bit.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])


def compiled(fn: F) -> F:
    """``fn`` compiled by numba (nopython, cached on disk, numpy's error model)
    the first time it is called."""
    kernel: Callable[..., Any] | None = None

    @functools.wraps(fn)
    def call(*args: Any) -> Any:
        nonlocal kernel
        if kernel is None:
            import numba

            kernel = numba.njit(cache=True, error_model="numpy")(fn)
        return kernel(*args)

    return call  # type: ignore[return-value]

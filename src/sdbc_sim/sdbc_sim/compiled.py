"""Loops compiled by numba, loaded when the physics is first set up.

The engine compiles the loops whose whole-array numpy form paid a call's
overhead on many small arrays at every step (the overlap projection and its
bookkeeping, the wall rays, the robot arcs, the network's sums, some tasks'
sensors and rules, the SDBC's features), and the kinematic model's step, which
has no array formulation (one robot's move depends on the moves before it).
Importing numba costs about 0.5 s of CPU and loading compiled code from its cache
0.7 s more, so nothing is loaded at import: :func:`load` loads every loop when
the first batch of trials is set up (``TrialSpaces``, ``KinematicTrials``), and a
loop called before that loads itself. A process that never steps the physics (a
controller node, a command-line tool) never pays it, and one that does pays it at
a known point rather than at whichever step first needs a loop.

Every loop has one signature (its callers pass arrays of the types it names,
contiguous where it says so; the robots' positions, strided views of the engine's
state rows, go in as they are rather than copied at every step) and is compiled
without fast-math: its additions, multiplications,
divisions, square roots and comparisons are the IEEE operations numpy does, and
each loop does them in the order of the array formulation it replaces, so its
results are the same to the bit (each module's tests keep that formulation as
the oracle). Functions of the C maths library stay in numpy, whose
implementations may differ from the ones numba calls in the last bit (numpy's
``exp`` and ``arctan2`` are its own vectorised code on a CPU with AVX-512), with
exceptions where they were most of a step's cost as whole arrays: the drive
(``sdbc_sim.engine._drive_rows``) takes each new heading's cosine and sine
from the C library numba calls: the same glibc functions numpy's float64 ``cos``
and ``sin`` call here, which its tests compare to the bit. The task state
(``sdbc_sim.task._kinematics``) and resource sharing's energy rules take each
speed's ``hypot`` by :func:`sdbc_sim.libm.hypot`, glibc's operations inline,
compared to the bit with numpy's ``np.hypot``, which calls glibc's.
Predator-prey's turns wrap angles with ``np.mod``, which numba and numpy both
compute as an exact ``fmod`` with the same sign correction. A trial's start,
drawn in bulk (resource sharing's and gate escape's), takes its cosines, sines
and ``hypot`` from the C library numba calls, as the Python path it replaces
takes them through the ``math`` module (its tests compare the starts to the
bit; a distance that ``hypot`` and ``math.dist`` might round apart goes back
to that path).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

F = TypeVar("F", bound=Callable[..., Any])


_HELPER_OPTIONS: dict[str, Any] = {"error_model": "numpy", "inline": "always"}
"""How a loop's helpers are compiled. Inlined into the loop in numba's own
representation: LLVM left many calls in place, each passing its arrays' whole
descriptors, which cost gate escape's step several percent."""


class _Loop:
    """A Python function and the numba kernel compiled from it once loaded."""

    def __init__(
        self,
        fn: Callable[..., Any],
        signature: str,
        calls: tuple[Callable[..., Any], ...],
    ) -> None:
        functools.update_wrapper(self, fn)
        self.fn = fn
        self.signature = signature
        self.calls = calls
        self.kernel: Callable[..., Any] | None = None

    def load(self) -> Callable[..., Any]:
        if self.kernel is None:
            import numba

            fn = self.fn
            if self.calls:
                # The loop and its helpers see the compiled helpers under their
                # own names, so a helper may call another; the modules keep the
                # plain functions. numba reads a function's globals when it
                # compiles it, at the first call, after every scope is filled.
                # Only the loop is cached on disk: it holds its helpers'
                # compiled code, and _forget_if_changed keeps it current.
                scopes: list[dict[str, Any]] = []
                kernels = {
                    helper.__name__: numba.njit(**_HELPER_OPTIONS)(
                        _rebound(helper, scopes)
                    )
                    for helper in self.calls
                }
                fn = _rebound(fn, scopes)
                for scope in scopes:
                    scope.update(kernels)
                _forget_if_changed(fn, self.calls)
            self.kernel = numba.njit(self.signature, cache=True, error_model="numpy")(
                fn
            )
        return self.kernel

    def __call__(self, *args: Any) -> Any:
        return (self.kernel or self.load())(*args)


def _forget_if_changed(
    fn: Callable[..., Any], helpers: tuple[Callable[..., Any], ...]
) -> None:
    """Empties numba's on-disk cache of the loop ``fn`` when its helpers' code,
    or the options they are compiled with, changed since it was cached. numba
    keeps a loop's cache while the loop's own file is unchanged, and a cached
    loop holds its helpers' compiled code: a helper edited in another module
    would otherwise go on running as it was."""
    from numba.core.caching import FunctionCache

    digest = hashlib.sha256(repr(sorted(_HELPER_OPTIONS.items())).encode())
    for helper in helpers:
        code = helper.__code__
        digest.update(f"{helper.__module__}.{helper.__qualname__}".encode())
        digest.update(code.co_code)
        digest.update(repr((code.co_consts, code.co_names)).encode())
    cache = FunctionCache(fn)
    stamp = Path(cache.cache_path) / f"{fn.__module__}.{fn.__qualname__}.helpers"
    fingerprint = digest.hexdigest()
    try:
        if stamp.read_text() == fingerprint:
            return
    except OSError:
        pass
    cache.flush()
    # An unwritable cache: numba compiles anew in every process anyway.
    with contextlib.suppress(OSError):
        stamp.write_text(fingerprint)


def _rebound(
    fn: Callable[..., Any], scopes: list[dict[str, Any]]
) -> Callable[..., Any]:
    """``fn`` over a copy of its module's globals, which is added to ``scopes``."""
    scope = dict(fn.__globals__)
    scopes.append(scope)
    copy = types.FunctionType(
        fn.__code__, scope, fn.__name__, fn.__defaults__, fn.__closure__
    )
    copy.__qualname__ = fn.__qualname__
    return copy


_LOOPS: list[_Loop] = []


def compiled(
    signature: str, *, calls: tuple[Callable[..., Any], ...] = ()
) -> Callable[[F], F]:
    """Marks ``fn`` as a loop compiled by numba with ``signature`` (nopython,
    cached on disk, numpy's error model), loaded by :func:`load`. ``calls`` are
    plain functions (of any module) that the loop, or another of them, calls by
    name: they are compiled with it, for the types it passes, so that loops can
    share one."""

    def mark(fn: F) -> F:
        loop = _Loop(fn, signature, calls)
        _LOOPS.append(loop)
        return cast(F, loop)

    return mark


_loaded = False


def load() -> None:
    """Loads (compiling if numba's cache lacks them) every loop marked so far."""
    global _loaded
    for loop in _LOOPS:
        loop.load()
    _loaded = True


def loaded() -> bool:
    """:func:`load` has run in this process: code with a loop and its numpy
    formulation (the network) runs the loop from then on, and the numpy form in a
    process that never loads numba (a controller node)."""
    return _loaded

"""sdbc_sim.libm.hypot inside a compiled loop: the C library's hypot to the bit.

numpy's ``np.hypot`` calls the C library's ``hypot``, so it is the oracle here;
on a C library that computes hypot otherwise (glibc before 2.35, or with fused
multiply-adds), these tests fail and say so.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from sdbc_sim import libm

_kernel = numba.njit(inline="always", error_model="numpy")(libm.hypot)


@numba.njit(error_model="numpy")
def _hypots(x: np.ndarray, y: np.ndarray) -> np.ndarray:  # pragma: no cover
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = _kernel(x[i], y[i])
    return out


def assert_bits_equal(x: np.ndarray, y: np.ndarray) -> None:
    got = _hypots(x, y)
    with np.errstate(all="ignore"):
        want = np.hypot(x, y)
    same = (got.view(np.int64) == want.view(np.int64)) | (
        np.isnan(got) & np.isnan(want)
    )
    if not same.all():
        i = np.flatnonzero(~same)[:5]
        pytest.fail(
            f"{(~same).sum()} of {x.size} pairs differ from the C library's hypot, "
            f"e.g. hypot({x[i].tolist()}, {y[i].tolist()}) = {got[i].tolist()} "
            f"here, {want[i].tolist()} by np.hypot"
        )


N = 1_000_000


def velocities(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return rng.uniform(-3.0, 3.0, N), rng.uniform(-3.0, 3.0, N)


def any_magnitude(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    def draw() -> np.ndarray:
        return rng.standard_normal(N) * 10.0 ** rng.integers(-320, 308, N)

    return draw(), draw()


def nearly_equal(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """h <= 2 b, the first of the two corrections, every time."""
    x = rng.uniform(-1.0, 1.0, N)
    return x, x * (1.0 + rng.uniform(-1e-3, 1e-3, N))


def one_much_smaller(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Ratios down to 1e-20, past the shortcut b <= a 2^-54."""
    x = rng.standard_normal(N)
    return x, x * 10.0 ** rng.uniform(-20.0, 0.0, N)


def any_bits(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Every double alike: NaNs, infinities and subnormals included."""
    x = rng.integers(0, 2**64, N, dtype=np.uint64).view(np.float64)
    y = rng.integers(0, 2**64, N, dtype=np.uint64).view(np.float64)
    return x, y


@pytest.mark.parametrize(
    "pairs", [velocities, any_magnitude, nearly_equal, one_much_smaller, any_bits]
)
def test_random_pairs_have_the_c_librarys_bits(pairs) -> None:
    x, y = pairs(np.random.default_rng(20261207))
    assert_bits_equal(x, y)


def test_the_edges_of_its_cases_have_the_c_librarys_bits() -> None:
    """Where glibc switches between its cases: zero, the shortcut's ratio
    2^-54, the thresholds 2^511 and 2^-459 it rescales beyond, the largest and
    smallest doubles, infinities and NaN."""
    edges = [0.0, -0.0, 1.0, 3.0, 4.0, 5e-324, 2.2250738585072014e-308, 1.8e308]
    for e in (2.0**-54, 2.0**511, 2.0**-459):
        edges += [e, np.nextafter(e, 0.0), np.nextafter(e, np.inf)]
    edges += [np.inf, -np.inf, np.nan]
    values = np.array(edges + [-v for v in edges])
    x, y = np.meshgrid(values, values)
    scaled = np.concatenate([x.ravel(), x.ravel() * 3.0, x.ravel()])
    others = np.concatenate([y.ravel(), y.ravel(), y.ravel() * 2.0**-54])
    assert_bits_equal(scaled, others)

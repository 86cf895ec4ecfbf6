"""Bounded Gaussian mutation: which genes mutate, bounds, redraws, fallback."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import truncnorm
from sdbc_evolution.ga.mutation import gaussian_mutation


class ScriptedGenerator:
    """Stands in for np.random.Generator with hand-picked draws."""

    def __init__(
        self, uniforms: list[float], normals: list[float], fallbacks: list[float] = ()
    ) -> None:
        self.uniforms = list(uniforms)
        self.normals = list(normals)
        self.fallbacks = list(fallbacks)

    def random(self, shape: tuple[int, ...]) -> np.ndarray:
        n = int(np.prod(shape))
        out, self.uniforms = self.uniforms[:n], self.uniforms[n:]
        return np.array(out).reshape(shape)

    def standard_normal(self, n: int) -> np.ndarray:
        out, self.normals = self.normals[:n], self.normals[n:]
        return np.array(out)

    def uniform(self, low: float, high: float, n: int) -> np.ndarray:
        out, self.fallbacks = self.fallbacks[:n], self.fallbacks[n:]
        return np.array(out)


def test_hand_worked_mutation_with_one_redraw() -> None:
    genome = np.array([[0.9, 0.0, -0.5]])
    # Genes 0 and 2 mutate (uniform < 0.05); gene 0 first lands at 0.9 + 0.5 * 0.4 =
    # 1.1, out of bounds, and is redrawn to 0.9 + 0.5 * -0.6 = 0.6; gene 2 lands at
    # -0.5 + 0.5 * -0.2 = -0.6.
    rng = ScriptedGenerator(uniforms=[0.01, 0.5, 0.02], normals=[0.4, -0.2, -0.6])
    child = gaussian_mutation(
        genome, rng, sigma=0.5, probability=0.05, low=-1.0, high=1.0, max_redraws=100
    )
    assert child[0].tolist() == pytest.approx([0.6, 0.0, -0.6])
    assert rng.normals == [] and rng.uniforms == []
    assert genome.tolist() == [[0.9, 0.0, -0.5]]


def test_exhausted_redraws_fall_back_to_a_uniform_value() -> None:
    rng = ScriptedGenerator(uniforms=[0.0], normals=[5.0, 5.0], fallbacks=[0.25])
    child = gaussian_mutation(
        np.array([[0.0]]),
        rng,
        sigma=1.0,
        probability=0.5,
        low=-1.0,
        high=1.0,
        max_redraws=2,
    )
    assert child.tolist() == [[0.25]]


def test_children_stay_in_bounds_and_are_not_clipped() -> None:
    rng = np.random.default_rng(3)
    parents = rng.uniform(-1, 1, (200, 100))
    children = gaussian_mutation(
        parents, rng, sigma=2.0, probability=1.0, low=-1.0, high=1.0, max_redraws=100
    )
    assert (children >= -1).all() and (children <= 1).all()
    assert not np.isin(children, [-1.0, 1.0]).any()
    assert (children != parents).all()


def test_probability_zero_changes_nothing_and_rate_matches() -> None:
    rng = np.random.default_rng(4)
    parents = rng.uniform(-1, 1, (200, 108))
    same = gaussian_mutation(parents, rng, 0.5, 0.0, -1.0, 1.0, 100)
    assert (same == parents).all()
    children = gaussian_mutation(parents, rng, 0.5, 0.05, -1.0, 1.0, 100)
    changed = (children != parents).mean()
    # 21600 genes, p = 0.05: SD of the rate 0.0015.
    assert abs(changed - 0.05) < 0.0075


def test_redrawn_values_follow_the_truncated_normal() -> None:
    rng = np.random.default_rng(5)
    parents = np.full((40_000, 1), 0.8)
    children = gaussian_mutation(parents, rng, 0.5, 1.0, -1.0, 1.0, 100)[:, 0]
    expected = truncnorm((-1 - 0.8) / 0.5, (1 - 0.8) / 0.5, loc=0.8, scale=0.5)
    assert children.mean() == pytest.approx(expected.mean(), abs=0.01)
    assert children.std() == pytest.approx(expected.std(), abs=0.01)


def test_same_generator_state_same_children() -> None:
    parents = np.random.default_rng(0).uniform(-1, 1, (10, 20))
    a = gaussian_mutation(parents, np.random.default_rng(9), 0.5, 0.3, -1.0, 1.0, 100)
    b = gaussian_mutation(parents, np.random.default_rng(9), 0.5, 0.3, -1.0, 1.0, 100)
    assert (a == b).all()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"sigma": 0.0}, "sigma"),
        ({"sigma": float("nan")}, "sigma"),
        ({"probability": 1.5}, "probability"),
        ({"low": 1.0}, "bounds"),
        ({"max_redraws": 0}, "max_redraws"),
    ],
)
def test_bad_parameters_are_rejected(kwargs: dict, message: str) -> None:
    args = {
        "sigma": 0.5,
        "probability": 0.05,
        "low": -1.0,
        "high": 1.0,
        "max_redraws": 100,
    } | kwargs
    with pytest.raises(ValueError, match=message):
        gaussian_mutation(np.zeros((2, 3)), np.random.default_rng(0), **args)

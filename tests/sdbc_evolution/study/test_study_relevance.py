"""The chance level of the relevance table: the MI estimate's own bias."""

from __future__ import annotations

import numpy as np
from sdbc_evolution.sdbc.weighting import WeightingSettings, mutual_information
from sdbc_evolution.study.relevance import chance_information


def test_chance_is_the_estimate_for_features_unrelated_to_fitness() -> None:
    rng = np.random.default_rng(3)
    settings = WeightingSettings()
    fitness = rng.uniform(size=50)
    related = fitness + rng.normal(scale=0.01, size=50)
    unrelated = rng.uniform(size=50)
    sdbc = np.column_stack([related, unrelated])
    true = mutual_information(sdbc, fitness, settings, 0)
    chance = chance_information(sdbc, fitness, settings, seed=0)
    # Both columns get about the same chance level, well above 0 at n = 50
    # (the plug-in bias), and the related one's true MI stands far above it.
    assert np.all(chance > 0.5) and abs(chance[0] - chance[1]) < 0.5
    assert true[0] > chance[0] + 1.0
    assert abs(true[1] - chance[1]) < 0.5
    again = chance_information(sdbc, fitness, settings, seed=0)
    assert np.array_equal(chance, again)
    assert not np.array_equal(
        chance, chance_information(sdbc, fitness, settings, seed=1)
    )

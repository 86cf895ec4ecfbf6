"""The SDBC of the paper's three tasks as the engine defines them: lengths 21, 21 and
27, the documented names, and the extractor observing real batches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names
from sdbc_evolution.sdbc.document import (
    characterisations_markdown,
    registry_descriptions,
)
from sdbc_sim.engine import run_batch
from sdbc_sim.tasks import available_tasks, make_task
from sdbc_states import GATE_ESCAPE, PREDATOR_PREY, RESOURCE_SHARING

DOCS = Path(__file__).parents[3] / "docs" / "characterisations.md"

PAPER_TASKS = {
    "gate_escape": (21, GATE_ESCAPE),
    "resource_sharing": (21, RESOURCE_SHARING),
    "predator_prey": (27, PREDATOR_PREY),
}


@pytest.mark.parametrize("name", sorted(PAPER_TASKS))
def test_characterisation_length_and_description(name: str) -> None:
    length, expected = PAPER_TASKS[name]
    description = make_task(name).description
    # The task's groups are those of docs/reference-setup.md, as written out by
    # hand in sdbc_states.
    assert description == expected
    assert len(dimension_names(description)) == length


def test_the_documented_names_are_current() -> None:
    assert set(PAPER_TASKS) <= set(available_tasks())
    assert DOCS.read_text() == characterisations_markdown(registry_descriptions()), (
        "docs/characterisations.md is stale: regenerate it with "
        "`python -m sdbc_evolution.sdbc.document docs/characterisations.md`"
    )


@pytest.mark.parametrize("name", sorted(PAPER_TASKS))
def test_extractor_on_engine_batches(name: str) -> None:
    task = make_task(name, max_steps=60)
    rng = np.random.default_rng(12)
    genomes = rng.uniform(-1.0, 1.0, (3, task.genome_length))
    seeds = rng.integers(0, 2**31, (3, 2))
    extractor = SdbcExtractor()
    result = run_batch(task, genomes, seeds, [extractor])
    vectors = extractor.characterisations()
    names = extractor.dimension_names
    assert vectors.shape == (6, PAPER_TASKS[name][0])
    assert np.isfinite(vectors).all()
    np.testing.assert_array_equal(vectors[:, -1], result.length.reshape(-1))
    # Group sizes are fractions of their limits.
    sizes = [k for k, n in enumerate(names) if "group size" in n]
    assert ((vectors[:, sizes] >= 0) & (vectors[:, sizes] <= 1)).all()
    # Each trial's vector does not depend on its batch-mates.
    alone = SdbcExtractor()
    run_batch(task, genomes[2:], seeds[2:, :1], [alone])
    np.testing.assert_allclose(
        alone.characterisations()[0], vectors[4], rtol=0, atol=1e-9
    )

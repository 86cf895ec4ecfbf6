"""Properties of the SDBC: invariance to entity order and to translation, and the
streaming extractor agreeing with aggregating a stored trial in one go."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from sdbc_evolution.sdbc.aggregation import aggregate_trial
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_evolution.sdbc.features import FeatureKind, StepFeatures
from sdbc_evolution.sdbc.options import SdbcOptions
from sdbc_sim.task_state import GroupState, TaskState
from sdbc_states import GATE_ESCAPE, PREDATOR_PREY, RESOURCE_SHARING, random_state

DESCRIPTIONS = st.sampled_from([GATE_ESCAPE, RESOURCE_SHARING, PREDATOR_PREY])
SEEDS = st.integers(0, 2**32 - 1)


def permute_slots(state: TaskState, rng: np.random.Generator) -> TaskState:
    """The same trials with the entity slots of every group shuffled, per trial."""
    groups = []
    for g in state.groups:
        b, s = g.present.shape
        order = rng.permuted(np.broadcast_to(np.arange(s), (b, s)), axis=1)

        def shuffle(
            array: np.ndarray | None, order: np.ndarray = order
        ) -> np.ndarray | None:
            if array is None:
                return None
            index = order.reshape(order.shape + (1,) * (array.ndim - 2))
            return np.take_along_axis(array, index, axis=1)

        groups.append(
            GroupState(
                shuffle(g.present),
                shuffle(g.attributes),
                shuffle(g.centres),
                shuffle(g.radii),
                shuffle(g.segments),
            )
        )
    return TaskState(state.step, state.active, tuple(groups))


def translate(state: TaskState, offset: np.ndarray) -> TaskState:
    """Every entity moved by ``offset`` (2,); attributes untouched."""
    groups = tuple(
        GroupState(
            g.present,
            g.attributes,
            None if g.centres is None else g.centres + offset,
            g.radii,
            None if g.segments is None else g.segments + offset,
        )
        for g in state.groups
    )
    return TaskState(state.step, state.active, groups)


@settings(max_examples=40, deadline=None)
@given(DESCRIPTIONS, SEEDS, st.integers(1, 12), st.floats(0.0, 1.0))
def test_permuting_entities_changes_no_feature(description, seed, n_trials, p_present):
    rng = np.random.default_rng(seed)
    state = random_state(description, n_trials, rng, p_present=p_present)
    features = StepFeatures(description)
    np.testing.assert_allclose(
        features.values(permute_slots(state, rng)),
        features.values(state),
        rtol=1e-12,
        atol=1e-9,
    )


@settings(max_examples=40, deadline=None)
@given(
    DESCRIPTIONS,
    SEEDS,
    st.integers(1, 12),
    st.tuples(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4)),
)
def test_translating_everything_changes_no_distance(
    description, seed, n_trials, offset
):
    rng = np.random.default_rng(seed)
    state = random_state(description, n_trials, rng)
    features = StepFeatures(description)
    spatial = [
        f
        for f, feature in enumerate(features.features)
        if feature.kind in (FeatureKind.DISPERSION, FeatureKind.GROUP_DISTANCE)
    ]
    assert spatial
    moved = features.values(translate(state, np.array(offset)))[:, spatial]
    np.testing.assert_allclose(
        moved, features.values(state)[:, spatial], rtol=0, atol=1e-9
    )


@settings(max_examples=30, deadline=None)
@given(DESCRIPTIONS, SEEDS, st.integers(1, 8), st.integers(1, 15))
def test_streaming_a_batch_equals_aggregating_each_trial(
    description, seed, n_trials, n_steps
):
    rng = np.random.default_rng(seed)
    lengths = rng.integers(1, n_steps + 1, n_trials)
    extractor = SdbcExtractor()
    extractor.start(description, n_trials)
    features = StepFeatures(description)
    samples = []
    state = None
    for step in range(1, n_steps + 1):
        # Static entities never move: their geometry stays that of step 1.
        state = random_state(description, n_trials, rng, step=step, previous=state)
        state.active = step <= lengths
        extractor.observe(state)
        samples.append(features.values(state))
    samples = np.array(samples)  # (T, B, F)
    result = extractor.characterisations()
    for b in range(n_trials):
        expected = aggregate_trial(samples[: lengths[b], b])
        np.testing.assert_allclose(result[b], expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(extractor.lengths, lengths)


@settings(max_examples=30, deadline=None)
@given(DESCRIPTIONS, SEEDS, st.integers(1, 40), st.integers(1, 12))
def test_computing_only_the_active_trials_changes_nothing(
    description, seed, n_trials, n_steps
):
    rng = np.random.default_rng(seed)
    lengths = rng.integers(1, n_steps + 1, n_trials)
    # Never compact, always compact (every step gathers the active trials), and
    # half way (compact once at most half of them are left).
    extractors = [SdbcExtractor(compact_below=c) for c in (0.0, 1.0, 0.5)]
    for extractor in extractors:
        extractor.start(description, n_trials)
    state = None
    for step in range(1, n_steps + 1):
        state = random_state(description, n_trials, rng, step=step, previous=state)
        state.active = step <= lengths
        for extractor in extractors:
            extractor.observe(state)
    reference = extractors[0].characterisations()
    for extractor in extractors[1:]:
        np.testing.assert_array_equal(extractor.characterisations(), reference)
        np.testing.assert_array_equal(extractor.lengths, lengths)


@settings(max_examples=20, deadline=None)
@given(
    DESCRIPTIONS,
    SEEDS,
    st.integers(1, 40),
    st.integers(1, 12),
    st.sampled_from(["regression", "final", {"frames": 3}]),
)
def test_computing_only_the_active_trials_changes_nothing_with_options(
    description, seed, n_trials, n_steps, aggregation
):
    rng = np.random.default_rng(seed)
    lengths = rng.integers(1, n_steps + 1, n_trials)
    options = SdbcOptions(aggregation=aggregation, state_deviation=True)
    extractors = [SdbcExtractor(options, compact_below=c) for c in (0.0, 1.0, 0.5)]
    for extractor in extractors:
        extractor.start(description, n_trials)
    state = None
    for step in range(1, n_steps + 1):
        state = random_state(description, n_trials, rng, step=step, previous=state)
        state.active = step <= lengths
        for extractor in extractors:
            extractor.observe(state)
    reference = extractors[0].characterisations()
    assert reference.shape[1] == len(extractors[0].dimension_names)
    for extractor in extractors[1:]:
        np.testing.assert_array_equal(extractor.characterisations(), reference)
        np.testing.assert_array_equal(extractor.lengths, lengths)

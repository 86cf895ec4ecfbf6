"""Systematically derived behaviour characterisations (SDBC, section 3 of the paper).

From a task description alone (:mod:`sdbc_sim.task_state`), the SDBC turns the task
state of every step into behaviour features (:mod:`.features`, eqs. 2 to 5, with
the distance function f_D of :mod:`.distance`; :mod:`.fused` computes the same
totals in compiled loops), aggregates them into a raw
characterisation per trial (:mod:`.aggregation`: means, finals, length), and, per
generation, standardises them (:mod:`.standardise`) and weights them by mutual
information with fitness (:mod:`.weighting`, NS-SD+).

One extractor, :class:`SdbcExtractor`, with the paper's configuration by default
and any :class:`SdbcOptions` (aggregation modes, added feature kinds, ignored
groups). Two ways in, one result: :class:`SdbcExtractor` observes the engine's batched
arrays; :class:`.messages.MessageSdbcExtractor` reads ``sdbc_msgs/TaskState``
streams. Typical use::

    extractor = SdbcExtractor()
    result = run_batch(task, genomes, seeds, [extractor])
    raw = mean_over_trials(extractor.characterisations(), seeds.shape[1])
    population_z, archive_z = standardise(raw, archive_raw)
    weights = mutual_information_weights(raw, result.controller_fitness)
"""

from sdbc_evolution.sdbc.aggregation import (
    TrialAggregator,
    aggregate_trial,
    characterisation_length,
    mean_over_trials,
)
from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names
from sdbc_evolution.sdbc.features import (
    BehaviourFeature,
    FeatureKind,
    behaviour_features,
)
from sdbc_evolution.sdbc.options import SdbcOptions
from sdbc_evolution.sdbc.standardise import (
    Standardisation,
    StandardisationSettings,
    standardise,
)
from sdbc_evolution.sdbc.weighting import (
    FeatureWeighting,
    WeightingSettings,
    mutual_information,
    mutual_information_weights,
)

__all__ = [
    "BehaviourFeature",
    "FeatureKind",
    "FeatureWeighting",
    "SdbcExtractor",
    "SdbcOptions",
    "Standardisation",
    "StandardisationSettings",
    "TrialAggregator",
    "WeightingSettings",
    "aggregate_trial",
    "behaviour_features",
    "characterisation_length",
    "dimension_names",
    "mean_over_trials",
    "mutual_information",
    "mutual_information_weights",
    "standardise",
]

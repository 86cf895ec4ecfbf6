"""sdbc_evolution: systematic behaviour characterisations, novelty search and the GA.

The names a researcher needs to put SDBC novelty search in a loop of their own::

    from sdbc_evolution import NoveltySearch, TaskDescription, EntityGroupSpec, ...

:class:`NoveltySearch` is the method as ask/tell (:mod:`sdbc_evolution.ga.search`);
the task-state formalism it reads is :mod:`sdbc_sim.task_state`'s. Importing this
package loads none of them: each name is loaded on first use (PEP 562), so
``import sdbc_evolution`` imports neither ROS 2 nor the simulator (pymunk, numba).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sdbc_sim.exports import lazy_exports

if TYPE_CHECKING:
    from sdbc_sim.task_state import (
        EntityGroupSpec,
        Geometry,
        GroupState,
        TaskDescription,
        TaskState,
    )

    from sdbc_evolution.ga.breeding import GaConfig
    from sdbc_evolution.ga.novelty import NoveltyConfig
    from sdbc_evolution.ga.search import BestSoFar, NoveltySearch
    from sdbc_evolution.ga.treatments import (
        PRESETS,
        GenerationScores,
        TreatmentSpec,
        parse_treatment,
    )
    from sdbc_evolution.sdbc.characterisation import SdbcExtractor
    from sdbc_evolution.sdbc.standardise import StandardisationSettings
    from sdbc_evolution.sdbc.weighting import WeightingSettings

_LAZY = {
    "NoveltySearch": "sdbc_evolution.ga.search",
    "BestSoFar": "sdbc_evolution.ga.search",
    "GenerationScores": "sdbc_evolution.ga.treatments",
    "PRESETS": "sdbc_evolution.ga.treatments",
    "TreatmentSpec": "sdbc_evolution.ga.treatments",
    "parse_treatment": "sdbc_evolution.ga.treatments",
    "GaConfig": "sdbc_evolution.ga.breeding",
    "NoveltyConfig": "sdbc_evolution.ga.novelty",
    "StandardisationSettings": "sdbc_evolution.sdbc.standardise",
    "WeightingSettings": "sdbc_evolution.sdbc.weighting",
    "SdbcExtractor": "sdbc_evolution.sdbc.characterisation",
    "TaskDescription": "sdbc_sim.task_state",
    "EntityGroupSpec": "sdbc_sim.task_state",
    "Geometry": "sdbc_sim.task_state",
    "TaskState": "sdbc_sim.task_state",
    "GroupState": "sdbc_sim.task_state",
}
"""Exported name -> the module that defines it."""

__all__ = [
    "PRESETS",
    "BestSoFar",
    "EntityGroupSpec",
    "GaConfig",
    "GenerationScores",
    "Geometry",
    "GroupState",
    "NoveltyConfig",
    "NoveltySearch",
    "SdbcExtractor",
    "StandardisationSettings",
    "TaskDescription",
    "TaskState",
    "TreatmentSpec",
    "WeightingSettings",
    "parse_treatment",
]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)

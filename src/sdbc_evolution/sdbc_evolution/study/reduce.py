"""From a study's run directories to its digest (:mod:`.digest`).

The one pass over the full data: each run's curve and per-generation numbers, the
weighting runs' relevance (NS-SD+: mutual information) and the MI's chance level,
and the SOM maps (trained on
a sample, then every individual mapped). Everything after this works on the digest.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sdbc_evolution.study.cost import joined_per_generation, workers_per_generation
from sdbc_evolution.study.digest import (
    PresetSummary,
    RunDigest,
    StudyDigest,
    TaskDigest,
)
from sdbc_evolution.study.exploration import (
    SomSettings,
    default_grids,
    exploration_maps,
    exploration_sensitivity,
)
from sdbc_evolution.study.plan import LOG_FILE, STUDY_FILE
from sdbc_evolution.study.presets import PresetError, load_preset_file
from sdbc_evolution.study.relevance import (
    run_chance_information,
    run_information,
    weight_measure,
)
from sdbc_evolution.study.rundirs import RunData, StudyData

REEVALUATED = "reevaluated_fitness"
"""Column of the re-evaluated best of each generation (the paper's curves)."""
SELECTED = "best_fitness"
"""Column of the best fitness as selection saw it (when there is no re-evaluation)."""


def curve_column(run: RunData) -> str:
    """The column a run's curve comes from: the re-evaluated best where the run
    re-evaluated, else the best as selection saw it (biased upwards)."""
    return REEVALUATED if np.isfinite(run.columns[REEVALUATED]).any() else SELECTED


def read_sessions(root: Path) -> list[dict]:
    """The study log's entries (a damaged line is left out)."""
    path = root / LOG_FILE
    if not path.is_file():
        return []
    entries = []
    for line in path.read_text().splitlines():
        try:
            entry = json.loads(line)
        except ValueError:
            continue
        if isinstance(entry, dict):
            entries.append(entry)
    return entries


def with_study_dir(command: list[str], study_dir: str) -> list[str]:
    """``command`` (as the study log recorded it) with its ``--out`` set to
    ``study_dir``: a study moved or copied after it ran is analysed where it is
    now, and that is the directory a reader would run it into again."""
    shown = list(command)
    for i, word in enumerate(shown):
        if word == "--out" and i + 1 < len(shown):
            shown[i + 1] = study_dir
        elif word.startswith("--out="):
            shown[i] = f"--out={study_dir}"
    return shown


def reduce_run(run: RunData) -> RunDigest:
    """One run's digest; the relevance of each dimension (and the MI's chance
    level) only for runs that weigh the SDBC."""
    column = curve_column(run)
    weighted = weight_measure(run.config) is not None
    joined = joined_per_generation(run)
    return RunDigest(
        name=run.name,
        config=run.config,
        curve=run.columns[column],
        curve_source=column,
        population=np.array([f.shape[0] for f in run.fitness], dtype=np.int64),
        trial_steps=run.trial_steps,
        # A run joined with others timed their trials and work too: its share.
        wall_time=run.columns["wall_time"] / joined,
        evaluation_time=run.columns["evaluation_time"] / joined,
        workers=workers_per_generation(run),
        information=run_information(run) if weighted else None,
        chance=run_chance_information(run) if weighted else None,
        champions=run.champions,
    )


def reduce_task(
    study: StudyData,
    task: str,
    som: SomSettings,
    seeds: Sequence[int] = (),
    grids: Sequence[tuple[int, int]] | None = None,
) -> TaskDigest:
    """One task's digest; with ``seeds``, the maps' sensitivity to them and to
    ``grids`` (default: :func:`~.exploration.default_grids`).

    Raises:
        ValueError: The task's runs do not share one SDBC (different settings).
    """
    from sdbc_sim.tasks import make_task

    runs = study.of(task)
    names = runs[0].sdbc_names
    for run in runs[1:]:
        if run.sdbc_names != names:
            raise ValueError(
                f"{run.name}: SDBC dimensions differ from {runs[0].name}'s; "
                "the runs are not of one task setting"
            )
    built = make_task(task, **runs[0].config.task_config)
    maps = exploration_maps(study, task, som)
    if seeds:
        sensitivity = exploration_sensitivity(
            study, task, som, seeds, default_grids(som) if grids is None else grids
        )
        maps = dataclasses.replace(maps, sensitivity=sensitivity)
    return TaskDigest(
        task=task,
        sdbc_names=names,
        bodies=int(built.layout.n_bodies),
        max_steps=int(built.max_steps),
        runs=tuple(reduce_run(r) for r in runs),
        maps=maps,
    )


def reduce_study(
    study: StudyData,
    som: SomSettings,
    study_dir: str | None = None,
    command: list[str] | None = None,
    seeds: Sequence[int] = (),
    grids: Sequence[tuple[int, int]] | None = None,
) -> StudyDigest:
    """The digest of ``study``; ``study_dir`` is how the report names the study
    directory (default: its path as loaded), and the ``--out`` of the study log's
    commands (:func:`with_study_dir`); ``seeds`` and ``grids`` as
    :func:`reduce_task` takes them."""
    preset, preset_error = None, None
    if (study.root / STUDY_FILE).is_file():
        try:
            loaded = load_preset_file(study.root / STUDY_FILE)
        except PresetError as error:
            preset_error = str(error)
        else:
            preset = PresetSummary(
                name=loaded.name,
                seed=loaded.seed,
                description=loaded.description,
                predictions=loaded.predictions,
            )
    label = str(study.root) if study_dir is None else study_dir
    return StudyDigest(
        study_dir=label,
        task_digests=tuple(
            reduce_task(study, t, som, seeds, grids) for t in study.tasks()
        ),
        problems=tuple(study.problems),
        expected=study.expected,
        sessions=tuple(
            {**s, "command": with_study_dir(s["command"], label)}
            if isinstance(s.get("command"), list)
            else s
            for s in read_sessions(study.root)
        ),
        preset=preset,
        preset_error=preset_error,
        command=tuple(command or ()),
    )

"""Champions re-evaluated: each finished run's best controllers judged on fresh trials.

A run's curve re-evaluates each generation's best in a few trials (the preset's
``evaluation.reevaluation_trials``, 10 in the local studies), and its highest point
is a maximum over many noisy estimates: biased upwards, and in predator-prey
typically a one-generation spike. So once a run's generations are done, the study
runner re-evaluates two of its controllers in ``champion_trials`` (at least
:data:`MIN_CHAMPION_TRIALS`) trials no run used:

- the **champion**: the best of the generation whose curve value is highest (the
  controller the curve's maximum names, chosen as before: first on ties);
- the **last**: the best of the last generation.

Both are evaluated on the same trial seeds (a paired comparison), and each one's
fitness sums its trials up like every fitness of the run (harmonic mean by default).
Fitness verdicts then use the champion's re-evaluated fitness (:mod:`.quality`).

Seeds. Run r of ``treatment`` on ``task`` gets its champion trial seeds from
``SeedSequence(study_seed, spawn_key=(CHAMPION_BRANCH, crc32(task),
crc32(treatment), r))``, a branch of the study seed of its own: the run seeds are
``SeedSequence(study_seed, spawn_key=(crc32(task), crc32(treatment), r))``
(:func:`sdbc_evolution.study.plan.run_seed`, a key of three words, never starting
with :data:`CHAMPION_BRANCH` since crc32 of a task name would have to equal it and
the key lengths differ anyway), and every trial seed a run uses is drawn from
generators seeded by children of its run seed. No stream is shared, so the champion
seeds are a stream independent of every trial seed of every run. As values they are
63-bit numbers like the runs' trial seeds; that any one of a study's few million
trial seeds equals one of its champion seeds has probability below 1e-9 (e.g.
240 runs x 100 generations x 260 trials x 50 champion seeds x 240 runs / 2^63).

The result is ``champion.json`` in the run directory, written atomically once both
evaluations are done: a re-evaluation killed halfway leaves no file and is done
again; a file whose trials or seeds are not the preset's, or whose champion is not
the run's, is not accepted (the run is not finished, see
:func:`sdbc_evolution.study.plan.run_status`).
"""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sdbc_evolution.run.config import ExperimentConfig
from sdbc_evolution.run.evaluators import Evaluator
from sdbc_evolution.run.results import (
    BEST_GENOMES_FILE,
    atomic_write_bytes,
    read_generations,
)

CHAMPION_FILE = "champion.json"
"""Per run directory: its champions' re-evaluation (see the module docstring)."""
CHAMPION_BRANCH = 0xC4A1_0000
"""First spawn-key word of the champion seeds' branch of the study seed."""
MIN_CHAMPION_TRIALS = 50
"""The fewest trials a champion is re-evaluated in (the paper's up to 50)."""
REEVALUATED = "reevaluated_fitness"
SELECTED = "best_fitness"


class ChampionError(ValueError):
    """A champion file that cannot be used; the message says why."""


def champion_seeds(
    study_seed: int, task: str, treatment: str, index: int, trials: int
) -> np.ndarray:
    """(trials,) int64 trial seeds of run ``index``'s champions (module docstring)."""
    sequence = np.random.SeedSequence(
        study_seed,
        spawn_key=(
            CHAMPION_BRANCH,
            zlib.crc32(task.encode()),
            zlib.crc32(treatment.encode()),
            index,
        ),
    )
    words = sequence.generate_state(trials, np.uint64) >> np.uint64(1)
    return words.astype(np.int64)


def champion_generation(columns: dict[str, np.ndarray]) -> tuple[int, str]:
    """The generation whose best is the run's champion, and the column that
    chose it: the highest re-evaluated best (first on ties), or the highest best
    as selection saw it where the run did not re-evaluate."""
    reevaluated = columns[REEVALUATED]
    column = REEVALUATED if np.isfinite(reevaluated).any() else SELECTED
    return int(np.nanargmax(columns[column])), column


@dataclass(frozen=True)
class Reevaluated:
    """One controller judged on the champion trials.

    Attributes:
        generation: The generation it was the best of.
        fitness: Its fitness over the trials (summed up like the run's).
        mean: The arithmetic mean of its trials.
        trial_fitness: (T,) each trial's fitness.
    """

    generation: int
    fitness: float
    mean: float
    trial_fitness: tuple[float, ...]

    def to_plain(self) -> dict[str, Any]:
        """As plain data (JSON)."""
        return {
            "generation": self.generation,
            "fitness": self.fitness,
            "mean": self.mean,
            "trial_fitness": list(self.trial_fitness),
        }


@dataclass(frozen=True)
class Champions:
    """A run's champion and last best, re-evaluated.

    Attributes:
        trials: Trials each was evaluated in.
        seeds: (trials,) the trial seeds, shared by both.
        chosen_by: The ``generations.csv`` column that chose the champion.
        curve_value: The champion's value on that column.
        champion: The champion re-evaluated.
        last: The last generation's best re-evaluated.
    """

    trials: int
    seeds: tuple[int, ...]
    chosen_by: str
    curve_value: float
    champion: Reevaluated
    last: Reevaluated

    def to_json(self) -> bytes:
        """The file a run's champions are kept in, as bytes."""
        data = {
            "trials": self.trials,
            "seeds": list(self.seeds),
            "chosen_by": self.chosen_by,
            "curve_value": self.curve_value,
            "champion": self.champion.to_plain(),
            "last": self.last.to_plain(),
        }
        return (json.dumps(data, indent=1) + "\n").encode()


def _reevaluated(data: Any, where: str) -> Reevaluated:
    try:
        trials = tuple(float(v) for v in data["trial_fitness"])
        return Reevaluated(
            generation=int(data["generation"]),
            fitness=float(data["fitness"]),
            mean=float(data["mean"]),
            trial_fitness=trials,
        )
    except (KeyError, TypeError, ValueError) as error:
        raise ChampionError(f"{where}: {error!r}") from None


def read_champions(path: Path) -> Champions:
    """Reads ``path/champion.json`` (raises :class:`ChampionError`)."""
    file = path / CHAMPION_FILE
    try:
        data = json.loads(file.read_text())
        champions = Champions(
            trials=int(data["trials"]),
            seeds=tuple(int(s) for s in data["seeds"]),
            chosen_by=str(data["chosen_by"]),
            curve_value=float(data["curve_value"]),
            champion=_reevaluated(data["champion"], f"{file} champion"),
            last=_reevaluated(data["last"], f"{file} last"),
        )
    except FileNotFoundError:
        raise ChampionError(f"{file} is missing") from None
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ChampionError(f"{file} unreadable: {error!r}") from None
    for part in (champions.champion, champions.last):
        if len(part.trial_fitness) != champions.trials:
            raise ChampionError(
                f"{file}: {len(part.trial_fitness)} trial values, not "
                f"{champions.trials}"
            )
    return champions


def check_champions(path: Path, seeds: np.ndarray, generations: int) -> Champions:
    """The run's champion file if it is the one the study asks for: these
    ``seeds``, the champion the run's ``generations.csv`` names, and the last of
    its ``generations`` generations (raises :class:`ChampionError` otherwise)."""
    champions = read_champions(path)
    if champions.seeds != tuple(int(s) for s in seeds):
        raise ChampionError(
            f"{path / CHAMPION_FILE}: trials or seeds are not the study's "
            f"({champions.trials} trials)"
        )
    columns = read_generations(path)
    generation, column = champion_generation(columns)
    if (champions.champion.generation, champions.chosen_by) != (generation, column):
        raise ChampionError(
            f"{path / CHAMPION_FILE}: champion of generation "
            f"{champions.champion.generation}, the run's is {generation}"
        )
    if champions.last.generation != generations - 1:
        raise ChampionError(
            f"{path / CHAMPION_FILE}: last best of generation "
            f"{champions.last.generation}, not {generations - 1}"
        )
    return champions


def reevaluate_champions(
    path: Path, config: ExperimentConfig, evaluator: Evaluator, seeds: np.ndarray
) -> Champions:
    """Re-evaluates the finished run in ``path`` on ``seeds`` and writes its
    ``champion.json`` (atomically, once both evaluations are done)."""
    from sdbc_sim.engine import controller_fitness

    columns = read_generations(path)
    generations = len(columns["generation"])
    if generations != config.resolved_generations:
        raise ChampionError(
            f"{path}: {generations} of {config.resolved_generations} generations "
            "done; champions are re-evaluated after the last"
        )
    best = np.load(path / BEST_GENOMES_FILE, allow_pickle=False)
    generation, column = champion_generation(columns)
    last = generations - 1
    chosen = [generation] if generation == last else [generation, last]
    trials = int(seeds.shape[0])
    # One row per trial, as the runs' own re-evaluation does: the evaluator
    # spreads them over its workers, and a trial's result ignores its batch-mates.
    genomes = np.repeat(best[chosen], trials, axis=0)
    rows = np.tile(seeds, len(chosen)).reshape(-1, 1).astype(np.int64)
    evaluation = evaluator.evaluate(genomes, rows)
    per_trial = evaluation.trial_fitness.reshape(len(chosen), trials)
    fitness = controller_fitness(per_trial, config.evaluation.fitness_mean)
    judged = [
        Reevaluated(
            generation=g,
            fitness=float(fitness[k]),
            mean=float(per_trial[k].mean()),
            trial_fitness=tuple(float(v) for v in per_trial[k]),
        )
        for k, g in enumerate(chosen)
    ]
    champions = Champions(
        trials=trials,
        seeds=tuple(int(s) for s in seeds),
        chosen_by=column,
        curve_value=float(columns[column][generation]),
        champion=judged[0],
        last=judged[-1],
    )
    atomic_write_bytes(path / CHAMPION_FILE, champions.to_json())
    return champions


@dataclass(frozen=True)
class ChampionSummary:
    """What a study's digest keeps of a run's champions.

    Attributes:
        trials: Trials each was re-evaluated in.
        generation: The champion's generation.
        fitness: The champion's re-evaluated fitness (what fitness verdicts use).
        mean: The arithmetic mean of its trials.
        last_fitness: The last generation's best, re-evaluated.
        last_mean: The arithmetic mean of its trials.
    """

    trials: int
    generation: int
    fitness: float
    mean: float
    last_fitness: float
    last_mean: float

    @classmethod
    def of(cls, champions: Champions) -> ChampionSummary:
        """The summary of a run's :class:`Champions`."""
        return cls(
            trials=champions.trials,
            generation=champions.champion.generation,
            fitness=champions.champion.fitness,
            mean=champions.champion.mean,
            last_fitness=champions.last.fitness,
            last_mean=champions.last.mean,
        )

"""A study's digest: the little its report needs, small enough to commit.

The run directories of a study are large (every individual of every generation);
its report needs far less. The digest keeps exactly that, so that the report, its
tables and its figures can be made again from the digest alone (``sdbc-study
analyse --from-digest``), byte for byte. Per run:

- its configuration, its curve (the best of each generation re-evaluated, or as
  selection saw it, see :func:`sdbc_evolution.study.reduce.curve_column`) and per
  generation the population size, the trial steps, the wall and evaluation times
  and the workers (the cost table);
- for runs that weigh the SDBC (NS-SD+ and any declared weighting treatment), each
  SDBC dimension's relevance (weight - delta: for NS-SD+ its MI with fitness)
  averaged over the run's generations, and the MI's chance level from evenly
  spaced generations (:mod:`.relevance`);
- its individuals per unit of the task's SOM (:mod:`.exploration`), and where the
  analysis asked for it, its uniformity and high-fitness share on maps of other
  seeds and grids (a digest without them stays the bytes it was);
- where the study re-evaluated champions (:mod:`.champions`), the champion's
  generation and re-evaluated fitness, the last generation's best re-evaluated,
  and the trials (a digest of a study without them holds none of these arrays, so
  it stays the bytes it was).

Per task: the SDBC dimension names, bodies per trial and the longest trial, and the
SOM's fitness percentile per unit for each treatment and pooled. Per study: the
preset's name, seed and description, the study log's sessions (a run command's
``--out`` given as the study directory analysed), the runs left out, and the SOM's
settings. Not kept: the SDBC vectors, the genomes, the SOM's weights.

On disk, ``DIR/study.json`` and one ``DIR/<task>.npz`` per task (layout in
:func:`write_digest`); both written with fixed key order and zip timestamps, so a
digest of the same runs is the same bytes. :func:`read_digest` checks everything it
reads and raises :class:`DigestError` naming the file and the problem.
"""

from __future__ import annotations

import dataclasses
import json
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from sdbc_sim.limits import excerpt
from sdbc_sim.settings import load
from sdbc_sim.yaml_input import YamlRefused, parse_yaml

from sdbc_evolution.ga.treatments import PAPER_TREATMENTS
from sdbc_evolution.run.config import (
    ConfigError,
    ExperimentConfig,
    config_from_dict,
    dump_config,
)
from sdbc_evolution.run.results import npz_bytes
from sdbc_evolution.study.champions import ChampionSummary
from sdbc_evolution.study.exploration import ExplorationMaps, Sensitivity, SomSettings
from sdbc_evolution.study.predictions import Prediction
from sdbc_evolution.study.rundirs import RunProblem

DIGEST_DIR = "digest"
"""The digest's folder beside a report."""
STUDY_JSON = "study.json"
FORMAT = "sdbc-study-digest"
VERSION = 1


class DigestError(ValueError):
    """A digest that cannot be read: the message names the file and the problem."""


@dataclass(frozen=True)
class RunDigest:
    """One run, reduced.

    Attributes:
        name: Path relative to the study directory.
        config: Its resolved configuration.
        curve: (G,) best fitness of each generation (re-evaluated if it was).
        curve_source: The ``generations.csv`` column the curve comes from.
        population: (G,) individuals evaluated in each generation.
        trial_steps: (G,) total trial steps of each generation's population.
        wall_time: (G,) seconds each generation took.
        evaluation_time: (G,) seconds of it spent in the evaluator.
        workers: (G,) workers that evaluated each generation.
        information: (D,) mean weight - delta of each SDBC dimension (NS-SD+: its
            MI with fitness, bits); weighting runs only, else None.
        chance: (D,) the MI's chance level, bits (weighting runs only, else
            None).
        champions: Its champions re-evaluated, or None.
    """

    name: str
    config: ExperimentConfig
    curve: np.ndarray
    curve_source: str
    population: np.ndarray
    trial_steps: np.ndarray
    wall_time: np.ndarray
    evaluation_time: np.ndarray
    workers: np.ndarray
    information: np.ndarray | None = None
    chance: np.ndarray | None = None
    champions: ChampionSummary | None = None

    @property
    def task(self) -> str:
        """The task of the run, as its configuration names it."""
        return self.config.task

    @property
    def treatment(self) -> str:
        """The treatment's name."""
        return self.config.treatment.name

    @property
    def generations(self) -> int:
        """Generations the run's curve covers."""
        return int(self.curve.shape[0])


def _ordered_treatments(runs: Any) -> list[str]:
    """Treatment names of ``runs``: the paper's four in its order, then the
    others in the order of their runs."""
    present = list(dict.fromkeys(r.treatment for r in runs))
    paper = [t for t in PAPER_TREATMENTS if t in present]
    return paper + [t for t in present if t not in paper]


@dataclass(frozen=True)
class TaskDigest:
    """One task's runs, reduced, and its SOM maps.

    Attributes:
        task: Task name.
        sdbc_names: (D,) the SDBC dimension names.
        bodies: Bodies per trial.
        max_steps: The task's longest trial.
        runs: Its usable runs, in the study directory's order.
        maps: The exploration maps (per-run counts per unit, percentiles).
    """

    task: str
    sdbc_names: tuple[str, ...]
    bodies: int
    max_steps: int
    runs: tuple[RunDigest, ...]
    maps: ExplorationMaps

    def of(self, treatment: str | None = None) -> list[RunDigest]:
        """Its runs (of one treatment, by name)."""
        return [r for r in self.runs if treatment is None or r.treatment == treatment]

    def treatments(self) -> list[str]:
        """Names of the treatments with usable runs: the paper's four in its
        order, then the others in the order of their runs."""
        return _ordered_treatments(self.runs)


@dataclass(frozen=True)
class PresetSummary:
    """What the report says of the study's preset (``study.yaml``)."""

    name: str
    seed: int
    description: str
    predictions: tuple[Prediction, ...] = ()
    """The preset's own predictions, which the analysis judges."""


@dataclass(frozen=True)
class StudyDigest:
    """A whole study, reduced.

    Attributes:
        study_dir: The study directory as it was given to the analysis.
        task_digests: One per task with usable runs, the paper's tasks first.
        problems: Runs left out (unusable, or expected and absent).
        expected: Runs the study's preset expects (None without ``study.yaml``).
        sessions: The study log's entries.
        preset: The preset (None without a readable ``study.yaml``).
        preset_error: Why ``study.yaml`` could not be read (None if it could, or
            if there is none).
        command: The command that made the digest (empty if not recorded).
    """

    study_dir: str
    task_digests: tuple[TaskDigest, ...]
    problems: tuple[RunProblem, ...]
    expected: int | None
    sessions: tuple[dict[str, Any], ...]
    preset: PresetSummary | None
    preset_error: str | None
    command: tuple[str, ...] = ()

    def tasks(self) -> list[str]:
        """The study's tasks, in the digest's order."""
        return [t.task for t in self.task_digests]

    def task(self, name: str) -> TaskDigest:
        """The digest of the task called ``name``.

        Raises:
            KeyError: The study has no such task.
        """
        for digest in self.task_digests:
            if digest.task == name:
                return digest
        raise KeyError(name)

    @property
    def runs(self) -> list[RunDigest]:
        """Every run of every task."""
        return [r for t in self.task_digests for r in t.runs]

    def of(self, task: str, treatment: str | None = None) -> list[RunDigest]:
        """The runs of ``task``, of one treatment or (None) of all."""
        return self.task(task).of(treatment)


PER_GENERATION = ("curve", "population", "trial_steps", "wall_time", "evaluation_time")
"""Per-generation arrays of a run, concatenated over a task's runs in the npz."""
FLOAT_PER_GENERATION = ("curve", "trial_steps", "wall_time", "evaluation_time")


def _json_bytes(data: dict[str, Any]) -> bytes:
    return (json.dumps(data, indent=1, sort_keys=True) + "\n").encode()


def _strings(values: Any) -> np.ndarray:
    # Fixed-width unicode: np.load reads it without pickle.
    return np.array(list(values), dtype=str)


def task_arrays(digest: TaskDigest) -> dict[str, np.ndarray]:
    """The arrays of ``<task>.npz`` (see :func:`write_digest`)."""
    runs = digest.runs
    maps = digest.maps
    by_name = {
        name: counts[i]
        for names, counts in zip(maps.run_names, maps.counts, strict=True)
        for i, name in enumerate(names)
    }
    weighted = [i for i, r in enumerate(runs) if r.information is not None]
    width = len(digest.sdbc_names)
    arrays: dict[str, np.ndarray] = {
        "sdbc_names": _strings(digest.sdbc_names),
        "bodies": np.array(digest.bodies, dtype=np.int64),
        "max_steps": np.array(digest.max_steps, dtype=np.int64),
        "run_names": _strings(r.name for r in runs),
        "configs": _strings(dump_config(r.config) for r in runs),
        "curve_sources": _strings(r.curve_source for r in runs),
        "generations": np.array([r.generations for r in runs], dtype=np.int64),
        "curve": np.concatenate([r.curve for r in runs]).astype(np.float64),
        "population": np.concatenate([r.population for r in runs]).astype(np.int64),
        "trial_steps": np.concatenate([r.trial_steps for r in runs]).astype(np.float64),
        "wall_time": np.concatenate([r.wall_time for r in runs]).astype(np.float64),
        "evaluation_time": np.concatenate([r.evaluation_time for r in runs]).astype(
            np.float64
        ),
        "workers": np.concatenate([r.workers for r in runs]).astype(np.int64),
        "mi_runs": np.array(weighted, dtype=np.int64),
        "mi": np.array(
            [runs[i].information for i in weighted], dtype=np.float64
        ).reshape(len(weighted), width),
        "mi_chance": np.array(
            [runs[i].chance for i in weighted], dtype=np.float64
        ).reshape(len(weighted), width),
        "som_treatments": _strings(maps.treatments),
        "som_counts": np.stack([by_name[r.name] for r in runs]).astype(np.int64),
        "som_percentile": maps.percentile.astype(np.float64),
        "som_pooled_percentile": maps.pooled_percentile.astype(np.float64),
        "som_sample_count": np.array(maps.sample_count, dtype=np.int64),
        "som_quantisation_error": np.array(maps.quantisation_error, dtype=np.float64),
    }
    if any(r.champions is not None for r in runs):
        arrays.update(_champion_arrays(runs))
    if maps.sensitivity is not None:
        arrays.update(_sensitivity_arrays(maps, [r.name for r in runs]))
    return arrays


def _sensitivity_arrays(
    maps: ExplorationMaps, order: list[str]
) -> dict[str, np.ndarray]:
    sensitivity = maps.sensitivity
    assert sensitivity is not None
    columns = {
        "uniformity": sensitivity.uniformity,
        "region_share": sensitivity.region_share,
    }
    arrays = {
        "som_sensitivity_seeds": np.array(sensitivity.seeds, dtype=np.int64),
        "som_sensitivity_grids": np.array(sensitivity.grids, dtype=np.int64).reshape(
            -1, 2
        ),
    }
    for key, per_treatment in columns.items():
        by_name = {
            name: values[:, :, i]
            for names, values in zip(maps.run_names, per_treatment, strict=True)
            for i, name in enumerate(names)
        }
        arrays[f"som_sensitivity_{key}"] = np.stack(
            [by_name[name] for name in order], axis=-1
        ).astype(np.float64)
    return arrays


def _read_sensitivity(npz: _Npz, r: int, groups: list[list[int]]) -> Sensitivity | None:
    if "som_sensitivity_seeds" not in npz.arrays:
        return None
    seeds = npz.get("som_sensitivity_seeds", "i", (None,))
    grids = npz.get("som_sensitivity_grids", "i", (None, 2))
    if seeds.size == 0 or grids.shape[0] == 0 or (grids < 2).any():
        raise _fail(
            npz.file, "'som_sensitivity_*': no seed, no grid, or a grid under 2"
        )
    shape = (grids.shape[0], seeds.size, r)
    values = {
        key: npz.get(f"som_sensitivity_{key}", "f", shape)
        for key in ("uniformity", "region_share")
    }
    return Sensitivity(
        seeds=tuple(int(x) for x in seeds),
        grids=tuple((int(a), int(b)) for a, b in grids),
        uniformity=tuple(values["uniformity"][:, :, g] for g in groups),
        region_share=tuple(values["region_share"][:, :, g] for g in groups),
    )


CHAMPION_ARRAYS = {
    "champion_trials": ("trials", np.int64, 0),
    "champion_generation": ("generation", np.int64, -1),
    "champion_fitness": ("fitness", np.float64, np.nan),
    "champion_mean": ("mean", np.float64, np.nan),
    "last_fitness": ("last_fitness", np.float64, np.nan),
    "last_mean": ("last_mean", np.float64, np.nan),
}
"""Per-run arrays of re-evaluated champions: field of :class:`ChampionSummary`,
dtype, and the value of a run without (0 trials)."""


def _champion_arrays(runs: tuple[RunDigest, ...]) -> dict[str, np.ndarray]:
    return {
        key: np.array(
            [
                missing if r.champions is None else getattr(r.champions, name)
                for r in runs
            ],
            dtype=dtype,
        )
        for key, (name, dtype, missing) in CHAMPION_ARRAYS.items()
    }


def _read_champions(npz: _Npz, r: int) -> list[ChampionSummary | None]:
    if "champion_trials" not in npz.arrays:
        return [None] * r
    arrays = {
        key: npz.get(key, "i" if dtype is np.int64 else "f", (r,))
        for key, (_, dtype, _) in CHAMPION_ARRAYS.items()
    }
    found: list[ChampionSummary | None] = []
    for i in range(r):
        if int(arrays["champion_trials"][i]) <= 0:
            found.append(None)
            continue
        values = {
            name: arrays[key][i].item() for key, (name, _, _) in CHAMPION_ARRAYS.items()
        }
        found.append(ChampionSummary(**values))
    return found


def _preset_json(preset: PresetSummary) -> dict[str, Any]:
    data = dataclasses.asdict(preset)
    if not preset.predictions:
        # A study without predictions keeps the digest it had before they existed.
        del data["predictions"]
    return data


def study_json(digest: StudyDigest, som: SomSettings) -> dict[str, Any]:
    """The content of ``study.json`` (see :func:`write_digest`)."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "study_dir": digest.study_dir,
        "command": list(digest.command),
        "tasks": digest.tasks(),
        "expected": digest.expected,
        "problems": [[p.name, p.reason] for p in digest.problems],
        "sessions": list(digest.sessions),
        "preset": None if digest.preset is None else _preset_json(digest.preset),
        "preset_error": digest.preset_error,
        "som": dataclasses.asdict(som),
    }


def write_digest(digest: StudyDigest, directory: str | Path) -> list[Path]:
    """Writes ``digest`` into ``directory`` and returns the files written::

        study.json      format, version, study_dir, command, tasks, expected,
                        problems [[run, reason]], sessions (study log entries),
                        preset {name, seed, description, predictions (if
                        any)} or preset_error, som
                        (the SOM settings)
        <task>.npz      sdbc_names (D,); bodies, max_steps; per run (R of them, the
                        study directory's order): run_names, configs (YAML),
                        curve_sources, generations (G_r); per generation,
                        concatenated over the runs: curve, population,
                        trial_steps, wall_time, evaluation_time, workers; per
                        weighting run: mi_runs (run index), mi (weight - delta)
                        and mi_chance (D,);
                        som_counts (R, U); per treatment som_treatments,
                        som_percentile (K, U); som_pooled_percentile (U,),
                        som_sample_count, som_quantisation_error; where any
                        run re-evaluated its champions, per run (R,):
                        champion_trials (0: not re-evaluated),
                        champion_generation, champion_fitness, champion_mean,
                        last_fitness, last_mean; where the analysis measured
                        the maps' sensitivity, som_sensitivity_seeds (S,),
                        som_sensitivity_grids (G, 2) rows and columns,
                        som_sensitivity_uniformity and
                        som_sensitivity_region_share (G, S, R)

    Files of tasks not in the digest are removed, so the folder is the digest.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    soms = {t.maps.settings for t in digest.task_digests}
    if len(soms) > 1:
        raise ValueError("the tasks' maps were made with different SOM settings")
    som = soms.pop() if soms else SomSettings()
    written = [directory / STUDY_JSON]
    written[0].write_bytes(_json_bytes(study_json(digest, som)))
    for task in digest.task_digests:
        path = task_file(directory, task.task, directory / STUDY_JSON)
        path.write_bytes(npz_bytes(task_arrays(task)))
        written.append(path)
    for stale in directory.glob("*.npz"):
        if stale not in written:
            stale.unlink()
    return written


def digest_size(directory: str | Path) -> int:
    """Bytes of the digest's files."""
    return sum(p.stat().st_size for p in Path(directory).iterdir() if p.is_file())


# Reading, every field checked.


def task_file(directory: Path, task: str, file: Path) -> Path:
    """``directory/<task>.npz``, refused for a task name that would name a file
    elsewhere (a path separator, a leading dot): a digest never opens or writes
    anything outside its folder."""
    if not task or "/" in task or "\\" in task or task.startswith(".") or "\0" in task:
        raise _fail(
            file,
            f"task name {excerpt(task)} would name a file outside the digest's "
            "folder (a path separator or a leading dot)",
        )
    return directory / f"{task}.npz"


def _fail(file: Path, message: str) -> DigestError:
    return DigestError(f"digest {file}: {message}")


def _field(data: dict[str, Any], key: str, kind: type | tuple, file: Path) -> Any:
    if key not in data:
        raise _fail(file, f"no {key!r}")
    value = data[key]
    if not isinstance(value, kind) or isinstance(value, bool) and kind is int:
        raise _fail(file, f"{key!r} has the wrong type ({type(value).__name__})")
    return value


def _read_json(file: Path) -> dict[str, Any]:
    if not file.is_file():
        raise _fail(file, "missing (is this a digest folder?)")
    try:
        data = json.loads(file.read_text())
    except (OSError, ValueError) as error:
        raise _fail(file, f"not readable JSON ({error})") from None
    if not isinstance(data, dict):
        raise _fail(file, "not a JSON object")
    if data.get("format") != FORMAT:
        raise _fail(file, f"format is {data.get('format')!r}, not {FORMAT!r}")
    if data.get("version") != VERSION:
        raise _fail(
            file, f"version {data.get('version')!r}; this code reads version {VERSION}"
        )
    return data


class _Npz:
    """An opened ``<task>.npz`` whose arrays are checked as they are taken."""

    def __init__(self, file: Path) -> None:
        self.file = file
        if not file.is_file():
            raise _fail(file, "missing")
        try:
            with np.load(file, allow_pickle=False) as data:
                self.arrays = {k: np.asarray(data[k]) for k in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as e:
            raise _fail(file, f"unreadable ({type(e).__name__}: {e})") from None

    def get(self, key: str, kind: str, shape: tuple[int | None, ...]) -> np.ndarray:
        if key not in self.arrays:
            raise _fail(self.file, f"no array {key!r}")
        array = self.arrays[key]
        if array.dtype.kind not in kind:
            raise _fail(self.file, f"{key!r} has dtype {array.dtype}, not {kind!r}")
        if len(shape) != array.ndim or any(
            s is not None and s != a for s, a in zip(shape, array.shape, strict=True)
        ):
            want = tuple("any" if s is None else s for s in shape)
            raise _fail(self.file, f"{key!r} has shape {array.shape}, not {want}")
        return array


def _read_task(file: Path, task: str, som: SomSettings) -> TaskDigest:
    npz = _Npz(file)
    names = tuple(str(n) for n in npz.get("sdbc_names", "U", (None,)))
    d = len(names)
    run_names = [str(n) for n in npz.get("run_names", "U", (None,))]
    r = len(run_names)
    configs = npz.get("configs", "U", (r,))
    sources = npz.get("curve_sources", "U", (r,))
    lengths = npz.get("generations", "i", (r,))
    if (lengths < 1).any():
        raise _fail(file, "a run with no generation")
    total = int(lengths.sum())
    per_generation = {
        key: npz.get(key, "f" if key in FLOAT_PER_GENERATION else "i", (total,))
        for key in PER_GENERATION
    }
    workers = npz.get("workers", "i", (total,))
    mi_runs = npz.get("mi_runs", "i", (None,))
    if ((mi_runs < 0) | (mi_runs >= r)).any() or len(set(mi_runs)) != mi_runs.size:
        raise _fail(file, "'mi_runs' holds an index that is not a run")
    mi = npz.get("mi", "f", (mi_runs.size, d))
    chance = npz.get("mi_chance", "f", (mi_runs.size, d))
    units = som.units
    counts = npz.get("som_counts", "i", (r, units))
    som_treatments = tuple(str(t) for t in npz.get("som_treatments", "U", (None,)))
    percentile = npz.get("som_percentile", "f", (len(som_treatments), units))
    pooled = npz.get("som_pooled_percentile", "f", (units,))
    sample_count = int(npz.get("som_sample_count", "i", ()))
    quantisation_error = float(npz.get("som_quantisation_error", "f", ()))
    bodies = int(npz.get("bodies", "i", ()))
    max_steps = int(npz.get("max_steps", "i", ()))

    champions = _read_champions(npz, r)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    information = dict(zip(mi_runs.tolist(), mi, strict=True))
    chances = dict(zip(mi_runs.tolist(), chance, strict=True))
    runs = []
    for i, name in enumerate(run_names):
        try:
            config = config_from_dict(parse_yaml(str(configs[i]), "configuration"))
        except (ConfigError, YamlRefused) as error:
            raise _fail(file, f"configuration of {name}: {error}") from None
        if config.task != task:
            raise _fail(file, f"{name} is a run of {config.task!r}, not {task!r}")
        window = slice(int(offsets[i]), int(offsets[i + 1]))
        runs.append(
            RunDigest(
                name=name,
                config=config,
                curve=per_generation["curve"][window],
                curve_source=str(sources[i]),
                population=per_generation["population"][window],
                trial_steps=per_generation["trial_steps"][window],
                wall_time=per_generation["wall_time"][window],
                evaluation_time=per_generation["evaluation_time"][window],
                workers=workers[window].astype(np.float64),
                information=information.get(i),
                chance=chances.get(i),
                champions=champions[i],
            )
        )
    present = _ordered_treatments(runs)
    if sorted(som_treatments) != sorted(present):
        raise _fail(
            file,
            f"'som_treatments' {list(som_treatments)} are not the runs' "
            f"treatments {present}",
        )
    present = list(som_treatments)
    by_treatment = [
        [i for i, r in enumerate(runs) if r.treatment == t] for t in present
    ]
    maps = ExplorationMaps(
        task=task,
        settings=som,
        treatments=som_treatments,
        run_names=tuple(tuple(runs[i].name for i in group) for group in by_treatment),
        counts=tuple(counts[group] for group in by_treatment),
        percentile=percentile,
        pooled_percentile=pooled,
        sample_count=sample_count,
        quantisation_error=quantisation_error,
        sensitivity=_read_sensitivity(npz, r, by_treatment),
    )
    if (counts.sum(axis=1) < 1).any():
        raise _fail(file, "'som_counts': a run with no individual mapped")
    return TaskDigest(task, names, bodies, max_steps, tuple(runs), maps)


def read_digest(directory: str | Path) -> StudyDigest:
    """Reads the digest in ``directory``.

    Raises:
        DigestError: A file is missing, unreadable or not what a digest holds.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise DigestError(f"no digest folder {directory}")
    file = directory / STUDY_JSON
    data = _read_json(file)
    tasks = _field(data, "tasks", list, file)
    if not tasks or not all(isinstance(t, str) for t in tasks):
        raise _fail(file, "'tasks' must name at least one task")
    som_data = _field(data, "som", dict, file)
    try:
        som = SomSettings(**som_data)
    except (TypeError, ValueError) as error:
        raise _fail(file, f"'som': {error}") from None
    problems = _field(data, "problems", list, file)
    if not all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(s, str) for s in p)
        for p in problems
    ):
        raise _fail(file, "'problems' must be [run, reason] pairs")
    expected = data.get("expected")
    if expected is not None and (not isinstance(expected, int) or expected < 0):
        raise _fail(
            file, f"'expected' must be a count or null, got {excerpt(expected)}"
        )
    sessions = _field(data, "sessions", list, file)
    if not all(isinstance(s, dict) for s in sessions):
        raise _fail(file, "'sessions' must be objects")
    preset_data = data.get("preset")
    preset = None
    if preset_data is not None:
        try:
            preset = PresetSummary(
                name=str(preset_data["name"]),
                seed=int(preset_data["seed"]),
                description=str(preset_data["description"]),
                predictions=tuple(
                    load(Prediction, p, where=f"predictions.{k}")
                    for k, p in enumerate(preset_data.get("predictions", ()))
                ),
            )
        except (KeyError, TypeError, ValueError) as error:
            raise _fail(file, f"'preset': {error!r}") from None
    preset_error = data.get("preset_error")
    command = _field(data, "command", list, file)
    task_digests = tuple(
        _read_task(task_file(directory, task, file), task, som) for task in tasks
    )
    return StudyDigest(
        study_dir=str(_field(data, "study_dir", str, file)),
        task_digests=task_digests,
        problems=tuple(RunProblem(name, reason) for name, reason in problems),
        expected=expected,
        sessions=tuple(sessions),
        preset=preset,
        preset_error=None if preset_error is None else str(preset_error),
        command=tuple(str(c) for c in command),
    )

"""Reading a study's run directories for the analysis, and saying which are unusable.

The analysis knows runs only through the output layout of
:mod:`sdbc_evolution.run.results`: any directory under the study directory holding a
``config.yaml`` is a run (hidden directories such as ``.discarded`` excepted), its
task and treatment are read from that file. A run is usable when every generation the
configuration asks for is there, whole: ``generations.csv`` parses, has one row per
generation, numbered 0, 1, ...; every ``individuals/gen_NNNNN.npz`` opens and holds
``fitness`` (N,) and ``sdbc`` (N, D) with D the CSV's weight columns. Anything else
(a run still going, a truncated CSV, a corrupt npz, a missing file) makes the run a
:class:`RunProblem`, reported by name; the analysis goes on without it. If the study
directory has ``study.yaml``, runs its preset expects but that are not there are
reported too, and so are runs whose champions the preset re-evaluates
(``champion_trials``) and whose ``champion.json`` is missing or unreadable.

Reading a run checks every file once, keeping per generation only what is small
(fitness, the sum of trial lengths); the SDBC vectors are read again, one generation
at a time, by whoever needs them (:meth:`RunData.sdbc_generations`).
"""

from __future__ import annotations

import csv
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sdbc_evolution.ga.treatments import PAPER_TREATMENTS, TreatmentSpec
from sdbc_evolution.run.config import (
    ConfigError,
    ExperimentConfig,
    load_config,
)
from sdbc_evolution.run.results import (
    BASE_COLUMNS,
    CONFIG_FILE,
    GENERATIONS_FILE,
    INDIVIDUALS_DIR,
    WEIGHT_PREFIX,
)
from sdbc_evolution.study.champions import (
    CHAMPION_FILE,
    ChampionError,
    ChampionSummary,
    read_champions,
)
from sdbc_evolution.study.paper import PAPER_TASKS
from sdbc_evolution.study.plan import STUDY_FILE, study_plan
from sdbc_evolution.study.presets import PresetError, load_preset_file

LENGTH_DIMENSION = "Simulation length"
"""The SDBC dimension holding a controller's mean trial length in steps."""


MISSING = "missing"
"""Reason given for a run the preset expects and the study directory lacks."""


@dataclass(frozen=True)
class RunProblem:
    """A run the analysis leaves out, and why.

    Attributes:
        name: The run's path relative to the study directory.
        reason: What is wrong, in a sentence.
    """

    name: str
    reason: str


@dataclass
class RunData:
    """One usable run.

    Attributes:
        name: Path relative to the study directory.
        path: The run directory.
        config: Its configuration.
        columns: ``generations.csv`` as float columns (empty cells NaN).
        sdbc_names: The SDBC dimension names.
        weight_names: The names of the weighted dimensions (the weight columns;
            those of the treatment's own characterisation when it is not the
            SDBC).
        fitness: One (N,) array per generation.
        trial_steps: (G,) total trial steps of each generation's population
            (sum over individuals of mean trial length x trials).
    """

    name: str
    path: Path
    config: ExperimentConfig
    columns: dict[str, np.ndarray]
    sdbc_names: tuple[str, ...]
    fitness: list[np.ndarray] = field(repr=False)
    trial_steps: np.ndarray = field(repr=False)
    weight_names: tuple[str, ...] = ()
    champions: ChampionSummary | None = None
    """Its champions re-evaluated (:mod:`.champions`), if they were."""

    @property
    def task(self) -> str:
        """The task of the run, as its configuration names it."""
        return self.config.task

    @property
    def treatment(self) -> str:
        """The treatment's name."""
        return self.config.treatment.name

    @property
    def treatment_spec(self) -> TreatmentSpec:
        """The treatment's declaration."""
        return self.config.treatment

    @property
    def generations(self) -> int:
        """Generations the run has written."""
        return len(self.fitness)

    def sdbc(self, generation: int) -> np.ndarray:
        """The raw SDBC vectors (N, D) float32 of one generation."""
        with np.load(_individuals_path(self.path, generation)) as data:
            return np.asarray(data["sdbc"])

    def behaviour(self, generation: int) -> np.ndarray:
        """The raw vectors (N, D) of the treatment's own characterisation in one
        generation (the SDBC's, or the task-specific ones, for the paper's)."""
        with np.load(_individuals_path(self.path, generation)) as data:
            if "behaviour" in data.files:
                return np.asarray(data["behaviour"])
            spec = self.treatment_spec.characterisation
            key = "characterisation" if spec and spec.kind == "task" else "sdbc"
            return np.asarray(data[key])

    def sdbc_generations(self) -> Iterator[np.ndarray]:
        """The raw SDBC vectors (N, D) float32 of each generation, in order."""
        for g in range(self.generations):
            yield self.sdbc(g)


def _individuals_path(run: Path, generation: int) -> Path:
    return run / INDIVIDUALS_DIR / f"gen_{generation:05d}.npz"


def find_runs(root: Path) -> list[Path]:
    """Every run directory under ``root`` (hidden directories skipped), sorted."""
    found = []
    for config in sorted(root.rglob(CONFIG_FILE)):
        relative = config.parent.relative_to(root)
        if any(part.startswith(".") for part in relative.parts):
            continue
        found.append(config.parent)
    return found


def _read_csv(path: Path) -> tuple[list[str], list[list[float]]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ValueError(f"{GENERATIONS_FILE} is empty")
    header, body = rows[0], rows[1:]
    if tuple(header[: len(BASE_COLUMNS)]) != BASE_COLUMNS:
        raise ValueError(f"{GENERATIONS_FILE} has an unknown header")
    data = []
    for i, row in enumerate(body):
        if len(row) != len(header):
            raise ValueError(
                f"{GENERATIONS_FILE} row {i + 1} has {len(row)} cells, the header "
                f"{len(header)} (truncated?)"
            )
        try:
            data.append([float(c) if c else np.nan for c in row])
        except ValueError:
            raise ValueError(
                f"{GENERATIONS_FILE} row {i + 1} holds a value that is not a number"
            ) from None
    return header, data


def load_run(path: Path, root: Path) -> RunData | RunProblem:
    """Reads and checks one run directory (see the module docstring)."""
    name = str(path.relative_to(root))
    try:
        config = load_config(path / CONFIG_FILE).resolved()
    except ConfigError as error:
        return RunProblem(name, f"{CONFIG_FILE} unusable: {error}")
    if not (path / GENERATIONS_FILE).is_file():
        return RunProblem(name, f"{GENERATIONS_FILE} is missing")
    try:
        header, data = _read_csv(path / GENERATIONS_FILE)
    except (OSError, ValueError, csv.Error) as error:
        return RunProblem(name, str(error))
    expected = config.resolved_generations
    if len(data) != expected:
        return RunProblem(
            name,
            f"truncated: {GENERATIONS_FILE} has {len(data)} of {expected} generations",
        )
    columns = {h: np.array([row[i] for row in data]) for i, h in enumerate(header)}
    if not np.array_equal(columns["generation"], np.arange(expected)):
        return RunProblem(
            name, f"{GENERATIONS_FILE} generations are not 0..{expected - 1}"
        )
    weight_names = tuple(
        h[len(WEIGHT_PREFIX) :] for h in header if h.startswith(WEIGHT_PREFIX)
    )
    sdbc_names = weight_names
    if expected and _individuals_path(path, 0).is_file():
        try:
            with np.load(_individuals_path(path, 0)) as npz:
                sdbc_names = tuple(str(n) for n in npz["sdbc_names"])
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            pass  # reported below, where every file is read
    try:
        length_index = sdbc_names.index(LENGTH_DIMENSION)
    except ValueError:
        return RunProblem(name, f"no {LENGTH_DIMENSION!r} SDBC dimension")
    trials = config.evaluation.trials
    fitness, steps = [], np.zeros(expected)
    for g in range(expected):
        file = _individuals_path(path, g)
        where = f"{INDIVIDUALS_DIR}/{file.name}"
        if not file.is_file():
            return RunProblem(name, f"{where} is missing")
        try:
            with np.load(file) as npz:
                f = np.asarray(npz["fitness"], dtype=np.float64)
                sdbc = np.asarray(npz["sdbc"])
        except (
            OSError,
            ValueError,
            KeyError,
            EOFError,
            zipfile.BadZipFile,
            zlib.error,
        ) as error:
            return RunProblem(
                name, f"{where} unreadable ({type(error).__name__}: {error})"
            )
        if f.ndim != 1 or sdbc.shape != (f.shape[0], len(sdbc_names)):
            return RunProblem(
                name,
                f"{where}: fitness {f.shape} and sdbc {sdbc.shape} do not fit "
                f"{len(sdbc_names)} SDBC dimensions",
            )
        if not np.isfinite(f).all():
            return RunProblem(name, f"{where}: fitness holds NaN or infinity")
        fitness.append(f)
        steps[g] = float(np.sum(sdbc[:, length_index], dtype=np.float64)) * trials
    champions = None
    if (path / CHAMPION_FILE).is_file():
        try:
            champions = ChampionSummary.of(read_champions(path))
        except ChampionError as error:
            return RunProblem(name, str(error))
    return RunData(
        name,
        path,
        config,
        columns,
        sdbc_names,
        fitness,
        steps,
        weight_names,
        champions,
    )


@dataclass
class StudyData:
    """The usable runs of a study directory and the problems found.

    Attributes:
        root: The study directory.
        runs: Usable runs.
        problems: Runs left out (unusable, or expected and absent).
        expected: Runs the study's preset expects (None without ``study.yaml``).
        order: The preset's treatments by name, in its order (empty without
            ``study.yaml``).
    """

    root: Path
    runs: list[RunData]
    problems: list[RunProblem]
    expected: int | None
    order: tuple[str, ...] = ()

    def tasks(self) -> list[str]:
        """Tasks with at least one usable run, the paper's first, in its order."""
        found = set(r.task for r in self.runs)
        known = [t for t in PAPER_TASKS if t in found]
        return known + sorted(found - set(known))

    def of(
        self, task: str, treatment: str | TreatmentSpec | None = None
    ) -> list[RunData]:
        """The usable runs of ``task`` (of one treatment, by name or spec)."""
        if isinstance(treatment, TreatmentSpec):
            treatment = treatment.name
        return [
            r
            for r in self.runs
            if r.task == task and (treatment is None or r.treatment == treatment)
        ]

    def treatments(self, task: str) -> list[str]:
        """Names of the treatments with usable runs on ``task``: in the preset's
        order, or else the paper's four in its order, then the others in the order
        their runs were found."""
        present = list(dict.fromkeys(r.treatment for r in self.of(task)))
        first = [t for t in (*self.order, *PAPER_TREATMENTS) if t in present]
        first = list(dict.fromkeys(first))
        return first + [t for t in present if t not in first]


def load_study(root: str | Path) -> StudyData:
    """Reads every run under ``root``; unusable and absent runs become problems."""
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"no study directory {root}")
    runs: list[RunData] = []
    problems: list[RunProblem] = []
    for path in find_runs(root):
        loaded = load_run(path, root)
        if isinstance(loaded, RunData):
            runs.append(loaded)
        else:
            problems.append(loaded)
    expected = None
    order: tuple[str, ...] = ()
    if (root / STUDY_FILE).is_file():
        try:
            preset = load_preset_file(root / STUDY_FILE)
        except PresetError as error:
            problems.append(RunProblem(STUDY_FILE, f"unreadable: {error}"))
        else:
            plan = study_plan(preset, root)
            expected = len(plan)
            order = tuple(t.name for t in preset.treatments)
            seen = {r.path.resolve() for r in runs} | {
                (root / p.name).resolve() for p in problems
            }
            if preset.champion_trials:
                unjudged = [r for r in runs if r.champions is None]
                runs = [r for r in runs if r.champions is not None]
                problems += [
                    RunProblem(
                        r.name,
                        f"{CHAMPION_FILE} missing: champions not re-evaluated yet",
                    )
                    for r in unjudged
                ]
            for spec in plan:
                if spec.path.resolve() not in seen:
                    problems.append(
                        RunProblem(str(spec.path.relative_to(root)), MISSING)
                    )
    if not runs:
        raise FileNotFoundError(
            f"no usable run under {root}"
            + "".join(f"\n  {p.name}: {p.reason}" for p in problems)
        )
    return StudyData(root, runs, problems, expected, order)

"""The output directory of an experiment: its layout, its writer and its readers.

The replication study and the analysis read this layout; it is kept stable::

    OUT/
      config.yaml           the resolved ExperimentConfig (every default filled in)
      generations.csv       one row per completed generation, columns below
      best_genomes.npy      (G, W) float64, row g = the best genome of generation g
                            (highest fitness, first index on ties)
      individuals/
        gen_00000.npz       every individual evaluated in generation 0, see below
        gen_00001.npz       ...
      checkpoint.npz        everything needed to resume after the last generation
                            (see ``sdbc_evolution.run.checkpoint``)

``generations.csv`` columns, in order:

- ``generation``: 0-based index;
- ``best_fitness``, ``mean_fitness``, ``median_fitness``: over the population;
- ``best_index``: the best individual's index in the generation;
- ``best_novelty``: the highest novelty score (empty for Fit);
- ``archive_size``: archive entries after this generation;
- ``reevaluated_fitness``: the best individual's fitness over
  ``evaluation.reevaluation_trials`` fresh trials, summed up like every fitness
  (harmonic mean by default); ``reevaluated_mean``: the arithmetic mean of those
  trials (both empty when re-evaluation is off) - the paper's curves;
- ``wall_time``: seconds the generation took up to writing its outputs (trials,
  scoring, breeding, re-evaluation; writing the outputs and the checkpoint comes
  after and is timed by ``bench/generation.py``); ``evaluation_time``: seconds of
  it spent waiting for the evaluator (trials and re-evaluation, with SDBC
  extraction, in whatever processes). With re-evaluation on, a generation's
  population is evaluated in one batch with the re-evaluation before it
  (``sdbc_evolution.run.experiment``, step 5), so these seconds are counted in
  the generation before: generation 0 holds two populations' trials and the
  last only its re-evaluation;
- ``weight:<dimension name>``, one per dimension of the weighted characterisation
  (the SDBC's for the paper's treatments): the weights in force, delta + relevance
  (for NS-SD+ the mutual information in bits; empty for unweighted treatments).

Floats are written with Python's ``repr`` (shortest exact round trip).

``individuals/gen_NNNNN.npz`` arrays, one row per individual in population order:

- ``fitness`` (N,) float64 and ``trial_fitness`` (N, T) float32;
- ``characterisation`` (N, C) float32: the task-specific characterisation;
- ``sdbc`` (N, D) float32: the raw (unstandardised) SDBC vector, mean over trials;
- ``sdbc_names`` (D,) str: the SDBC dimension names;
- ``novelty`` (N,) float64 (NaN for Fit); ``front`` (N,) int16; ``rank`` (N,) int32
  (position in the ranking order, 0 = best); ``archived`` (N,) bool;
- ``behaviour`` (N, D') float32 and ``behaviour_names`` (D',) str: only for a
  treatment whose characterisation is neither the task-specific one nor the paper's
  SDBC, its raw vectors;
- ``parent`` (N,) int32: index in the previous generation of the individual it was
  copied or mutated from (-1 in generation 0); ``elite`` (N,) bool: copied unchanged.

Float32 is all the analysis needs; the checkpoint keeps exact values for resuming.

Disk. An individuals file holds N (28 + 4T + 4C + 4D) bytes of arrays before
compression (fitness and novelty 8 bytes per individual, rank and parent 4, front
2, archived and elite 1: 28; then 4 per trial, per characterisation value and per
SDBC dimension), plus about 2 KB of archive headers and names; a test checks the
formula against a real file. At the paper's population 200 and 10 trials, with
C = 4 and D = 21 (gate escape, resource sharing) or 27 (predator-prey), that is
33.6 or 38.4 KB per generation before compression, one file each. The checkpoint
(uncompressed, rewritten every generation, one file) holds the next population,
N (8W + 9) bytes (W = 108, 75 or 47 weights: 77-175 KB at N = 200), and the
archive. So a 750-generation run writes at most 25-29 MB of individuals in 750
files, and the paper preset's 240 runs at most about 6.3 GB in 180,000 files;
the analysis reads every individuals file of every run.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sdbc_sim.limits import excerpt

from sdbc_evolution.run.system_errors import named

CONFIG_FILE = "config.yaml"
GENERATIONS_FILE = "generations.csv"
BEST_GENOMES_FILE = "best_genomes.npy"
INDIVIDUALS_DIR = "individuals"
CHECKPOINT_FILE = "checkpoint.npz"
WEIGHT_PREFIX = "weight:"

BASE_COLUMNS = (
    "generation",
    "best_fitness",
    "mean_fitness",
    "median_fitness",
    "best_index",
    "best_novelty",
    "archive_size",
    "reevaluated_fitness",
    "reevaluated_mean",
    "wall_time",
    "evaluation_time",
)
RESULT_FILE_MODE = 0o644
"""Permissions of every file written (readable by all, like a plain ``open``)."""
TIME_COLUMNS = ("wall_time", "evaluation_time")
"""Columns that differ between two otherwise identical runs."""


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Writes ``data`` to ``path`` through a temporary file and a rename, so a
    reader (or a crash) never sees half a file."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except OSError as error:
        raise named(error, path) from error
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        # mkstemp makes the file private; results are for whoever may read the dir.
        os.chmod(tmp, RESULT_FILE_MODE)
        os.replace(tmp, path)
    except OSError as error:
        Path(tmp).unlink(missing_ok=True)
        raise named(error, path) from error
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


ZIP_TIMESTAMP = (1980, 1, 1, 0, 0, 0)
"""Date of every entry of the ``.npz`` archives written here (the earliest a zip
holds): ``np.savez`` stamps entries with the current time, so the same arrays
would give different bytes, and a committed file would change on every rewrite."""


def npz_bytes(arrays: dict[str, np.ndarray], compress: bool = True) -> bytes:
    """The bytes of an ``.npz`` archive holding ``arrays``, which ``np.load`` reads
    like ``np.savez``'s; the same arrays always give the same bytes."""
    buffer = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(buffer, "w", compression=method) as archive:
        for name, value in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=ZIP_TIMESTAMP)
            info.compress_type = method
            with archive.open(info, "w", force_zip64=True) as entry:
                np.lib.format.write_array(entry, np.asanyarray(value))
    return buffer.getvalue()


@dataclass
class GenerationRecord:
    """One row of ``generations.csv``; see the module docstring for the fields."""

    generation: int
    best_fitness: float
    mean_fitness: float
    median_fitness: float
    best_index: int
    best_novelty: float
    archive_size: int
    reevaluated_fitness: float
    reevaluated_mean: float
    wall_time: float
    evaluation_time: float
    weights: np.ndarray | None

    def row(self, n_weights: int) -> list[str]:
        """CSV cells; NaN becomes an empty cell."""
        values: list[float | int] = [getattr(self, c) for c in BASE_COLUMNS]
        weights = (
            self.weights if self.weights is not None else np.full(n_weights, np.nan)
        )
        values += [float(w) for w in weights]
        return [_cell(v) for v in values]


def _cell(value: float | int) -> str:
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    value = float(value)
    return "" if math.isnan(value) else repr(value)


INDIVIDUALS_ARRAYS = (
    "fitness",
    "trial_fitness",
    "characterisation",
    "sdbc",
    "novelty",
    "front",
    "rank",
    "archived",
    "parent",
    "elite",
)
"""The per-individual arrays of an individuals file (besides ``sdbc_names``)."""


FINITE_ARRAYS = ("fitness", "trial_fitness", "characterisation", "sdbc")
"""Arrays of an individuals file that must be finite numbers (novelty is NaN
under Fit)."""


class RunDamaged(ValueError):
    """An output a run's checkpoint vouches for is missing or damaged."""


def load_npz(path: Path) -> np.lib.npyio.NpzFile:
    """Opens an ``.npz`` archive without pickles.

    Raises:
        ValueError: The file is not a zip archive (numpy would otherwise take it
            for a pickle and suggest loading it unsafely).
        OSError: It cannot be read.
    """
    if not zipfile.is_zipfile(path):
        if not Path(path).is_file():
            raise FileNotFoundError(f"{path}: no such file")
        raise ValueError(f"{path}: not an .npz archive")
    return np.load(path, allow_pickle=False)


def check_individuals(path: Path, population_size: int) -> None:
    """Reads every array of an individuals file (zip checksums included).

    Raises:
        RunDamaged: Missing, unreadable, or not of ``population_size`` rows.
    """
    try:
        with load_npz(path) as data:
            missing = sorted(set(INDIVIDUALS_ARRAYS) - set(data.files))
            if missing:
                raise RunDamaged(f"{path}: missing arrays {missing}")
            for name in INDIVIDUALS_ARRAYS:
                array = data[name]
                rows = array.shape[:1]
                if rows != (population_size,):
                    raise RunDamaged(
                        f"{path}: {name} has {rows[0] if rows else 0} rows, the run's "
                        f"population is {population_size}"
                    )
                if name in FINITE_ARRAYS and not (
                    array.dtype.kind == "f" and np.isfinite(array).all()
                ):
                    raise RunDamaged(f"{path}: {name} holds NaN, infinity or no number")
    except RunDamaged:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:
        detail = str(error) if str(path) in str(error) else f"{path}: {error}"
        raise RunDamaged(detail) from None


class ResultsDirectory:
    """Reads and writes one experiment's output directory.

    Args:
        path: The directory.
        sdbc_names: Names of the SDBC dimensions.
        weight_names: Names of the weighted dimensions (the weight columns); by
            default the SDBC's.
    """

    def __init__(
        self,
        path: str | Path,
        sdbc_names: tuple[str, ...],
        weight_names: tuple[str, ...] | None = None,
    ) -> None:
        self.path = Path(path)
        self.sdbc_names = tuple(sdbc_names)
        self.weight_names = (
            self.sdbc_names if weight_names is None else tuple(weight_names)
        )

    @property
    def columns(self) -> tuple[str, ...]:
        """Header of ``generations.csv``."""
        return BASE_COLUMNS + tuple(WEIGHT_PREFIX + n for n in self.weight_names)

    @property
    def checkpoint_path(self) -> Path:
        """The run's checkpoint file."""
        return self.path / CHECKPOINT_FILE

    def individuals_path(self, generation: int) -> Path:
        """The file of every individual of ``generation``."""
        return self.path / INDIVIDUALS_DIR / f"gen_{generation:05d}.npz"

    def holds_a_run(self) -> bool:
        """True if the directory holds something of a run: a checkpoint (a run
        writes one at generation 0), an individuals file or a generation's row.
        A configuration and an empty ``generations.csv`` alone, as older versions
        left a run stopped before its first generation, are not a run."""
        individuals = self.path / INDIVIDUALS_DIR
        return (
            (self.path / CHECKPOINT_FILE).exists()
            or (individuals.is_dir() and any(individuals.iterdir()))
            or _has_data_rows(self.path / GENERATIONS_FILE)
        )

    def create(self, config_yaml: str) -> None:
        """Prepares an empty directory for a new run."""
        (self.path / INDIVIDUALS_DIR).mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(self.path / CONFIG_FILE, config_yaml.encode())
        self._write_rows([])
        atomic_write_bytes(self.path / BEST_GENOMES_FILE, _npy_bytes(np.zeros((0, 0))))

    def write_config(self, config_yaml: str) -> None:
        """Writes the run's resolved configuration (YAML), atomically."""
        atomic_write_bytes(self.path / CONFIG_FILE, config_yaml.encode())

    def append_generation(
        self,
        record: GenerationRecord,
        individuals: dict[str, np.ndarray],
        best_genome: np.ndarray,
    ) -> None:
        """Writes one generation's outputs (the checkpoint comes after).

        Raises:
            RuntimeError: ``generations.csv`` does not hold exactly the rows of the
                generations before this one: another writer got in (the run's
                lock should make that impossible), so nothing is written.
        """
        rows = len(self.read_rows())
        if rows != record.generation:
            raise RuntimeError(
                f"{self.path / GENERATIONS_FILE} holds {rows} generations before "
                f"generation {record.generation}: another process wrote to this run"
            )
        atomic_write_bytes(
            self.individuals_path(record.generation),
            npz_bytes({**individuals, "sdbc_names": np.array(self.sdbc_names)}),
        )
        try:
            with open(self.path / GENERATIONS_FILE, "a", newline="") as f:
                csv.writer(f).writerow(record.row(len(self.weight_names)))
                f.flush()
                os.fsync(f.fileno())
        except OSError as error:
            raise named(error, self.path / GENERATIONS_FILE) from error
        best = self.best_genomes()
        if best.size == 0:
            best = np.zeros((0, best_genome.shape[0]))
        if best.shape[0] != record.generation:
            raise RuntimeError(
                f"{BEST_GENOMES_FILE} holds {best.shape[0]} rows before generation "
                f"{record.generation}"
            )
        atomic_write_bytes(
            self.path / BEST_GENOMES_FILE,
            _npy_bytes(np.concatenate([best, best_genome[None]])),
        )

    def verify(self, generations: int, population_size: int) -> None:
        """Checks that every output of generations ``0 .. generations - 1`` (what a
        checkpoint after them vouches for) is there and whole: their rows of
        ``generations.csv``, in order; their rows of ``best_genomes.npy``; and
        each individuals file, a readable archive of ``population_size`` rows.
        Outputs of later generations are not checked (resuming drops them).

        Raises:
            RunDamaged: Naming the first damaged file and what is wrong with it.
        """
        try:
            rows = self.read_rows()
        except (OSError, ValueError, csv.Error) as error:
            raise RunDamaged(f"{self.path / GENERATIONS_FILE}: {error}") from None
        numbers = [r[0] if r else "" for r in rows[:generations]]
        if numbers != [str(g) for g in range(generations)]:
            raise RunDamaged(
                f"{self.path / GENERATIONS_FILE}: generations {_listed(numbers)} "
                f"where the checkpoint needs 0 to {generations - 1}"
            )
        for g, row in enumerate(rows[:generations]):
            problem = _row_problem(row, self.columns)
            if problem is not None:
                raise RunDamaged(
                    f"{self.path / GENERATIONS_FILE}: the row of generation {g} "
                    f"{problem}"
                )
        try:
            best = np.load(self.path / BEST_GENOMES_FILE, allow_pickle=False)
        except (OSError, ValueError, EOFError) as error:
            raise RunDamaged(f"{self.path / BEST_GENOMES_FILE}: {error}") from None
        if generations and (best.ndim != 2 or best.shape[0] < generations):
            raise RunDamaged(
                f"{self.path / BEST_GENOMES_FILE}: shape {best.shape}, the "
                f"checkpoint needs {generations} rows"
            )
        for g in range(generations):
            check_individuals(self.individuals_path(g), population_size)

    def truncate(self, generations: int) -> None:
        """Drops every output of generation ``generations`` and later (left by a run
        stopped between writing a generation and its checkpoint), and the
        temporary files of writes that were killed (:meth:`remove_leftovers`)."""
        self.remove_leftovers()
        rows = self.read_rows()
        if len(rows) < generations:
            raise ValueError(
                f"{self.path / GENERATIONS_FILE} has {len(rows)} generations, the "
                f"checkpoint {generations}: the directory is incomplete"
            )
        self._write_rows(rows[:generations])
        best = self.best_genomes()
        if best.shape[0] < generations:
            raise ValueError(
                f"{self.path / BEST_GENOMES_FILE} has {best.shape[0]} rows, the "
                f"checkpoint {generations} generations: the directory is incomplete"
            )
        atomic_write_bytes(
            self.path / BEST_GENOMES_FILE, _npy_bytes(best[:generations])
        )
        for path in sorted((self.path / INDIVIDUALS_DIR).glob("gen_*.npz")):
            if int(path.stem.split("_")[1]) >= generations:
                path.unlink()

    def remove_leftovers(self) -> list[Path]:
        """Removes the temporary files :func:`atomic_write_bytes` leaves when its
        process is killed mid-write (``.checkpoint.npz.XXXXXXXX``, ...): those of
        this directory's own files and of its individuals files. Only for the
        holder of the run's lock, so that no write is going on. Returns them."""
        removed = []
        for folder in (self.path, self.path / INDIVIDUALS_DIR):
            if not folder.is_dir():
                continue
            for path in folder.iterdir():
                match = _TEMPORARY.fullmatch(path.name)
                if match is None or not path.is_file():
                    continue
                name = match.group(1)
                if name in _OWN_FILES or _INDIVIDUALS_FILE.fullmatch(name):
                    path.unlink(missing_ok=True)
                    removed.append(path)
        return removed

    def read_rows(self) -> list[list[str]]:
        """Data rows of ``generations.csv`` as strings (the header checked)."""
        with open(self.path / GENERATIONS_FILE, newline="") as f:
            rows = list(csv.reader(f))
        if not rows or tuple(rows[0]) != self.columns:
            raise ValueError(
                f"{self.path / GENERATIONS_FILE}: header does not match this run"
            )
        return rows[1:]

    def best_genomes(self) -> np.ndarray:
        """(generations, W) the best genome of every generation written so far."""
        return np.load(self.path / BEST_GENOMES_FILE)

    def _write_rows(self, rows: list[list[str]]) -> None:
        buffer = io.StringIO()
        writer = csv.writer(buffer)
        writer.writerow(self.columns)
        writer.writerows(rows)
        atomic_write_bytes(self.path / GENERATIONS_FILE, buffer.getvalue().encode())


_TEMPORARY = re.compile(r"\.(.+)\.[a-z0-9_]{8}")
"""A temporary file of :func:`atomic_write_bytes` (``tempfile.mkstemp``'s
eight random characters after the target's name)."""
_INDIVIDUALS_FILE = re.compile(r"gen_\d{5}\.npz")
_OWN_FILES = (
    CONFIG_FILE,
    GENERATIONS_FILE,
    BEST_GENOMES_FILE,
    CHECKPOINT_FILE,
    "study_run.json",
)
"""Files a run directory's writers write atomically (``study_run.json``: the
study's record of how a run was executed)."""
INTEGER_COLUMNS = ("generation", "best_index", "archive_size")
"""Columns of ``generations.csv`` holding a count or an index."""
OPTIONAL_COLUMNS = ("best_novelty", "reevaluated_fitness", "reevaluated_mean")
"""Columns that may be empty (NaN): novelty under Fit, re-evaluation turned off;
the weight columns too (unweighted treatments)."""


def _row_problem(row: list[str], columns: tuple[str, ...]) -> str | None:
    """What is wrong with one data row of ``generations.csv``, or None: every cell
    there, integers where counts go, finite numbers everywhere else (empty only
    in :data:`OPTIONAL_COLUMNS` and the weight columns)."""
    if len(row) != len(columns):
        return f"has {len(row)} cells, the header {len(columns)} (truncated?)"
    for name, cell in zip(columns, row, strict=True):
        optional = name in OPTIONAL_COLUMNS or name.startswith(WEIGHT_PREFIX)
        if cell == "" and optional:
            continue
        try:
            value = int(cell) if name in INTEGER_COLUMNS else float(cell)
        except ValueError:
            return f"holds {excerpt(cell)} in {name}, not a number"
        if not math.isfinite(value) or (name in INTEGER_COLUMNS and value < 0):
            return f"holds {excerpt(cell)} in {name}"
    return None


def _listed(numbers: list[str]) -> str:
    shown = ", ".join(numbers[:6]) + (", ..." if len(numbers) > 6 else "")
    return f"[{shown}] ({len(numbers)} rows)"


def _has_data_rows(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            return sum(1 for line in f if line.strip()) > 1
    except FileNotFoundError:
        return False


def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def read_generations(path: str | Path) -> dict[str, np.ndarray]:
    """``generations.csv`` of a run as columns of floats (empty cells are NaN)."""
    with open(Path(path) / GENERATIONS_FILE, newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], rows[1:]
    return {
        name: np.array([float(r[i]) if r[i] else np.nan for r in data])
        for i, name in enumerate(header)
    }


def read_individuals(path: str | Path) -> dict[str, np.ndarray]:
    """Every individual of a run, generations stacked (N x G rows), with a
    ``generation`` column added."""
    files = sorted((Path(path) / INDIVIDUALS_DIR).glob("gen_*.npz"))
    if not files:
        raise FileNotFoundError(f"no individuals in {Path(path) / INDIVIDUALS_DIR}")
    parts: dict[str, list[np.ndarray]] = {}
    names: np.ndarray | None = None
    for file in files:
        with np.load(file) as data:
            generation = int(file.stem.split("_")[1])
            n = data["fitness"].shape[0]
            for key in data.files:
                if key == "sdbc_names":
                    names = data[key]
                    continue
                parts.setdefault(key, []).append(data[key])
            parts.setdefault("generation", []).append(np.full(n, generation))
    out = {key: np.concatenate(values) for key, values in parts.items()}
    if names is not None:
        out["sdbc_names"] = names
    return out

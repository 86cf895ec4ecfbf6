"""Checkpoints: the complete state of a run between two generations.

A run is a function of (configuration, seed); the state after generation g-1 that
determines everything from generation g on is: the population to evaluate next (and
where each member came from), the novelty archive, the NS-SD+ weights in force, and
the states of the run's two random generators (the GA's, and the one that seeds
re-evaluation trials). :func:`save_checkpoint` writes these atomically (temporary file
and rename) to ``checkpoint.npz``: arrays as arrays, the rest as one JSON document,
with the configuration the run was started with.

:func:`load_checkpoint` refuses, with a :class:`CheckpointError` that says why, a
file that is not a checkpoint (truncated, corrupt, another format version), one from
another task, or one whose configuration differs from the resuming run's in anything
but ``generations`` (extending a finished run is allowed). It only reads: nothing in
the output directory changes unless the checkpoint is accepted.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

# The generators a checkpoint may name: the ask/tell object's (re-exported).
from sdbc_evolution.ga.search import BIT_GENERATORS as BIT_GENERATORS
from sdbc_evolution.ga.search import generator_from_state as restored_generator
from sdbc_evolution.run.results import atomic_write_bytes, load_npz, npz_bytes

FORMAT_VERSION = 1
"""Bumped whenever the checkpoint's content changes meaning."""

RESUMABLE_CHANGES = ("generations",)
"""Configuration keys a resumed run may change."""

_ARRAYS = (
    "population",
    "parent",
    "elite",
    "archive_behaviours",
    "archive_fitness",
    "archive_generation",
    "weights",
)


class CheckpointError(ValueError):
    """A checkpoint that cannot be resumed; the message says why."""


@dataclass
class Checkpoint:
    """The state of a run before generation ``generation``.

    Attributes:
        generation: Generations completed (the next one to run).
        config: The run's resolved configuration as plain data.
        population: (N, W) genomes to evaluate in ``generation``.
        parent: (N,) index in the previous generation each came from (-1: none).
        elite: (N,) bool, copied unchanged from the previous generation.
        archive_behaviours: (A, D) raw behaviour vectors of the archive.
        archive_fitness: (A,) their fitness.
        archive_generation: (A,) the generation each entered.
        weights: (D,) NS-SD+ weights in force, or None.
        ga_rng: ``bit_generator.state`` of the GA's generator.
        reevaluation_rng: ``bit_generator.state`` of the re-evaluation generator.
    """

    generation: int
    config: dict[str, Any]
    population: np.ndarray
    parent: np.ndarray
    elite: np.ndarray
    archive_behaviours: np.ndarray
    archive_fitness: np.ndarray
    archive_generation: np.ndarray
    weights: np.ndarray | None
    ga_rng: dict[str, Any]
    reevaluation_rng: dict[str, Any]


def save_checkpoint(path: str | Path, checkpoint: Checkpoint) -> None:
    """Writes ``checkpoint`` to ``path`` atomically."""
    meta = {
        "format_version": FORMAT_VERSION,
        "generation": checkpoint.generation,
        "config": checkpoint.config,
        "ga_rng": checkpoint.ga_rng,
        "reevaluation_rng": checkpoint.reevaluation_rng,
        "has_weights": checkpoint.weights is not None,
    }
    arrays = {name: np.asarray(getattr(checkpoint, name)) for name in _ARRAYS[:-1]}
    arrays["weights"] = (
        np.zeros(0) if checkpoint.weights is None else np.asarray(checkpoint.weights)
    )
    arrays["meta"] = np.array(json.dumps(meta))
    # Uncompressed: a checkpoint is small and written every generation.
    atomic_write_bytes(Path(path), npz_bytes(arrays, compress=False))


def load_checkpoint(path: str | Path, config: dict[str, Any]) -> Checkpoint:
    """Reads and validates the checkpoint at ``path`` for a run with ``config``.

    Args:
        path: The checkpoint file.
        config: The resuming run's resolved configuration as plain data.

    Raises:
        CheckpointError: Missing, unreadable or corrupt file; another format
            version; another task; another configuration.
    """
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint at {path}: nothing to resume")
    try:
        with load_npz(path) as data:
            missing = sorted(set(_ARRAYS + ("meta",)) - set(data.files))
            if missing:
                raise CheckpointError(f"corrupt checkpoint {path}: missing {missing}")
            arrays = {name: data[name] for name in _ARRAYS}
            meta = json.loads(str(data["meta"]))
    except CheckpointError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as error:
        detail = str(error).removeprefix(f"{path}: ")
        raise CheckpointError(f"corrupt checkpoint {path}: {detail}") from None
    if not isinstance(meta, dict) or meta.get("format_version") != FORMAT_VERSION:
        version = meta.get("format_version") if isinstance(meta, dict) else None
        raise CheckpointError(
            f"checkpoint {path} has format version {version!r}; this code reads "
            f"version {FORMAT_VERSION}"
        )
    try:
        saved = meta["config"]
        generation = int(meta["generation"])
        ga_rng, reevaluation_rng = meta["ga_rng"], meta["reevaluation_rng"]
        has_weights = bool(meta["has_weights"])
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(
            f"corrupt checkpoint {path}: bad metadata ({error})"
        ) from None
    if saved.get("task") != config.get("task"):
        raise CheckpointError(
            f"checkpoint {path} is from task {saved.get('task')!r}, this run is task "
            f"{config.get('task')!r}"
        )
    differences = config_differences(_as_loaded_now(saved), config)
    if differences:
        listed = "; ".join(
            f"{key}: {old!r} in the checkpoint, {new!r} now"
            for key, old, new in differences[:5]
        )
        raise CheckpointError(
            f"checkpoint {path} was made with a different configuration ({listed})"
        )
    weights = arrays.pop("weights")
    checkpoint = Checkpoint(
        generation=generation,
        config=saved,
        weights=weights if has_weights else None,
        ga_rng=ga_rng,
        reevaluation_rng=reevaluation_rng,
        **arrays,
    )
    _check_shapes(path, checkpoint)
    return checkpoint


def _as_loaded_now(saved: dict[str, Any]) -> dict[str, Any]:
    """A checkpoint's configuration as this code reads it: a setting added since
    the checkpoint was written takes its default, so adding one with the old
    behaviour as default leaves every run resumable. Left as it is if it no
    longer loads (a setting since removed), so the difference is named."""
    from sdbc_evolution.run.config import ConfigError, config_from_dict

    try:
        return config_from_dict(saved).resolved().to_dict()
    except (ConfigError, TypeError, ValueError):
        return saved


def config_differences(
    saved: dict[str, Any], current: dict[str, Any], prefix: str = ""
) -> list[tuple[str, Any, Any]]:
    """Keys whose values differ between two plain configurations (dotted paths),
    ignoring :data:`RESUMABLE_CHANGES`."""
    out = []
    for key in sorted(set(saved) | set(current)):
        dotted = f"{prefix}{key}"
        if dotted in RESUMABLE_CHANGES:
            continue
        a, b = saved.get(key), current.get(key)
        if isinstance(a, dict) and isinstance(b, dict) and key != "task_config":
            out += config_differences(a, b, prefix=f"{dotted}.")
        elif a != b:
            out.append((dotted, a, b))
    return out


def _check_shapes(path: Path, c: Checkpoint) -> None:
    n = c.population.shape[0] if c.population.ndim == 2 else -1
    a = c.archive_behaviours.shape[0] if c.archive_behaviours.ndim == 2 else -1
    ok = (
        n >= 0
        and c.generation >= 0
        and c.parent.shape == (n,)
        and c.elite.shape == (n,)
        and a >= 0
        and c.archive_fitness.shape == (a,)
        and c.archive_generation.shape == (a,)
        and np.isfinite(c.population).all()
        and (c.weights is None or c.weights.ndim == 1)
    )
    if not ok:
        raise CheckpointError(f"corrupt checkpoint {path}: inconsistent arrays")


def generator_from_state(state: dict[str, Any]) -> np.random.Generator:
    """A generator restored to a saved ``bit_generator.state``."""
    try:
        return restored_generator(state)
    except ValueError as error:
        raise CheckpointError(
            f"corrupt generator state in checkpoint: {error}"
        ) from None

"""One study from parts analysed apart: the tasks of one preset run in different
study directories (different sessions, machines or cluster jobs), each reduced to
its digest, then analysed together.

A part is a :class:`~sdbc_evolution.study.digest.StudyDigest`. Parts combine when
they are of one preset (same name, seed and description), their maps were made
with the same SOM settings, and no task is in two of them: a task's runs are
compared and mapped together, so a task is never split across parts. The
combined digest keeps every part's sessions (so the report lists every command
that made a run) and the runs each part left out, except the runs of a task that
another part provides (a part that ran one task of a preset lists the others'
runs as missing).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from pathlib import PurePosixPath

from sdbc_evolution.study.digest import DigestError, StudyDigest, TaskDigest
from sdbc_evolution.study.paper import PAPER_TASKS


def _unique(sessions: Iterable[dict]) -> tuple[dict, ...]:
    """``sessions`` in their order, each once: a later task run in the same study
    directory as a committed part has that part's sessions in its log too."""
    seen: set[str] = set()
    kept = []
    for session in sessions:
        key = json.dumps(session, sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            kept.append(session)
    return tuple(kept)


def _task_of_problem(name: str) -> str | None:
    """The task of a left-out run (its path's first folder), None for a problem of
    the study itself (e.g. an unreadable ``study.yaml``)."""
    parts = PurePosixPath(name).parts
    return parts[0] if len(parts) > 1 else None


def combine_digests(
    parts: Sequence[tuple[str, StudyDigest]], command: Sequence[str] = ()
) -> StudyDigest:
    """The study made of ``parts``, each ``(label, digest)``; the label names the
    part in errors (e.g. its folder).

    Raises:
        DigestError: No part, parts of different presets or SOM settings, a part
            whose preset could not be read, or a task in two parts.
    """
    if not parts:
        raise DigestError("nothing to combine: give at least one study or digest")
    first_label, first = parts[0]
    owner: dict[str, str] = {}
    by_task: dict[str, TaskDigest] = {}
    for label, part in parts:
        if part.preset_error is not None:
            raise DigestError(
                f"{label}: its preset was unreadable ({part.preset_error}); "
                "parts combine only when each names its preset"
            )
        if part.preset != first.preset:
            raise DigestError(
                f"{label} is of preset {part.preset}, {first_label} of "
                f"{first.preset}: only parts of one preset combine"
            )
        if part.expected != first.expected:
            raise DigestError(
                f"{label} expects {part.expected} runs, {first_label} "
                f"{first.expected}: the parts were planned differently"
            )
        for task in part.task_digests:
            if task.task in owner:
                raise DigestError(
                    f"task {task.task} is in both {owner[task.task]} and {label}: "
                    "a task's runs must come from one part"
                )
            owner[task.task] = label
            by_task[task.task] = task
    soms = {t.maps.settings for t in by_task.values()}
    if len(soms) > 1:
        raise DigestError(
            "the parts' maps were made with different SOM settings: "
            + "; ".join(sorted(str(s) for s in soms))
        )
    known = [t for t in PAPER_TASKS if t in by_task]
    order = known + [t for t in by_task if t not in known]
    problems = tuple(
        p
        for label, part in parts
        for p in part.problems
        if owner.get(_task_of_problem(p.name) or "", label) == label
    )
    labels = list(dict.fromkeys(part.study_dir for _, part in parts))
    return StudyDigest(
        study_dir=" + ".join(labels),
        task_digests=tuple(by_task[t] for t in order),
        problems=problems,
        expected=first.expected,
        sessions=_unique(s for _, part in parts for s in part.sessions),
        preset=first.preset,
        preset_error=None,
        command=tuple(command),
    )

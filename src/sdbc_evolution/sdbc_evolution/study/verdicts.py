"""The paper's claims in several studies at once, under the same rules, with the
declared cause of every disagreement.

Reads each analysis's ``tables/claims.csv`` (:mod:`.compare` reads it too) and
writes a Markdown page: per study its verdict counts (a test counted once, as the
reports count), over all its claims and over the tasks every study ran; then, task
by task, one row per claim with each study's verdict (and A with its interval
where the claim rests on a test), "not run" where a study has no such task (a
study analysed from a digest of some tasks only), and the cause of a
disagreement.

A **disagreement** is a study's verdict against the paper's claim. Its cause is
the researcher's reading, not something the numbers say, so it comes from one
reviewed YAML file (:func:`read_causes`): a claim's statement, as the reports
word it, maps to ``cause`` (the explanation) and, where an experiment tested
that explanation, ``tested`` (the experiment or study that did). The page marks
each cause *tested: <experiment>* or *untested*, and every disagreement without
a declared cause is listed (and named on stderr by ``sdbc-study verdicts``), so
that none is left unexplained by accident.

Every table must come from today's rules (:mod:`.claims`: Holm within a task's
family, equivalence and non-inferiority by a margin): a claims table without the
Holm p, A's interval and the statistic used is refused, since its verdicts are of
the rules before them. The committed reports are made again from their digests by
today's code (``tests/sdbc_evolution/study/test_study_digest.py``).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from sdbc_evolution.study.claims import Verdict
from sdbc_evolution.study.compare import (
    CLAIMS_TABLE,
    ClaimRow,
    CompareError,
    read_claims,
    read_mapping,
    verdict_counts,
)
from sdbc_evolution.study.paper import PAPER_TASKS, task_title
from sdbc_evolution.study.report import markdown_cell, markdown_table

RULE_COLUMNS = ("p_holm", "A", "A_low", "A_high", "statistic")
"""Columns a claims table of today's rules has beside the earlier ones."""
CAUSE_KEYS = frozenset({"cause", "tested"})
"""The keys of one claim's entry in the causes file."""
NOT_RUN = "not run"
"""A study's cell for a task it did not run."""
NOT_JUDGED = "not judged"
"""A study's cell for a claim it has no test for on a task it ran (a study of
some treatments only)."""


@dataclass(frozen=True)
class StudyClaims:
    """One analysed study's claims, by statement.

    Attributes:
        name: What the page calls the study.
        rows: Its claims, in its table's order.
        effects: Per statement, "A = a [low, high]" where the claim rests on a
            test.
    """

    name: str
    rows: tuple[ClaimRow, ...]
    effects: dict[str, str]

    @property
    def tasks(self) -> list[str]:
        """Its tasks, in its table's order."""
        return list(dict.fromkeys(r.task for r in self.rows))

    def verdict(self, statement: str) -> ClaimRow | None:
        """Its claim ``statement`` (None: not among its claims)."""
        for row in self.rows:
            if row.statement == statement:
                return row
        return None


@dataclass(frozen=True)
class Cause:
    """Why a claim disagrees, as declared.

    Attributes:
        cause: The explanation.
        tested: The experiment (or study) that tested it; None: untested.
    """

    cause: str
    tested: str | None

    @property
    def text(self) -> str:
        """The cause as the page gives it."""
        status = "untested" if self.tested is None else f"tested: {self.tested}"
        return f"*{status}*: {self.cause}"


def _effect(row: dict[str, str]) -> str:
    try:
        a, low, high = (float(row[k]) for k in ("A", "A_low", "A_high"))
    except ValueError:  # a claim with no test: empty cells
        return ""
    if not all(math.isfinite(x) for x in (a, low, high)):
        return ""
    return f"A = {a:.2f} [{low:.2f}, {high:.2f}]"


def read_study(analysis_dir: str | Path, name: str) -> StudyClaims:
    """The claims of the analysis in ``analysis_dir``, called ``name``.

    Raises:
        CompareError: The table is missing, not a claims table, or of the rules
            before today's (no Holm p, A's interval or statistic).
    """
    path = Path(analysis_dir) / CLAIMS_TABLE
    rows = read_claims(analysis_dir)
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in RULE_COLUMNS if c not in (reader.fieldnames or ())]
        if missing:
            raise CompareError(
                f"{path}: no {', '.join(missing)}: judged by the rules before "
                "today's; analyse the study again (sdbc-study analyse "
                "--from-digest DIR)"
            )
        effects = {r["claim"]: _effect(r) for r in reader}
    return StudyClaims(name, tuple(rows), effects)


def read_causes(path: str | Path) -> dict[str, Cause]:
    """The declared causes of disagreements: a YAML mapping from a claim's
    statement to ``{cause: text, tested: experiment}`` (``tested`` left out:
    untested).

    Raises:
        CompareError: Not such a mapping.
    """
    path = Path(path)
    data = read_mapping(path, "causes")
    causes = {}
    for statement, entry in data.items():
        where = f"{path}: {statement!r}"
        if not isinstance(statement, str) or not isinstance(entry, dict):
            raise CompareError(f"{where}: must map to {{cause: ..., tested: ...}}")
        unknown = sorted(set(entry) - CAUSE_KEYS)
        if unknown:
            raise CompareError(
                f"{where}: unknown key(s) {', '.join(map(str, unknown))} "
                f"(known: {', '.join(sorted(CAUSE_KEYS))})"
            )
        cause, tested = entry.get("cause"), entry.get("tested")
        if not isinstance(cause, str) or not cause.strip():
            raise CompareError(f"{where}: 'cause' must be a text")
        if tested is not None and (not isinstance(tested, str) or not tested.strip()):
            raise CompareError(f"{where}: 'tested' must name an experiment")
        causes[statement] = Cause(
            " ".join(cause.split()),
            None if tested is None else " ".join(tested.split()),
        )
    return causes


def _counts(rows: Sequence[ClaimRow]) -> list[str]:
    counts, _ = verdict_counts(rows)
    return [str(len(rows))] + [str(counts[v]) for v in Verdict]


@dataclass(frozen=True)
class Disagreement:
    """A claim some studies disagree with."""

    statement: str
    task: str
    studies: tuple[str, ...]
    cause: Cause | None


def disagreements(
    studies: Sequence[StudyClaims], causes: dict[str, Cause]
) -> list[Disagreement]:
    """Every claim with a "disagree" verdict in some study, in the order of the
    claims (:func:`claim_order`)."""
    found = []
    for task, statement in claim_order(studies):
        against = tuple(
            s.name
            for s in studies
            if (row := s.verdict(statement)) is not None
            and row.verdict is Verdict.DISAGREE
        )
        if against:
            found.append(Disagreement(statement, task, against, causes.get(statement)))
    return found


def claim_order(studies: Sequence[StudyClaims]) -> list[tuple[str, str]]:
    """(task, statement) of every claim of any study: the paper's tasks first,
    each task's claims in the order the studies list them."""
    seen: dict[str, str] = {}
    for study in studies:
        for row in study.rows:
            seen.setdefault(row.statement, row.task)
    tasks = list(dict.fromkeys(seen.values()))
    order = [t for t in PAPER_TASKS if t in tasks] + [
        t for t in tasks if t not in PAPER_TASKS
    ]
    return [(t, s) for t in order for s, task in seen.items() if task == t]


def verdicts_of(studies: Sequence[StudyClaims], statement: str) -> set[Verdict]:
    """The verdicts the studies that judged ``statement`` gave it."""
    return {row.verdict for s in studies if (row := s.verdict(statement)) is not None}


def _cell(study: StudyClaims, statement: str, task: str) -> str:
    row = study.verdict(statement)
    if row is None:
        return NOT_RUN if task not in study.tasks else NOT_JUDGED
    word = row.verdict.value
    if row.verdict is Verdict.DISAGREE:
        word = f"**{word}**"
    effect = study.effects.get(statement, "")
    return f"{word}, {effect}" if effect else word


def verdicts_page(
    studies: Sequence[StudyClaims],
    causes: dict[str, Cause],
    causes_name: str = "the causes file",
) -> tuple[str, list[Disagreement]]:
    """The Markdown page, and the disagreements it lists."""
    if len(studies) < 2:
        raise CompareError("verdicts sets at least two studies side by side")
    names = [s.name for s in studies]
    if len(set(names)) < len(names):
        raise CompareError(f"two studies with one name: {names}")
    shared = [t for t in studies[0].tasks if all(t in s.tasks for s in studies)]
    found = disagreements(studies, causes)
    header = ["study", "tasks", "claims", *(v.value for v in Verdict)]
    lines = [
        f"# The paper's claims in {len(studies)} studies, under the same rules",
        "",
        "Each study's verdicts as its report gives them (its tables/claims.csv, "
        "made by today's rules: Holm within each task's family, 'no difference' "
        "and 'not below' by the margin on A's interval); a test counted once.",
        "",
    ]
    lines += markdown_table(
        header,
        [
            [s.name, ", ".join(task_title(t) for t in s.tasks), *_counts(s.rows)]
            for s in studies
        ],
    )
    if any(s.tasks != shared for s in studies):
        lines += [
            "On the tasks every study ran ("
            + (", ".join(task_title(t) for t in shared) or "none")
            + "):",
            "",
        ]
        lines += markdown_table(
            header,
            [
                [
                    s.name,
                    ", ".join(task_title(t) for t in shared),
                    *_counts([r for r in s.rows if r.task in shared]),
                ]
                for s in studies
            ],
        )
    tested = sum(d.cause is not None and d.cause.tested is not None for d in found)
    untested = sum(d.cause is not None and d.cause.tested is None for d in found)
    order = claim_order(studies)
    differing = [s for _, s in order if len(verdicts_of(studies, s)) > 1]
    lines += [
        f"Claims some study disagrees with: {len(found)}; their causes, declared "
        f"in {causes_name}: {tested} tested by an experiment, {untested} untested, "
        f"{len(found) - tested - untested} not declared. Claims whose verdict "
        f"differs between the studies that judged them: {len(differing)} (the "
        "column gives a declared cause for these too where there is one; the "
        "studies' comparison pages explain the changes between two of them).",
        "",
    ]
    by_statement = {d.statement: d for d in found}
    for task in dict.fromkeys(t for t, _ in order):
        lines += [f"## {task_title(task)[0].upper()}{task_title(task)[1:]}", ""]
        rows = []
        for t, statement in order:
            if t != task:
                continue
            declared = causes.get(statement)
            cause = (
                declared.text
                if declared is not None
                else "(no cause declared)"
                if statement in by_statement
                else ""
            )
            rows.append(
                [markdown_cell(statement)]
                + [markdown_cell(_cell(s, statement, task)) for s in studies]
                + [markdown_cell(cause)]
            )
        lines += markdown_table(["claim", *names, "cause of a disagreement"], rows)
    return "\n".join(lines), found

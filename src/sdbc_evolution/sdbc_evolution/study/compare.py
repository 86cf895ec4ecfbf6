"""Two analyses of the paper's claims side by side: what changed between an earlier
study and a later one (another engine, other settings, more runs).

Reads each analysis's ``tables/claims.csv`` (written by :mod:`.analysis`, the same
bytes from a digest as from the run directories) and writes a Markdown page: the
verdict counts of both, over all their claims and over the tasks both ran, and one
row per claim whose verdict changed, with both studies' evidence. Why a verdict
changed is the researcher's reading, not something the numbers say: it comes from
a YAML file mapping a claim's statement to its explanation, and every changed
verdict without one is reported, so that none goes unexplained by accident.
"""

from __future__ import annotations

import csv
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sdbc_sim.yaml_input import YamlRefused, read_yaml

from sdbc_evolution.study.claims import Verdict
from sdbc_evolution.study.paper import task_title
from sdbc_evolution.study.report import markdown_cell, markdown_table

CLAIMS_TABLE = Path("tables") / "claims.csv"
COLUMNS = ("topic", "task", "claim", "paper", "ours", "p", "verdict")


class CompareError(ValueError):
    """Input that cannot be compared: the message names the file and the problem."""


@dataclass(frozen=True)
class ClaimRow:
    """One claim as an analysis judged it."""

    topic: str
    task: str
    statement: str
    ours: str
    verdict: Verdict


@dataclass(frozen=True)
class Change:
    """A claim whose verdict differs between the two studies."""

    before: ClaimRow
    after: ClaimRow
    why: str | None


def read_claims(analysis_dir: str | Path) -> list[ClaimRow]:
    """The claims of the analysis in ``analysis_dir`` (its ``tables/claims.csv``).

    Raises:
        CompareError: The table is missing or not a claims table.
    """
    path = Path(analysis_dir) / CLAIMS_TABLE
    if not path.is_file():
        raise CompareError(f"{path}: missing (analyse the study first)")
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        # Later tables add columns (Holm p, A's interval, the statistic); the
        # comparison needs these.
        if not set(COLUMNS) <= set(reader.fieldnames or ()):
            raise CompareError(
                f"{path}: columns {reader.fieldnames}, expected {list(COLUMNS)}"
            )
        rows = []
        for line, row in enumerate(reader, start=2):
            try:
                verdict = Verdict(row["verdict"])
            except ValueError:
                raise CompareError(
                    f"{path}:{line}: unknown verdict {row['verdict']!r}"
                ) from None
            rows.append(
                ClaimRow(row["topic"], row["task"], row["claim"], row["ours"], verdict)
            )
    statements = Counter(r.statement for r in rows)
    twice = [s for s, n in statements.items() if n > 1]
    if twice:
        raise CompareError(f"{path}: claim listed twice: {twice[0]!r}")
    return rows


def read_mapping(path: Path, what: str) -> dict[Any, Any]:
    """The YAML mapping in ``path`` ({} for an empty file), called ``what`` in
    errors.

    Raises:
        CompareError: Unreadable, or not a mapping.
    """
    try:
        data = read_yaml(path, what)
    except YamlRefused as error:
        raise CompareError(str(error)) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise CompareError(f"{path}: must map claim statements to {what}")
    return data


def read_reasons(path: str | Path) -> dict[str, str]:
    """Explanations of changed verdicts: a YAML mapping from a claim's statement
    (as the report words it) to why its verdict changed.

    Raises:
        CompareError: Not such a mapping.
    """
    path = Path(path)
    data = read_mapping(path, "explanations")
    if not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        raise CompareError(f"{path}: must map claim statements to explanations")
    return {k: " ".join(v.split()) for k, v in data.items()}


def changes(
    before: Sequence[ClaimRow], after: Sequence[ClaimRow], reasons: dict[str, str]
) -> list[Change]:
    """The claims of ``after`` whose verdict differs in ``before``, in ``after``'s
    order."""
    earlier = {r.statement: r for r in before}
    return [
        Change(earlier[r.statement], r, reasons.get(r.statement))
        for r in after
        if r.statement in earlier and earlier[r.statement].verdict != r.verdict
    ]


def verdict_counts(rows: Sequence[ClaimRow]) -> tuple[Counter[Verdict], int]:
    """Verdicts counted as the reports count them (:func:`.claims.totals`): two
    claims on one test, which give the same evidence, with one verdict are one
    observation; and how many observations there are."""
    unique = {(r.topic, r.task, r.ours, r.verdict) for r in rows}
    return Counter(verdict for *_, verdict in unique), len(unique)


def _counts(rows: Sequence[ClaimRow]) -> str:
    counts, unique = verdict_counts(rows)
    return (
        f"{len(rows)} claims: {counts[Verdict.AGREE]} agree, "
        f"{counts[Verdict.DISAGREE]} disagree, "
        f"{counts[Verdict.INCONCLUSIVE]} inconclusive"
        + (
            f" (a test counted once: {len(rows) - unique} claims share one)"
            if unique < len(rows)
            else ""
        )
    )


def comparison_page(
    before: Sequence[ClaimRow],
    after: Sequence[ClaimRow],
    reasons: dict[str, str],
    names: tuple[str, str] = ("before", "after"),
) -> tuple[str, list[Change]]:
    """The Markdown page, and the changes it lists."""
    ran_before = {r.task for r in before}
    both = [t for t in dict.fromkeys(r.task for r in after) if t in ran_before]
    only_before = [t for t in dict.fromkeys(r.task for r in before) if t not in both]
    found = changes(before, after, reasons)
    lines = [
        f"# The paper's claims: {names[0]} and {names[1]}",
        "",
        f"- {names[0]}: {_counts(before)}.",
        f"- {names[1]}: {_counts(after)}.",
    ]
    if only_before:
        shared = [r for r in before if r.task in both]
        lines += [
            f"- {names[0]}, on the tasks both studies ran "
            f"({', '.join(task_title(t) for t in both)}): {_counts(shared)}.",
            f"- Not run in {names[1]}: "
            + ", ".join(task_title(t) for t in only_before)
            + ".",
        ]
    lines += ["", f"Changed verdicts: {len(found)}.", ""]
    if found:
        lines += markdown_table(
            ["claim", names[0], names[1], "why"],
            [
                [
                    markdown_cell(x)
                    for x in (
                        c.after.statement,
                        f"**{c.before.verdict.value}**: {c.before.ours}",
                        f"**{c.after.verdict.value}**: {c.after.ours}",
                        c.why if c.why is not None else "(not explained)",
                    )
                ]
                for c in found
            ],
        )
    return "\n".join(lines), found

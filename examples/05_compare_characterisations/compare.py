"""Tutorial 05: compare behaviour characterisations with a study of declared
treatments, then read its report.

Runs ``sdbc-study all`` on ``study.yaml`` (four treatments that differ only in their
characterisation), then prints what a reader looks at first: each treatment's runs
and the median of their best fitness, and the pairwise Mann-Whitney tests, read
from the tables the analysis writes beside the report.

    python examples/05_compare_characterisations/compare.py --out results/05
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
from collections import defaultdict
from pathlib import Path

from sdbc_evolution.study.cli import main as sdbc_study

HERE = Path(__file__).resolve().parent
PRESET = HERE / "study.yaml"
TASK = "predator_prey"


def read_table(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as table:
        return list(csv.DictReader(table))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("results/05_compare_characterisations"),
        help="the study's folder (its runs, then report/); run again to resume",
    )
    args = parser.parse_args(argv)
    status = sdbc_study(
        ["all", "--preset", str(PRESET), "--out", str(args.out), "--quiet"]
    )
    if status != 0:
        return status
    tables = args.out / "report" / "tables"

    # Each run's best individual, re-evaluated in fresh trials: the study's outcome.
    bests: dict[str, list[float]] = defaultdict(list)
    for row in read_table(tables / f"bests_{TASK}.csv"):
        bests[row["treatment"]].append(float(row["best"]))
    print(f"\n{'treatment':<16} runs  median best fitness")
    for treatment, values in bests.items():
        print(f"{treatment:<16} {len(values):>4}  {statistics.median(values):.4f}")

    # A is the chance that a run of a beats a run of b; p says whether the runs can
    # tell them apart at all (with 2 runs a side they cannot: p >= 1/3).
    print(f"\n{'a':<16} {'b':<16}    A      p")
    for row in read_table(tables / f"mann_whitney_{TASK}.csv"):
        a, b, effect, p = row["a"], row["b"], float(row["A"]), float(row["p"])
        print(f"{a:<16} {b:<16} {effect:.2f}  {p:.3f}")
    print(f"\nreport: {args.out / 'report' / 'report.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

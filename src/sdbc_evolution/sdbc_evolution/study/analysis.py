"""The analysis of a study: every table and figure, and the claims.

``analyse(study_dir, out_dir)`` reads the run directories (:mod:`.rundirs`), leaves
out and names the unusable ones, reduces them to the study's digest
(:mod:`.reduce`, :mod:`.digest`) and makes everything else from that digest alone;
``analyse_digest_dir(digest_dir, out_dir)`` does the same from a digest written
before, with the same tables and figures to the byte. It writes::

    OUT/
      report.md                      the report (:mod:`.report`)
      digest/study.json, <task>.npz  the digest: what all of the below needs
      figures/curves_<task>.png      best-fitness curves
      figures/bests_<task>.png       boxplots of each run's best
      figures/exploration_<task>.png SOM exploration maps
      tables/curves_<task>.csv       generation, per treatment mean, sd, n
      tables/bests_<task>.csv        treatment, run, best, last, statistic
      tables/mann_whitney_<task>.csv pairwise tests (A with its 95 % interval,
                                     raw and Holm-adjusted p)
      tables/relevance_<task>.csv    MI of every SDBC dimension (NS-SD+ runs)
      tables/relevance_above_chance_<task>.csv  the same, MI above its chance
                                     level (each run's MI minus its own), ranked
      tables/relevance_<task>_<treatment>.csv   the same for any other weighting
                                     treatment (its measure's units)
      tables/exploration_<task>.csv  per run: uniformity, coverage, high-fitness share
      tables/exploration_<task>.npz  per-run shares, mean shares, percentiles, region
      tables/exploration_sensitivity_<task>.csv  per setting (other region sizes;
                                     other SOM seeds and grids where the digest
                                     holds them) and treatment: mean high-fitness
                                     share and uniformity
      tables/exploration_stability_<task>.csv   per setting kind and claim: the
                                     verdict on the map, on how many settings it
                                     is the same, and each verdict's count
      tables/cost.csv                measured rates per task
      tables/projection.csv          the paper preset's wall time on W workers
      tables/claims.csv              every claim: raw and Holm p, A and its
                                     interval, the statistic used, verdict
      tables/predictions.csv         the preset's own predictions, judged (if any)
      tables/problems.csv            runs left out, and why
"""

from __future__ import annotations

import csv
import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sdbc_evolution.ga.treatments import treatment_directory
from sdbc_evolution.run.results import npz_bytes
from sdbc_evolution.study.claims import (
    Claim,
    PredictionResult,
    Verdict,
    exploration_claims,
    judge_predictions,
    quality_claims,
    relevance_claims,
)
from sdbc_evolution.study.combine import combine_digests
from sdbc_evolution.study.cost import (
    paper_preset,
    projections,
    task_cost,
)
from sdbc_evolution.study.digest import (
    DIGEST_DIR,
    StudyDigest,
    TaskDigest,
    read_digest,
    write_digest,
)
from sdbc_evolution.study.figures import plot_bests, plot_curves, plot_exploration
from sdbc_evolution.study.findings import Analysis, AnalysisSettings, TaskAnalysis
from sdbc_evolution.study.quality import (
    PairTest,
    best_curves,
    pairwise_tests,
    run_best,
    run_bests,
    run_last,
    run_lasts,
    run_statistic,
    task_statistic,
)
from sdbc_evolution.study.reduce import reduce_study
from sdbc_evolution.study.relevance import (
    ABOVE_CHANCE,
    PAPER_WEIGHTED,
    RelevanceTable,
    above_chance_table,
    other_relevance_tables,
    relevance_table,
)
from sdbc_evolution.study.report import write_report
from sdbc_evolution.study.rundirs import StudyData, load_study
from sdbc_evolution.study.sensitivity import MAP, REGION, MapSensitivity, sensitivity

FIGURES_DIR = "figures"
TABLES_DIR = "tables"
REPORT_FILE = "report.md"


def _write_csv(path: Path, header: list[str], rows: list[list[Any]]) -> Path:
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for row in rows:
            writer.writerow(
                [
                    repr(float(v)) if isinstance(v, (float, np.floating)) else v
                    for v in row
                ]
            )
    return path


def _write_relevance(path: Path, table: RelevanceTable) -> Path:
    unit = (
        "mi_above_chance_bits"
        if table.measure == ABOVE_CHANCE
        else "mi_bits"
        if table.treatment == PAPER_WEIGHTED
        else "relevance"
    )
    return _write_csv(
        path,
        [
            "rank",
            "feature",
            f"mean_{unit}",
            f"sd_{unit}",
            "runs",
            "in_task_specific",
            "chance_mi_bits",
        ],
        [
            [
                i + 1,
                name,
                table.mean[i],
                table.sd[i],
                table.runs,
                bool(table.in_task_specific[i]),
                table.chance[i],
            ]
            for i, name in enumerate(table.names)
        ],
    )


def analyse_task(
    digest: TaskDigest, settings: AnalysisSettings, out: Path
) -> TaskAnalysis:
    """Writes one task's tables and figures under ``out`` from its digest, and returns
    what the report says of it."""
    task = digest.task
    figures, tables = out / FIGURES_DIR, out / TABLES_DIR
    curves = best_curves(digest)
    header = ["generation"]
    for t in curves.treatments:
        header += [f"{t} mean", f"{t} sd", f"{t} n"]
    rows = []
    for g in curves.generations:
        row: list[Any] = [int(g)]
        for i in range(len(curves.treatments)):
            row += [curves.mean[i, g], curves.sd[i, g], int(curves.n[i, g])]
        rows.append(row)
    _write_csv(tables / f"curves_{task}.csv", header, rows)

    bests = run_bests(digest)
    lasts = run_lasts(digest)
    best_runs = {t: tuple(r.name for r in digest.of(t)) for t in bests}
    _write_csv(
        tables / f"bests_{task}.csv",
        ["treatment", "run", "best", "last", "statistic"],
        [
            [t, run.name, run_best(run), run_last(run), run_statistic(run)]
            for t in bests
            for run in digest.of(t)
        ],
    )
    tests = pairwise_tests(task, bests)
    last_tests = pairwise_tests(task, lasts)
    _write_csv(
        tables / f"mann_whitney_{task}.csv",
        [
            "a",
            "b",
            "n_a",
            "n_b",
            "median_a",
            "median_b",
            "mean_a",
            "mean_b",
            "U",
            "A",
            "A_low",
            "A_high",
            "p",
            "p_holm",
        ],
        [
            [
                s.a,
                s.b,
                s.n_a,
                s.n_b,
                s.median_a,
                s.median_b,
                s.mean_a,
                s.mean_b,
                s.u,
                s.effect,
                s.effect_low,
                s.effect_high,
                s.p,
                s.p_holm,
            ]
            for s in tests
        ],
    )

    relevance = relevance_table(digest)
    if relevance is not None:
        _write_relevance(tables / f"relevance_{task}.csv", relevance)
    above = above_chance_table(digest)
    if above is not None:
        _write_relevance(tables / f"relevance_above_chance_{task}.csv", above)
    other_relevance = other_relevance_tables(digest)
    for treatment, table in other_relevance.items():
        name = f"relevance_{task}_{treatment_directory(treatment)}.csv"
        _write_relevance(tables / name, table)

    maps = digest.maps
    rows = []
    for k, t in enumerate(maps.treatments):
        for name, u, c, h in zip(
            maps.run_names[k],
            maps.uniformity(k),
            maps.coverage(k),
            maps.region_share(k),
            strict=True,
        ):
            rows.append([t, name, u, c, h])
    _write_csv(
        tables / f"exploration_{task}.csv",
        ["treatment", "run", "uniformity", "coverage", "high_fitness_share"],
        rows,
    )
    (tables / f"exploration_{task}.npz").write_bytes(
        npz_bytes(
            {
                "treatments": np.array([t for t in maps.treatments]),
                "mean_share": maps.mean_share,
                "percentile": maps.percentile,
                "pooled_percentile": maps.pooled_percentile,
                "region": maps.region,
                **{
                    f"shares_{t}": maps.shares[k] for k, t in enumerate(maps.treatments)
                },
                **{
                    f"runs_{t}": np.array(maps.run_names[k])
                    for k, t in enumerate(maps.treatments)
                },
            }
        )
    )

    spreads = [
        found
        for kind in (MAP, REGION)
        if (found := sensitivity(maps, kind, settings.alpha)) is not None
    ]
    _write_sensitivity(tables, task, spreads)

    figure_paths = {
        "curves": plot_curves(curves, figures / f"curves_{task}.png"),
        "bests": plot_bests(task, bests, figures / f"bests_{task}.png"),
        "exploration": plot_exploration(maps, figures / f"exploration_{task}.png"),
    }
    return TaskAnalysis(
        task=task,
        curves=curves,
        bests=bests,
        best_runs=best_runs,
        tests=tests,
        statistic=task_statistic(digest),
        last_tests=last_tests,
        relevance=relevance,
        relevance_above_chance=above,
        other_relevance=other_relevance,
        maps=maps,
        sensitivity=spreads,
        cost=task_cost(digest),
        figures=figure_paths,
    )


def _write_sensitivity(tables: Path, task: str, spreads: list[MapSensitivity]) -> None:
    _write_csv(
        tables / f"exploration_sensitivity_{task}.csv",
        [
            "kind",
            "seed",
            "rows",
            "columns",
            "region_fraction",
            "treatment",
            "mean_high_fitness_share",
            "mean_uniformity",
        ],
        [
            [
                found.kind,
                setting.seed,
                setting.rows,
                setting.columns,
                setting.fraction,
                treatment,
                found.shares[k, n],
                found.uniformity[k, n],
            ]
            for found in spreads
            for n, setting in enumerate(found.settings)
            for k, treatment in enumerate(found.treatments)
        ],
    )
    _write_csv(
        tables / f"exploration_stability_{task}.csv",
        [
            "kind",
            "claim",
            "verdict_on_map",
            "settings",
            "same_verdict",
            "agree",
            "disagree",
            "inconclusive",
        ],
        [
            [
                found.kind,
                c.statement,
                c.verdict.value,
                len(c.verdicts),
                c.same,
                *(c.count(v) for v in Verdict),
            ]
            for found in spreads
            for c in found.claims
        ],
    )


def only_tasks(study: StudyData, tasks: Sequence[str] | None) -> StudyData:
    """``study`` with only the runs (and left-out runs) of ``tasks`` (None: all),
    so that a task finished while others still run becomes a digest part of its
    own (a part holds whole tasks, :mod:`.combine`).

    Raises:
        FileNotFoundError: A task with no usable run in ``study``.
    """
    if tasks is None:
        return study
    chosen = set(tasks)
    missing = sorted(chosen - {r.task for r in study.runs})
    if missing:
        raise FileNotFoundError(
            f"no usable run of {', '.join(missing)} under {study.root}"
        )
    return dataclasses.replace(
        study,
        runs=[r for r in study.runs if r.task in chosen],
        problems=[
            p
            for p in study.problems
            if "/" not in p.name or p.name.split("/")[0] in chosen
        ],
    )


def _reduce(
    study: StudyData,
    settings: AnalysisSettings,
    study_dir: str | Path,
    command: list[str] | None,
) -> StudyDigest:
    return reduce_study(
        study,
        settings.som,
        str(study_dir),
        command,
        settings.seeds,
        settings.sensitivity_grids,
    )


def analyse(
    study_dir: str | Path,
    out_dir: str | Path | None = None,
    settings: AnalysisSettings | None = None,
    command: list[str] | None = None,
    tasks: Sequence[str] | None = None,
) -> Analysis:
    """Analyses the study in ``study_dir`` into ``out_dir`` (default
    ``study_dir/report``): writes the digest (``out_dir/digest``), then the
    tables, figures and report from it; only ``tasks`` if given.

    Raises:
        FileNotFoundError: No usable run at all (of one of ``tasks``).
    """
    settings = settings or AnalysisSettings()
    out = Path(out_dir) if out_dir is not None else Path(study_dir) / "report"
    study = only_tasks(load_study(study_dir), tasks)
    digest = _reduce(study, settings, study_dir, command)
    write_digest(digest, out / DIGEST_DIR)
    return analyse_digest(digest, out, settings, command)


def analyse_digest_dir(
    digest_dir: str | Path,
    out_dir: str | Path | None = None,
    settings: AnalysisSettings | None = None,
    command: list[str] | None = None,
) -> Analysis:
    """Makes the tables, figures and report again from the digest in
    ``digest_dir`` alone, into ``out_dir`` (default: the digest's parent folder),
    and writes the digest beside them if it is not there already.

    Raises:
        DigestError: The digest is missing, damaged or not a digest.
    """
    digest = read_digest(digest_dir)
    out = Path(out_dir) if out_dir is not None else Path(digest_dir).parent
    if (out / DIGEST_DIR).resolve() != Path(digest_dir).resolve():
        write_digest(digest, out / DIGEST_DIR)
    return analyse_digest(digest, out, settings, command)


def analyse_parts(
    study_dir: str | Path | None,
    digest_dirs: list[Path],
    out_dir: str | Path | None = None,
    settings: AnalysisSettings | None = None,
    command: list[str] | None = None,
    tasks: Sequence[str] | None = None,
) -> Analysis:
    """Analyses one study made of parts (:mod:`.combine`): the run directories in
    ``study_dir`` (if given; only those of ``tasks`` if given) and the digests in
    ``digest_dirs``, e.g. the tasks of a preset run in different sessions.
    Writes the combined digest into ``out_dir/digest`` (default:
    ``study_dir/report``, else the first digest's parent folder), then the
    tables, figures and report from it.

    Raises:
        FileNotFoundError: ``study_dir`` has no usable run.
        DigestError: A digest is unreadable, or the parts do not combine.
    """
    settings = settings or AnalysisSettings()
    parts = [(str(d), read_digest(d)) for d in digest_dirs]
    if study_dir is not None:
        study = only_tasks(load_study(study_dir), tasks)
        reduced = _reduce(study, settings, study_dir, command)
        parts.insert(0, (str(study_dir), reduced))
    if out_dir is not None:
        out = Path(out_dir)
    elif study_dir is not None:
        out = Path(study_dir) / "report"
    else:
        out = Path(digest_dirs[0]).parent
    digest = combine_digests(parts, command or ())
    write_digest(digest, out / DIGEST_DIR)
    return analyse_digest(digest, out, settings, command)


TEST_COLUMNS = ("p_holm", "A", "A_low", "A_high")
"""A test's columns in the claims and predictions tables beside its raw p."""


def _test_cells(test: PairTest | None) -> list[Any]:
    if test is None:
        return ["", "", "", ""]
    holm = "" if test.p_holm is None else test.p_holm
    return [holm, test.effect, test.effect_low, test.effect_high]


def analyse_digest(
    digest: StudyDigest,
    out: Path,
    settings: AnalysisSettings | None = None,
    command: list[str] | None = None,
) -> Analysis:
    """Every table, figure and the report of ``digest`` into ``out``; the maps'
    settings are the digest's own."""
    settings = settings or AnalysisSettings()
    if digest.task_digests:
        settings = dataclasses.replace(
            settings, som=digest.task_digests[0].maps.settings
        )
    (out / FIGURES_DIR).mkdir(parents=True, exist_ok=True)
    (out / TABLES_DIR).mkdir(parents=True, exist_ok=True)
    tasks = [analyse_task(t, settings, out) for t in digest.task_digests]
    claims: list[Claim] = []
    for ta in tasks:
        claims += quality_claims(ta.task, ta.tests, settings.alpha, ta.statistic)
    for ta in tasks:
        claims += relevance_claims(ta.task, ta.relevance, ta.relevance_above_chance)
    for ta in tasks:
        claims += exploration_claims(ta.maps, settings.alpha)
    predicted = _judge_predictions(digest, tasks, settings.alpha)
    tables = out / TABLES_DIR
    if predicted:
        _write_csv(
            tables / "predictions.csv",
            [
                "task",
                "prediction",
                "a",
                "b",
                "rule",
                "evidence",
                "p",
                *TEST_COLUMNS,
                "outcome",
            ],
            [
                [
                    r.task,
                    r.prediction.statement,
                    r.prediction.a,
                    r.prediction.b,
                    r.prediction.rule,
                    r.evidence,
                    r.p,
                    *_test_cells(r.test),
                    r.outcome,
                ]
                for r in predicted
            ],
        )
    _write_csv(
        tables / "claims.csv",
        [
            "topic",
            "task",
            "claim",
            "paper",
            "ours",
            "p",
            *TEST_COLUMNS,
            "statistic",
            "verdict",
        ],
        [
            [
                c.topic,
                c.task,
                c.statement,
                c.paper,
                c.ours,
                "" if c.p is None else c.p,
                *_test_cells(c.test),
                c.statistic,
                c.verdict.value,
            ]
            for c in claims
        ],
    )
    _write_csv(
        tables / "problems.csv",
        ["run", "reason"],
        [[p.name, p.reason] for p in digest.problems],
    )
    costs = [ta.cost for ta in tasks]
    _write_csv(
        tables / "cost.csv",
        [
            "task",
            "runs",
            "bodies",
            "max_steps",
            "mean_trial_length",
            "robot_steps_per_s_per_worker",
            "serial_s_per_individual",
            "s_per_generation",
            "generations_per_s",
            "run_seconds_total",
        ],
        [
            [
                c.task,
                c.runs,
                c.bodies,
                c.max_steps,
                c.mean_length,
                c.rate,
                c.serial_per_individual,
                c.seconds_per_generation,
                c.generations_per_second,
                c.run_seconds,
            ]
            for c in costs
        ],
    )
    projected = projections(costs, paper_preset(), settings.cluster_workers)
    _write_csv(
        tables / "projection.csv",
        ["task", "workers", "expected_hours", "bound_hours", "cpu_hours", "runs"],
        [
            [p.task, p.workers, p.expected_hours, p.bound_hours, p.cpu_hours, p.runs]
            for p in projected
        ],
    )
    analysis = Analysis(
        digest=digest,
        settings=settings,
        tasks=tasks,
        claims=claims,
        predictions=predicted,
        projections=projected,
        out=out,
    )
    write_report(analysis, out / REPORT_FILE, command)
    return analysis


def _judge_predictions(
    digest: StudyDigest, tasks: list[TaskAnalysis], alpha: float
) -> list[PredictionResult]:
    """The preset's predictions, judged on every task they concern."""
    if digest.preset is None:
        return []
    predictions = digest.preset.predictions
    return [
        result
        for ta in tasks
        for result in judge_predictions(predictions, ta.task, ta.tests, alpha)
    ]

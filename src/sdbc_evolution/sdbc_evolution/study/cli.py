"""``sdbc-study``: the paper's study, its figures, tables and report, in one command.

Examples::

    sdbc-study --preset smoke                     # run, then analyse
    sdbc-study run --preset local --task gate_escape --out results/study-local
    sdbc-study run --preset paper --scheduler tcp://10.0.0.5:8786
    sdbc-study run --preset paper --workers 1 --shard $SLURM_ARRAY_TASK_ID/240
    sdbc-study analyse results/study-local --out docs/study/local
    sdbc-study analyse --from-digest docs/study/local/digest   # again, from its digest
    # one study whose tasks ran apart: this session's runs with an earlier digest
    sdbc-study analyse results/pp --from-digest docs/study/v2/digest --out docs/study/v2
    sdbc-study measure --preset local             # what the study would cost here
    sdbc-study compare docs/study/local-v1 docs/study/local --reasons why.yaml
    sdbc-study verdicts docs/study/local docs/study/local_kinematic \
        --causes docs/study/disagreement-causes.yaml     # claims in several studies

``run`` is resumable: run it again with the same ``--preset`` and ``--out`` and it
skips finished runs and resumes interrupted ones. Also ``python -m
sdbc_evolution.study``.

Exit status: 0 done, 1 some run failed, 2 bad input (preset, task, directory,
scheduler), 3 some runs were being written by another process and were left to it
(run the same command again once it ends), 130 interrupted by Ctrl-C or SIGTERM
(run the same command again to resume).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from sdbc_sim.limits import excerpt

from sdbc_evolution.run.evaluators import (
    SchedulerLost,
    SchedulerUnreachable,
    add_evaluator_arguments,
    check_evaluator_arguments,
    quiet_dask_logging,
)
from sdbc_evolution.run.joined import JOINED_TRIALS
from sdbc_evolution.run.stopping import stoppable
from sdbc_evolution.run.system_errors import one_line_errors
from sdbc_evolution.study.presets import (
    PRESET_NAMES,
    PresetError,
    StudyPreset,
    load_preset,
)

if TYPE_CHECKING:
    from sdbc_evolution.study.findings import AnalysisSettings

RESULTS_ROOT = Path("results")
"""Where studies go when ``--out`` is not given: ``results/study-<preset>``."""
BUSY_EXIT = 3
"""Exit status of a session that left runs to another process's writer."""
COMMANDS = ("run", "analyse", "all", "measure", "compare", "verdicts")
"""Subcommands; ``all`` (run, then analyse) when none is given."""


def _run_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--preset",
        default="smoke",
        help=f"{', '.join(PRESET_NAMES)} or a preset YAML file (default: smoke)",
    )
    parser.add_argument(
        "--task",
        action="append",
        help="run only this task (repeatable; default: every task of the preset)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        help=f"study directory (default: {RESULTS_ROOT}/study-<preset>)",
    )
    add_evaluator_arguments(
        parser,
        workers_help="local processes side by side (default: every core)",
    )
    parser.add_argument(
        "--joined-runs",
        type=int,
        metavar="K",
        help="most runs of a task per process, their generations evaluated in one "
        f"batch each (default: enough for about {JOINED_TRIALS} trials per batch; "
        "1: every run alone)",
    )
    parser.add_argument(
        "--shard",
        metavar="K/N",
        help="run only share K of N of the runs (runs K, K+N, ...), e.g. one "
        "array job each on a cluster's shared filesystem",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``sdbc-study``."""
    parser = argparse.ArgumentParser(
        prog="sdbc-study",
        description=(
            "Replicate the study of Gomes, Mariano & Christensen (ALIFE 2014): "
            "4 treatments x 3 tasks x R runs at a preset's scale, then the "
            "analysis (curves, boxplots, Mann-Whitney U, MI relevance, SOM "
            "exploration maps) and a Markdown report."
        ),
    )
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run (or resume) the study's runs")
    _run_options(run)
    both = sub.add_parser("all", help="run, then analyse (the default)")
    _run_options(both)
    both.add_argument(
        "--report", type=Path, help="report directory (default: STUDY/report)"
    )
    analyse = sub.add_parser(
        "analyse",
        help="figures, tables, report and digest of a study",
        description="Analyse a study's run directories (writing OUT/digest beside "
        "the report), or redo the report, tables and figures from a digest alone.",
    )
    analyse.add_argument("study", type=Path, nargs="?", help="the study directory")
    analyse.add_argument(
        "--from-digest",
        type=Path,
        metavar="DIR",
        action="append",
        help="make everything from this digest instead of the run directories; "
        "repeated, or beside a study directory, the parts are analysed as one "
        "study (the tasks of one preset run apart, e.g. in different sessions)",
    )
    analyse.add_argument(
        "--out",
        type=Path,
        help="report directory (default: STUDY/report, or the digest's parent)",
    )
    analyse.add_argument(
        "--task",
        action="append",
        help="only this task's runs of the study directory (repeatable): a task "
        "finished while others still run, as a digest part of its own",
    )
    analyse.add_argument(
        "--som-seeds",
        type=int,
        default=0,
        metavar="N",
        help="also train each task's map again with N seeds (0..N-1) on each grid "
        "of --som-grids and keep every run's exploration numbers on them in the "
        "digest: the sensitivity of the region shares to the map (run directories "
        "only; about 10 s of CPU per map and task; default 0: not measured)",
    )
    analyse.add_argument(
        "--som-grids",
        metavar="RxC,...",
        help="the grids of --som-seeds (default: the map's scaled by 0.5, 0.75 "
        "and 1, so 10x10,15x15,20x20)",
    )
    compare = sub.add_parser(
        "compare",
        help="the paper's claims in two analyses: counts and changed verdicts",
        description="Set the claims of two analysed studies side by side (their "
        "tables/claims.csv): verdict counts, and every changed verdict with both "
        "studies' evidence and the explanation given in --reasons.",
    )
    compare.add_argument("before", type=Path, help="the earlier analysis's folder")
    compare.add_argument("after", type=Path, help="the later analysis's folder")
    compare.add_argument(
        "--reasons",
        type=Path,
        help="YAML: a claim's statement -> why its verdict changed",
    )
    compare.add_argument(
        "--names",
        default="before,after",
        help="what the page calls the two studies (default: before,after)",
    )
    compare.add_argument(
        "--out", type=Path, help="write the page here (default: print it)"
    )
    verdicts = sub.add_parser(
        "verdicts",
        help="the paper's claims in several analyses: each study's verdict, claim "
        "by claim, and the declared cause of every disagreement",
        description="Set the claims of several analysed studies side by side "
        "(their tables/claims.csv, made by today's rules): verdict counts, each "
        "claim's verdict in each study ('not run' for a task a study lacks), and "
        "the cause of each disagreement from --causes, marked tested (by the "
        "experiment named) or untested.",
    )
    verdicts.add_argument(
        "analyses", type=Path, nargs="+", help="the analyses' folders, in order"
    )
    verdicts.add_argument(
        "--names",
        help="what the page calls the studies, separated by commas (default: the "
        "folders' names)",
    )
    verdicts.add_argument(
        "--causes",
        type=Path,
        help="YAML: a claim's statement -> {cause: why, tested: experiment}",
    )
    verdicts.add_argument(
        "--out", type=Path, help="write the page here (default: print it)"
    )
    measure = sub.add_parser(
        "measure", help="time a few generations per task and project the study"
    )
    measure.add_argument("--preset", default="local", help="preset (default: local)")
    measure.add_argument("--task", action="append", help="task(s) to measure")
    measure.add_argument(
        "--generations", type=int, default=3, help="generations per probe run"
    )
    measure.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="processes side by side in the projection (default: every core)",
    )
    measure.add_argument(
        "--joined-runs",
        type=int,
        metavar="K",
        help="runs probed joined, as `run --joined-runs K` would join them "
        "(default: as `run` does)",
    )
    return parser


def _error(message: str) -> int:
    print(f"sdbc-study: error: {message}", file=sys.stderr)
    return 2


def _preset(args: argparse.Namespace) -> StudyPreset:
    preset = load_preset(args.preset)
    for task in args.task or ():
        if task not in preset.tasks:
            raise PresetError(
                f"--task {task}: not in preset {preset.name!r} "
                f"(its tasks: {', '.join(preset.tasks)})"
            )
    return preset


def _run(args: argparse.Namespace, argv: list[str]) -> tuple[int, Path | None]:
    from sdbc_evolution.study.plan import Shard
    from sdbc_evolution.study.runner import Execution, StudyError, run_study

    try:
        check_evaluator_arguments(args)
        preset = _preset(args)
        execution = Execution(
            workers=args.workers,
            scheduler=args.scheduler,
            connect_timeout=args.connect_timeout,
            joined_runs=args.joined_runs,
        )
        shard = Shard.parse(args.shard) if args.shard is not None else None
        if args.scheduler is not None:
            quiet_dask_logging()
    except (PresetError, ValueError) as error:
        return _error(str(error)), None
    out = args.out if args.out is not None else RESULTS_ROOT / f"study-{preset.name}"
    if out.exists() and not out.is_dir():
        return _error(f"--out {out}: a file, not a directory"), None
    try:
        outcome = run_study(
            preset,
            out,
            tasks=args.task,
            execution=execution,
            quiet=args.quiet,
            command=["sdbc-study", *argv],
            shard=shard,
        )
    except (StudyError, SchedulerUnreachable, ValueError) as error:
        return _error(str(error)), None
    except SchedulerLost as error:
        return _error(f"{error}; run the same command again to continue"), None
    if outcome.interrupted:
        print(
            f"\ninterrupted; resume with the same command "
            f"(--preset {args.preset} --out {out})",
            file=sys.stderr,
        )
        return 130, out
    for task, seconds in outcome.task_seconds.items():
        print(f"{task}: {seconds / 60:.1f} min in this session")
    print(f"study: {out.resolve()}")
    if outcome.failed:
        return 1, out
    if outcome.busy:
        print(
            f"sdbc-study: {len(outcome.busy)} run(s) were being written by another "
            "process and were left to it; run the same command again once it ends",
            file=sys.stderr,
        )
        return BUSY_EXIT, out
    return 0, out


def parse_grids(text: str) -> tuple[tuple[int, int], ...]:
    """``"10x10,15x15"`` -> ((10, 10), (15, 15)).

    Raises:
        ValueError: Not such a list, or a grid under 2 x 2.
    """
    grids = []
    for word in text.split(","):
        parts = word.strip().lower().split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
            raise ValueError(
                f"--som-grids: ROWSxCOLUMNS separated by commas, got {excerpt(text)}"
            )
        rows, columns = (int(p) for p in parts)
        if min(rows, columns) < 2:
            raise ValueError(f"--som-grids: {word.strip()} is under 2 x 2")
        grids.append((rows, columns))
    return tuple(grids)


def _analysis_settings(args: argparse.Namespace) -> AnalysisSettings:
    from sdbc_evolution.study.findings import AnalysisSettings

    if args.som_seeds < 0:
        raise ValueError(f"--som-seeds: at least 0, got {args.som_seeds}")
    if args.som_grids is not None and args.som_seeds == 0:
        raise ValueError("--som-grids is the grids of --som-seeds: give that too")
    if args.som_seeds and args.study is None:
        raise ValueError(
            "--som-seeds trains new maps on the runs' SDBC vectors, which a digest "
            "does not keep: give the study directory"
        )
    grids = parse_grids(args.som_grids) if args.som_grids is not None else None
    return AnalysisSettings(sensitivity_seeds=args.som_seeds, sensitivity_grids=grids)


def _analyse(
    study: Path | None,
    out: Path | None,
    argv: list[str],
    digests: list[Path] | None = None,
    tasks: list[str] | None = None,
    settings: AnalysisSettings | None = None,
) -> int:
    from sdbc_evolution.study.analysis import (
        REPORT_FILE,
        analyse,
        analyse_digest_dir,
        analyse_parts,
    )
    from sdbc_evolution.study.digest import DigestError

    command = ["sdbc-study", *argv]
    digests = digests or []
    try:
        if study is None and not digests:
            return _error(
                "analyse takes a study directory, --from-digest DIR, or both "
                "(parts of one study)"
            )
        if tasks and study is None:
            return _error("--task chooses runs of a study directory: give one")
        if study is not None and not digests:
            analysis = analyse(study, out, settings, command=command, tasks=tasks)
        elif study is None and len(digests) == 1:
            analysis = analyse_digest_dir(digests[0], out, settings, command=command)
        else:
            analysis = analyse_parts(
                study, digests, out, settings, command=command, tasks=tasks
            )
    except (FileNotFoundError, DigestError) as error:
        return _error(str(error))
    for problem in analysis.problems:
        print(f"left out {problem.name}: {problem.reason}", file=sys.stderr)
    print(f"report: {(analysis.out / REPORT_FILE).resolve()}")
    return 0


def _write_page(page: str, out: Path | None, what: str) -> None:
    """``page`` into ``out`` (its path printed), or printed."""
    if out is not None:
        out.write_text(page)
        print(f"{what}: {out.resolve()}")
    else:
        print(page)


def _compare(args: argparse.Namespace) -> int:
    from sdbc_evolution.study.compare import (
        CompareError,
        comparison_page,
        read_claims,
        read_reasons,
    )

    names = tuple(n.strip() for n in args.names.split(","))
    if len(names) != 2 or not all(names):
        return _error(
            f"--names: two names separated by a comma, got {excerpt(args.names)}"
        )
    try:
        before, after = read_claims(args.before), read_claims(args.after)
        reasons = read_reasons(args.reasons) if args.reasons is not None else {}
    except CompareError as error:
        return _error(str(error))
    page, found = comparison_page(before, after, reasons, (names[0], names[1]))
    _write_page(page, args.out, "comparison")
    for change in found:
        if change.why is None:
            print(f"not explained: {change.after.statement}", file=sys.stderr)
    return 0


def _verdicts(args: argparse.Namespace) -> int:
    from sdbc_evolution.study.compare import CompareError
    from sdbc_evolution.study.verdicts import read_causes, read_study, verdicts_page

    names = (
        [n.strip() for n in args.names.split(",")]
        if args.names is not None
        else [a.resolve().name for a in args.analyses]
    )
    if len(names) != len(args.analyses) or not all(names):
        return _error(
            f"--names: one name per analysis ({len(args.analyses)}), separated by "
            f"commas, got {excerpt(args.names)}"
        )
    try:
        studies = [read_study(a, n) for a, n in zip(args.analyses, names, strict=True)]
        causes = read_causes(args.causes) if args.causes is not None else {}
        page, found = verdicts_page(
            studies,
            causes,
            "the causes file" if args.causes is None else f"`{args.causes}`",
        )
    except CompareError as error:
        return _error(str(error))
    _write_page(page, args.out, "verdicts")
    for d in found:
        if d.cause is None:
            print(
                f"no cause declared: {d.statement} ({', '.join(d.studies)})",
                file=sys.stderr,
            )
    claimed = {r.statement for study in studies for r in study.rows}
    for statement in causes:
        if statement not in claimed:
            print(f"cause of no claim here: {statement}", file=sys.stderr)
    return 0


def _measure(args: argparse.Namespace) -> int:
    from sdbc_evolution.study.measure import probe, probe_report
    from sdbc_evolution.study.runner import Execution

    try:
        preset = _preset(args)
        execution = Execution(joined_runs=args.joined_runs)
        if args.workers < 1:
            raise PresetError(f"--workers: must be at least 1, got {args.workers}")
        if args.generations < 2:
            raise PresetError(
                f"--generations: must be at least 2, got {args.generations}"
            )
    except (PresetError, ValueError) as error:
        return _error(str(error))
    tasks = args.task or list(preset.tasks)
    probes = {}
    for task in tasks:
        config = preset.experiment_config(task, preset.treatments[0], 0)
        # A treatment has the preset's runs to join, at most.
        joined = min(execution.joined(config), preset.runs)
        print(
            f"{task}: probing {joined} run(s) of each treatment joined", file=sys.stderr
        )
        probes[task] = probe(preset, task, args.generations, joined)
    print(probe_report(preset, probes, args.workers))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``sdbc-study``: runs, analyses or compares a study (``all`` when no command is
    given); the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in (*COMMANDS, "-h", "--help"):
        argv = ["all", *argv]
    args = build_parser().parse_args(argv)
    return one_line_errors("sdbc-study", lambda: _main(args, argv))


def _main(args: argparse.Namespace, argv: list[str]) -> int:
    if args.command == "analyse":
        try:
            settings = _analysis_settings(args)
        except ValueError as error:
            return _error(str(error))
        return _analyse(
            args.study, args.out, argv, args.from_digest, args.task, settings
        )
    if args.command == "measure":
        return _measure(args)
    if args.command == "compare":
        return _compare(args)
    if args.command == "verdicts":
        return _verdicts(args)
    with stoppable():
        status, out = _run(args, argv)
    if args.command == "run" or status != 0 or out is None:
        return status
    return _analyse(out, args.report, argv)


if __name__ == "__main__":
    sys.exit(main())

"""``sdbc-evolve``: run, resume and watch an evolutionary experiment.

With no arguments it runs the quick-start experiment (NS-SD+ on gate escape, a few
minutes on two cores), says where the results are, and renders the best
individual's trial as a GIF. Flags override the configuration (the quick-start one,
or ``--config FILE``); ``configs/`` holds examples, the paper's setup included.

Examples::

    sdbc-evolve
    sdbc-evolve --task predator_prey --treatment fit --generations 100 --seed 3
    sdbc-evolve --task my_tasks.py:Beacon --generations 20
    sdbc-evolve --list-tasks
    sdbc-evolve --config configs/paper/gate_escape.yaml --treatment ns-ts --out runs/a
    sdbc-evolve --task predator_prey --treatment configs/treatments/nslc-sdbc.yaml
    sdbc-evolve --resume --out runs/a
    sdbc-evolve --config run.yaml --scheduler tcp://10.0.0.5:8786

Exit status: 0 done, 1 a run that failed, 2 bad input (configuration, checkpoint,
scheduler), 130 interrupted (resume with ``--resume --out DIR``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sdbc_evolution.run.checkpoint import CheckpointError
from sdbc_evolution.run.config import PHYSICS_MODELS, ConfigError, ExperimentConfig
from sdbc_evolution.run.evaluators import (
    SchedulerLost,
    SchedulerUnreachable,
    ValuesOutOfRange,
    add_evaluator_arguments,
    check_evaluator_arguments,
    make_evaluator,
    quiet_dask_logging,
)
from sdbc_evolution.run.experiment import Experiment, ExperimentError, task_spec
from sdbc_evolution.run.lock import RunBusy, RunLock
from sdbc_evolution.run.processes import available_cores
from sdbc_evolution.run.request import (
    RESULTS_ROOT,
    ConfigRequest,
    check_before_run,
    default_out,
    resolve_config,
)
from sdbc_evolution.run.results import GenerationRecord, read_generations
from sdbc_evolution.run.stopping import stoppable
from sdbc_evolution.run.system_errors import one_line_errors

GIF_NAME = "best.gif"
"""The best individual's trial, rendered in the output directory."""


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``sdbc-evolve``."""
    parser = argparse.ArgumentParser(
        prog="sdbc-evolve",
        description=(
            "Evolve robot-team controllers with novelty search and systematically "
            "derived behaviour characterisations (Gomes, Mariano & Christensen, "
            "ALIFE 2014). Without --config: a quick-start experiment (NS-SD+ on gate "
            "escape, a few minutes on two cores)."
        ),
    )
    parser.add_argument("--config", type=Path, help="YAML experiment configuration")
    parser.add_argument(
        "--task",
        help="the task: a registered name (see --list-tasks), package.module:Class "
        "or path/to/file.py:Class",
    )
    parser.add_argument(
        "--list-tasks",
        action="store_true",
        help="list the registered tasks (this package's and the 'sdbc.tasks' entry "
        "points) and exit",
    )
    parser.add_argument(
        "--treatment",
        metavar="NAME|FILE",
        help="a paper treatment (fit, ns-ts, ns-sd, ns-sd+) or a YAML file declaring "
        "one (see docs/treatments.md)",
    )
    parser.add_argument("--generations", type=int, help="generations to run")
    parser.add_argument("--population", type=int, help="population size")
    parser.add_argument("--trials", type=int, help="trials per individual")
    parser.add_argument(
        "--physics",
        metavar="|".join(PHYSICS_MODELS),
        help="the engine's physics model: rigid (pymunk bodies, the default) or "
        "kinematic (the authors' robots: a move that would overlap is refused and "
        "retried sideways)",
    )
    parser.add_argument("--seed", type=int, help="seed of the run")
    parser.add_argument(
        "--out", type=Path, help=f"output directory (default: {RESULTS_ROOT}/<name>)"
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out from its checkpoint",
    )
    add_evaluator_arguments(
        parser, workers_help="local worker processes (default: every core)"
    )
    parser.add_argument("--no-gif", action="store_true", help="skip the GIF at the end")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def config_request(args: argparse.Namespace) -> ConfigRequest:
    """The configuration the command line asks for."""
    return ConfigRequest(
        config=args.config,
        resume=args.resume,
        out=args.out,
        task=args.task,
        treatment=args.treatment,
        generations=args.generations,
        population=args.population,
        trials=args.trials,
        physics=args.physics,
        seed=args.seed,
    )


def list_tasks() -> str:
    """One line per registered task: name, where it comes from, what it is."""
    from sdbc_sim.tasks import available_tasks, package_tasks

    ours = package_tasks()
    lines = []
    for name, task_class in sorted(available_tasks().items()):
        origin = (
            "this package"
            if name in ours
            else f"{task_class.__module__}:{task_class.__qualname__}"
        )
        summary = (task_class.__doc__ or "").strip().split("\n")[0]
        lines.append(
            f"{name}  ({origin}, {task_class.default_generations} "
            f"generations by default)  {summary}".rstrip()
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """``sdbc-evolve``: runs (or resumes) one experiment; the exit status (2 on bad
    input, with a one-line error)."""
    args = build_parser().parse_args(argv)
    if args.list_tasks:
        try:
            print(list_tasks())
        except ValueError as error:
            print(f"sdbc-evolve: error: {error}", file=sys.stderr)
            return 2
        return 0
    return one_line_errors("sdbc-evolve", lambda: _main(args))


def _main(args: argparse.Namespace) -> int:
    try:
        check_evaluator_arguments(args)
        config = resolve_config(config_request(args))
        out = args.out if args.out is not None else default_out(config)
        if out.exists() and not out.is_dir():
            raise ConfigError(f"--out {out}: a file, not a directory")
    except (ConfigError, CheckpointError, ValueError) as error:
        print(f"sdbc-evolve: error: {error}", file=sys.stderr)
        return 2
    # A run another process writes is refused first, before the checks below
    # run a trial: a second writer learns it is one at once, however long the
    # task's trial and the machine's load make those checks.
    try:
        lock = RunLock(out).acquire() if out.is_dir() else None
    except RunBusy as error:
        print(f"sdbc-evolve: error: {error}", file=sys.stderr)
        return 2
    try:
        return _checked_main(args, config, out, lock)
    finally:
        if lock is not None:
            lock.release()  # a no-op once the run took it and released it


def _checked_main(
    args: argparse.Namespace, config: ExperimentConfig, out: Path, lock: RunLock | None
) -> int:
    try:
        workers = 1 if args.scheduler is not None else args.workers
        check_before_run(config, available_cores() if workers is None else workers)
        if args.scheduler is not None:
            quiet_dask_logging()
        evaluator = make_evaluator(
            task_spec(config),
            workers=args.workers,
            scheduler=args.scheduler,
            timeout=args.connect_timeout,
        )
    except (ConfigError, CheckpointError, SchedulerUnreachable, ValueError) as error:
        print(f"sdbc-evolve: error: {error}", file=sys.stderr)
        return 2
    for note in config.notes():
        print(f"sdbc-evolve: note: {note}", file=sys.stderr)
    with evaluator:
        try:
            if args.resume:
                experiment = Experiment.resume(config, out, evaluator, lock=lock)
            else:
                experiment = Experiment.create(config, out, evaluator, lock=lock)
        except (CheckpointError, ExperimentError, RunBusy, ValueError) as error:
            print(f"sdbc-evolve: error: {error}", file=sys.stderr)
            return 2
        with experiment:
            status = _run(experiment, out, quiet=args.quiet)
    if status == 0:
        _report(experiment, out, gif=not args.no_gif)
    return status


def _run(experiment: Experiment, out: Path, quiet: bool) -> int:
    from tqdm import tqdm

    config = experiment.config
    bar = tqdm(
        total=experiment.generations,
        initial=experiment.state.generation,
        desc=f"{config.task} {config.treatment.name}",
        unit="gen",
        disable=quiet,
        dynamic_ncols=True,
    )
    best = -np.inf

    def progress(record: GenerationRecord) -> None:
        nonlocal best
        best = max(best, record.best_fitness)
        bar.set_postfix(gen=record.generation, best=f"{best:.4f}", refresh=False)
        bar.update(1)

    try:
        with stoppable():
            experiment.run(progress)
    except ValuesOutOfRange as error:
        bar.close()
        print(
            f"sdbc-evolve: error: {error} (sdbc-evolve --resume --out {out})",
            file=sys.stderr,
        )
        return 2
    except SchedulerLost as error:
        bar.close()
        print(
            f"sdbc-evolve: error: {error}; continue with: sdbc-evolve --resume "
            f"--out {out} --scheduler ADDRESS",
            file=sys.stderr,
        )
        return 2
    except KeyboardInterrupt:
        bar.close()
        print(
            f"\ninterrupted after generation {experiment.state.generation}; "
            f"resume with:\n  sdbc-evolve --resume --out {out}",
            file=sys.stderr,
        )
        return 130
    bar.close()
    return 0


def _report(experiment: Experiment, out: Path, gif: bool) -> None:
    generations = read_generations(out)
    score = generations["reevaluated_fitness"]
    if np.isnan(score).all():
        score = generations["best_fitness"]
    g = int(np.nanargmax(score))
    genome = np.load(out / "best_genomes.npy")[g]
    print(f"results: {out.resolve()}")
    print(
        f"best individual: generation {g}, fitness {generations['best_fitness'][g]:.4f}"
        + (
            f", re-evaluated {generations['reevaluated_fitness'][g]:.4f}"
            if not np.isnan(generations["reevaluated_fitness"][g])
            else ""
        )
    )
    if not gif:
        return
    from sdbc_sim.render import render_trial

    path = out / GIF_NAME
    spec = task_spec(experiment.config)
    render_trial(
        spec.build(),
        genome,
        experiment.config.seed,
        path,
        settings=spec.engine_settings(),
    )
    print(f"its trial: {path.resolve()}")


if __name__ == "__main__":
    sys.exit(main())

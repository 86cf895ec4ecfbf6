"""The Markdown report of an analysed study: our numbers beside the paper's claims.

Sections: what ran (preset sizes beside the paper's, commands, wall time per task,
runs left out), the claims one by one with our p-values and verdicts, one section per
task (figures, tests, relevance, exploration), where and why we may differ, and the
projection of the paper preset's wall time on a cluster.
"""

from __future__ import annotations

import math
import os
import shlex
from collections import Counter
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from sdbc_sim.tasks.resource_sharing import NO_CHARGE_OPTIMUM

from sdbc_evolution.ga.treatments import label
from sdbc_evolution.run.config import ExperimentConfig
from sdbc_evolution.study.claims import (
    EQUIVALENCE_MARGIN,
    PAPER_RELEVANCE,
    Claim,
    Verdict,
    totals,
)
from sdbc_evolution.study.exploration import ExplorationMaps
from sdbc_evolution.study.findings import Analysis, TaskAnalysis
from sdbc_evolution.study.paper import (
    deceptive_optimum,
    is_paper_task,
    paper_generations,
    task_title,
)
from sdbc_evolution.study.plan import STUDY_FILE
from sdbc_evolution.study.presets import PAPER_RUNS
from sdbc_evolution.study.quality import PairTest
from sdbc_evolution.study.relevance import BITS, task_specific_features
from sdbc_evolution.study.rundirs import MISSING, RunProblem
from sdbc_evolution.study.sensitivity import MAP, REGION

if TYPE_CHECKING:
    from sdbc_evolution.study.cost import Projection

CLAIM_TOPICS = {
    "quality": "Quality of the solutions (each run's best fitness)",
    "relevance": "Relevance of behaviour features (MI of the NS-SD+ runs)",
    "exploration": "Behaviour-space exploration (per-run numbers of the SOM maps)",
}
"""The report's claim tables, in the paper's order."""
PAPER = ExperimentConfig()
"""The paper's settings (docs/reference-setup.md), for the side-by-side sizes."""
PLATEAU_MARGIN = 0.005
"""A run's last best counts as on resource sharing's plateau within this distance of
the no-charge optimum, and as above it beyond. In the first local study the bests
on the plateau, re-evaluated in fresh trials, lay 0.0005 to 0.0015 below it, those
that charged 0.007 or more above, and the rest 0.007 or more below."""


def _f(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}g}" if math.isfinite(x) else "n/a"


def _p(p: float | None) -> str:
    if p is None:
        return ""
    return "< 0.001" if p < 1e-3 else f"{p:.3f}"


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.1f} min"


def markdown_cell(text: str) -> str:
    """``text`` as a Markdown table cell: its ``|`` escaped."""
    return text.replace("|", "\\|")


def markdown_table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table and the blank line after it."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines + [""]


def _rel(path: Path, start: Path) -> str:
    return Path(os.path.relpath(path, start)).as_posix()


def _sizes(analysis: Analysis) -> list[str]:
    """Each task's run sizes; the paper's beside them for the paper's tasks (and
    no paper column at all when the study has none of them)."""
    study = analysis.digest
    with_paper = any(is_paper_task(ta.task) for ta in analysis.tasks)
    rows = []
    for ta in analysis.tasks:
        config = study.of(ta.task)[0].config
        runs = Counter(r.treatment for r in study.of(ta.task))
        per_treatment = ", ".join(f"{label(t)} {runs[t]}" for t in ta.curves.treatments)
        sizes = [
            (config.ga.population_size, PAPER.ga.population_size),
            (config.evaluation.trials, PAPER.evaluation.trials),
            (
                config.evaluation.reevaluation_trials,
                PAPER.evaluation.reevaluation_trials,
            ),
            (config.resolved_generations, paper_generations(ta.task)),
        ]
        row = [task_title(ta.task), per_treatment]
        if not with_paper:
            rows.append(row + [str(ours) for ours, _ in sizes])
            continue
        paper_gens = paper_generations(ta.task)
        if paper_gens is None:
            # A task the paper did not run: nothing of the paper's to compare.
            rows.append(row + [f"{ours} (-)" for ours, _ in sizes] + ["-"])
            continue
        ours = (
            config.ga.population_size
            * config.evaluation.trials
            * config.resolved_generations
        )
        paper = PAPER.ga.population_size * PAPER.evaluation.trials * paper_gens
        rows.append(
            row
            + [f"{mine} ({theirs})" for mine, theirs in sizes]
            + [f"{100 * ours / paper:.2g} %"]
        )
    header = ["task", "usable runs"]
    header += ["population", "trials", "re-evaluation trials", "generations"]
    if with_paper:
        header = [
            "task",
            f"usable runs (paper: {PAPER_RUNS} each)",
            *(f"{h} (paper)" for h in header[2:]),
            "trials per run, share of the paper's",
        ]
    return markdown_table(header, rows)


def session_wall_seconds(sessions: list[dict]) -> float:
    """Time during which at least one of ``sessions`` (study log entries) ran: the
    union of their [started, started + elapsed_s] intervals. Sessions one after
    another add up; shards run at once count once."""
    spans = []
    for session in sessions:
        elapsed = float(session.get("elapsed_s", 0.0))
        try:
            start = datetime.fromisoformat(session["started"]).timestamp()
        except (KeyError, TypeError, ValueError):
            return sum(float(s.get("elapsed_s", 0.0)) for s in sessions)
        spans.append((start, start + elapsed))
    total, reached = 0.0, -math.inf
    for start, end in sorted(spans):
        if end > reached:
            total += end - max(start, reached)
            reached = end
    return total


def _wall_times(analysis: Analysis) -> list[str]:
    rows = []
    for ta in analysis.tasks:
        sessions = [s for s in analysis.sessions if s.get("task") == ta.task]
        if sessions:
            hows = Counter(
                f"{s.get('evaluator', '?')} x{s.get('concurrent_runs', '?')} on "
                f"{s.get('cpu_count', '?')} cores"
                + (
                    f", up to {s['joined_runs']} runs joined"
                    if s.get("joined_runs", 1) > 1
                    else ""
                )
                + (" (shards)" if s.get("shard") else "")
                + (" (interrupted)" if s.get("interrupted") else "")
                for s in sessions
            )
            how = ", ".join(
                h if n == 1 else f"{h} ({n} sessions)" for h, n in hows.items()
            )
            rows.append(
                [
                    task_title(ta.task),
                    _minutes(session_wall_seconds(sessions)),
                    str(len(sessions)),
                    how,
                ]
            )
        else:
            rows.append(
                [
                    task_title(ta.task),
                    f"not logged (runs' own wall time, summed: "
                    f"{_minutes(ta.cost.run_seconds)})",
                    "0",
                    "",
                ]
            )
    return markdown_table(["task", "wall time", "sessions", "how"], rows)


def _interval(test: PairTest | None) -> str:
    if test is None:
        return ""
    return f"{test.effect:.2f} [{test.effect_low:.2f}, {test.effect_high:.2f}]"


def _claims_table(claims: list[Claim]) -> list[str]:
    rows = [
        [
            str(i + 1),
            c.statement,
            c.paper,
            c.ours,
            _p(c.p),
            "" if c.test is None else _p(c.test.p_holm),
            _interval(c.test),
            f"**{c.verdict.value}**",
        ]
        for i, c in enumerate(claims)
    ]
    return markdown_table(
        ["#", "claim", "paper", "ours", "our p", "Holm p", "A [95 % CI]", "verdict"],
        rows,
    )


def _rules_text(alpha: float) -> str:
    low, high = EQUIVALENCE_MARGIN
    return (
        f"Verdicts at alpha = {alpha} on two-sided Mann-Whitney tests whose p is "
        "Holm-adjusted within each task's family of fitness tests (every pair of "
        "its treatments) and, apart, of exploration tests; A = U / (n_a n_b) is "
        "the chance that a run of the first treatment beats one of the second, "
        "with its 95 % bootstrap interval. *Agree*: a claimed difference is "
        "significant (Holm) in the paper's direction; a claim of no difference has "
        f"A's whole interval inside [{low}, {high}] (Vargha and Delaney's 'small' "
        "bounds); a claim of not below has the interval's lower end above "
        f"{low}. *Disagree*: significant (Holm) the other way. *Inconclusive*: "
        "anything else, our runs cannot tell (a p above alpha is not agreement). "
        "The rules are in `sdbc_evolution/study/claims.py`."
    )


def _totals_line(claims: list[Claim]) -> str:
    counts = totals(claims)
    shared = len(claims) - sum(counts.values())
    line = (
        f"Of {len(claims)} claims: {counts[Verdict.AGREE]} agree, "
        f"{counts[Verdict.DISAGREE]} disagree, {counts[Verdict.INCONCLUSIVE]} "
        "inconclusive"
    )
    if shared:
        line += (
            f", counting a test once where two claims rest on it with one verdict "
            f"({shared} such {'claim' if shared == 1 else 'claims'} not counted "
            "again)"
        )
    return line + "."


def _tests_table(tests: list[PairTest]) -> list[str]:
    return markdown_table(
        [
            "a",
            "b",
            "median a",
            "median b",
            "mean a",
            "mean b",
            "U",
            "A [95 % CI]",
            "p",
            "Holm p",
        ],
        [
            [
                label(t.a),
                label(t.b),
                _f(t.median_a),
                _f(t.median_b),
                _f(t.mean_a),
                _f(t.mean_b),
                _f(t.u),
                _interval(t),
                _p(t.p),
                _p(t.p_holm),
            ]
            for t in tests
        ],
    )


def _task_section(ta: TaskAnalysis, analysis: Analysis) -> list[str]:
    out = analysis.out
    title = task_title(ta.task)
    lines = [f"## {title[0].upper()}{title[1:]}", ""]
    lines += [
        f"![best fitness per generation]({_rel(ta.figures['curves'], out)}) "
        f"![best of each run]({_rel(ta.figures['bests'], out)})",
        "",
        "Left: the best individual of each generation re-evaluated in fresh trials, "
        "mean over runs, band +-1 standard error. Right: each run's best; boxes at "
        "the quartiles, whiskers at 1.5 IQR, dots are runs.",
        "",
        f"A run's best, which the tests and the fitness verdicts use: {ta.statistic}.",
        "",
        "Mann-Whitney U (two-sided) on each run's best; A = U / (n_a n_b) is the "
        "chance that a run of the first treatment beats one of the second, with its "
        "95 % bootstrap interval; Holm p is adjusted over the task's tests below.",
        "",
    ]
    lines += _tests_table(ta.tests)
    if ta.last_tests:
        lines += [
            "The same tests on each run's last generation's best (re-evaluated "
            "like its best; reported beside, deciding no verdict):",
            "",
        ]
        lines += _tests_table(ta.last_tests)
    lines += _relevance_section(ta, analysis)
    lines += _other_relevance_sections(ta, analysis)
    lines += _exploration_section(ta, analysis)
    return lines


def _relevance_section(ta: TaskAnalysis, analysis: Analysis) -> list[str]:
    table = ta.relevance
    lines = ["### Relevance of behaviour features", ""]
    if table is None:
        return lines + ["No usable NS-SD+ run: no weights to read.", ""]
    n = analysis.settings.top_features
    # Only the paper's tasks have the paper's table (Table 1) to set beside ours.
    with_paper = is_paper_task(ta.task)
    paper = {f.name: f for f in PAPER_RELEVANCE.get(ta.task, ())}
    mapping = task_specific_features(ta.task)
    lines += [
        f"Mutual information I(F; k) = weight - delta of the NS-SD+ runs "
        f"({table.runs}), averaged over each run's generations; mean and SD over "
        f"runs, bits. The {n} most relevant of {len(table.names)} dimensions"
        + (
            "; the paper's values where its table lists the feature"
            if with_paper
            else ""
        )
        + ". Tick: the task-specific characterisation has a matching feature ("
        + (
            "the task's mapping: "
            + "; ".join(
                f"{feature} = {', '.join(names)}" for feature, names in mapping.items()
            )
            if mapping
            else "the task declares no mapping, so no tick"
        )
        + "). Chance: the same estimate with each population's fitness shuffled, "
        "the estimate's own bias at population "
        f"{analysis.digest.of(ta.task)[0].config.ga.population_size} (mean over "
        f"all {len(table.names)} dimensions: {table.chance.mean():.2f} bits, "
        f"against {table.mean.mean():.2f} with the true fitness); what a "
        "feature has above it is what it shares with fitness.",
        "",
    ]
    top = table.top(n)
    rows = []
    for i, name in enumerate(top.names):
        p = paper.get(name)
        rows.append(
            [
                str(i + 1),
                name,
                f"{top.mean[i]:.2f}",
                _f(top.sd[i], 2),
                f"{top.chance[i]:.2f}",
                "yes" if top.in_task_specific[i] else "",
            ]
            + ([f"{p.mean:.2f} ({p.sd:.2f})" if p else ""] if with_paper else [])
        )
    header = ["#", "feature", "mean MI", "SD MI", "chance", "in TS char."]
    lines += markdown_table(header + (["paper mean (SD)"] if with_paper else []), rows)
    missing = [f for f in PAPER_RELEVANCE.get(ta.task, ()) if f.name not in top.names]
    notes = []
    for f in missing:
        rank = table.rank_of(f.name)
        shown = f.label or f.name
        notes.append(
            f"{shown}: {f.mean:.2f} bits in the paper, ours "
            f"{table.mean[rank - 1]:.2f} (#{rank})"
            if rank
            else f"{shown}: not an SDBC dimension here"
        )
    if notes:
        lines += ["The paper's other listed features: " + "; ".join(notes) + ".", ""]
    above = ta.relevance_above_chance
    if above is not None:
        lines += [
            f"Ranked by MI above chance (each run's MI minus its own chance level, "
            f"then mean and SD over runs, bits): the ranking the relevance claims "
            f"are judged on. The {n} most relevant:",
            "",
        ]
        best = above.top(n)
        lines += markdown_table(
            ["#", "feature", "mean above chance", "SD", "raw rank", "in TS char."],
            [
                [
                    str(i + 1),
                    name,
                    f"{best.mean[i]:.2f}",
                    _f(best.sd[i], 2),
                    f"#{table.rank_of(name)}",
                    "yes" if best.in_task_specific[i] else "",
                ]
                for i, name in enumerate(best.names)
            ],
        )
    return lines


def _other_relevance_sections(ta: TaskAnalysis, analysis: Analysis) -> list[str]:
    """One table per weighting treatment other than NS-SD+, in its measure's
    units."""
    n = analysis.settings.top_features
    lines = []
    for treatment, table in ta.other_relevance.items():
        bits = table.measure in BITS
        lines += [
            f"#### {label(treatment)}: relevance by `{table.measure}`",
            "",
            f"Weight - delta of the {label(treatment)} runs ({table.runs}), "
            "averaged over each run's generations; mean and SD over runs"
            + (", bits" if bits else "")
            + f". The {n} most relevant of {len(table.names)} dimensions."
            + (
                " Chance: the MI's chance level on the same populations (as in "
                "the NS-SD+ table)"
                + (
                    ", which this measure subtracts from the MI at every "
                    "generation (keeping at least 0)"
                    if table.measure == "mi_chance"
                    else ""
                )
                + "."
                if bits
                else ""
            ),
            "",
        ]
        top = table.top(n)
        rows = [
            [str(i + 1), name, f"{top.mean[i]:.2f}", _f(top.sd[i], 2)]
            + ([f"{top.chance[i]:.2f}"] if bits else [])
            + ["yes" if top.in_task_specific[i] else ""]
            for i, name in enumerate(top.names)
        ]
        header = ["#", "feature", "mean", "SD"] + (["chance"] if bits else [])
        lines += markdown_table(header + ["in TS char."], rows)
    return lines


def _exploration_section(ta: TaskAnalysis, analysis: Analysis) -> list[str]:
    maps = ta.maps
    s = maps.settings
    lines = [
        "### Behaviour-space exploration",
        "",
        f"![exploration maps]({_rel(ta.figures['exploration'], analysis.out)})",
        "",
        f"A {s.rows} x {s.columns} SOM trained on {maps.sample_count} z-scored SDBC "
        "vectors sampled evenly from every run (all generations, all treatments); "
        "circle area: mean share of the treatment's individuals in the unit over its "
        f"runs; colour: {s.fitness_percentile:g}th fitness percentile of those "
        f"individuals; red rings: the high-fitness region (the "
        f"{100 * s.high_fitness_units:g} % of occupied units with the highest "
        "percentile over all treatments"
        + _region_floor(ta.task, maps)
        + "). Quantisation error "
        f"{maps.quantisation_error:.2f} (z units); seed {s.seed}. How much the "
        "numbers depend on the map is below the table.",
        "",
    ]
    rows = []
    for k, t in enumerate(maps.treatments):
        u, c, h = maps.uniformity(k), maps.coverage(k), maps.region_share(k)
        rows.append(
            [
                label(t),
                str(u.size),
                f"{u.mean():.3f} +- {_sd(u):.3f}",
                f"{c.mean():.3f} +- {_sd(c):.3f}",
                f"{h.mean():.3f} +- {_sd(h):.3f}",
            ]
        )
    lines += markdown_table(
        [
            "treatment",
            "runs",
            "uniformity (normalised entropy)",
            "units visited (share)",
            "share in high-fitness region",
        ],
        rows,
    )
    return lines + _sensitivity_section(ta)


def _share_range(values: np.ndarray) -> str:
    return f"{values.min():.3f}-{values.max():.3f}"


def _sensitivity_section(ta: TaskAnalysis) -> list[str]:
    by_kind = {found.kind: found for found in ta.sensitivity}
    task = ta.task
    lines = ["#### How much the exploration numbers depend on the map", ""]
    found = by_kind.get(MAP)
    if found is None:
        lines += [
            "The SOM's seed and grid: not measured. This digest holds one map "
            "and not the SDBC vectors another one needs (`sdbc-study analyse "
            "STUDY --som-seeds N` measures it from the run directories).",
            "",
        ]
    else:
        seeds = sorted({x.seed for x in found.settings})
        grids = list(dict.fromkeys((x.rows, x.columns) for x in found.settings))
        lines += [
            f"The map trained again with seeds {seeds[0]}-{seeds[-1]} on grids "
            + ", ".join(f"{r} x {c}" for r, c in grids)
            + f" ({len(found.settings)} maps; the other settings as above; "
            f"`tables/exploration_sensitivity_{task}.csv`). Mean share in the "
            "high-fitness region, per treatment: on this map, its range over the "
            "seeds of each grid, and its SD over all the maps:",
            "",
        ]
        columns = [
            [n for n, x in enumerate(found.settings) if (x.rows, x.columns) == g]
            for g in grids
        ]
        lines += markdown_table(
            ["treatment", "this map"]
            + [f"{r} x {c}" for r, c in grids]
            + ["SD over maps"],
            [
                [label(t), f"{found.on_map[k]:.3f}"]
                + [_share_range(found.shares[k, c]) for c in columns]
                + [f"{np.std(found.shares[k], ddof=1):.3f}"]
                for k, t in enumerate(found.treatments)
            ],
        )
        if found.claims:
            lines += [
                "Each exploration claim judged again on every map (the same rules, "
                f"Holm over the task's exploration tests on each; "
                f"`tables/exploration_stability_{task}.csv`):",
                "",
            ]
            lines += markdown_table(
                [
                    "claim",
                    "this map",
                    "same verdict on",
                    "agree / disagree / inconclusive",
                ],
                [
                    [
                        c.statement,
                        c.verdict.value,
                        f"{c.same} of {len(c.verdicts)} maps",
                        " / ".join(str(c.count(v)) for v in Verdict),
                    ]
                    for c in found.claims
                ],
            )
    found = by_kind.get(REGION)
    if found is not None:
        lines += [
            "The high-fitness region's size, on this map (mean share per "
            "treatment with the region made of each fraction of the occupied "
            "units):",
            "",
        ]
        heads = [f"{100 * x.fraction:g} %" for x in found.settings]
        lines += markdown_table(
            ["treatment", *heads],
            [
                [label(t)] + [f"{v:.3f}" for v in found.shares[k]]
                for k, t in enumerate(found.treatments)
            ],
        )
        if found.claims:
            lines += markdown_table(
                ["claim", *heads],
                [[c.statement] + [v.value for v in c.verdicts] for c in found.claims],
            )
    return lines


def _region_floor(task: str, maps: ExplorationMaps) -> str:
    floor = deceptive_optimum(task)
    if floor is None:
        return ""
    region = maps.pooled_percentile[maps.region]
    start = f"; it starts at {region.min():.4g}" if region.size else "; no unit is"
    return (
        f", and only those above the task's deceptive optimum {floor:.4g}, which a "
        f"team that never charges reaches{start}"
    )


def _sd(x: np.ndarray) -> float:
    return float(np.std(x, ddof=1)) if x.size > 1 else float("nan")


def _physics_difference(config: ExperimentConfig) -> str:
    """The bullet on how the study's robots move (``evaluation.physics``), beside
    the authors' kinematic robots."""
    if config.evaluation.physics == "kinematic":
        return (
            "- **Physics.** Our robots move as the authors' did (`evaluation.physics: "
            "kinematic`): turn, then move; a move that would overlap is refused and "
            "retried sideways at half speed, and nobody pushes anybody. Four details "
            "differ from their code (docs/reference-setup.md): the first sidestep is "
            "always to the left (theirs draws the side at random); both sidesteps go "
            "at half the commanded speed (their second at 0.5 units per step); walls "
            "are segments a robot keeps clear of (their gate lets a robot's centre "
            "through its whole opening); and robots move in a fixed order (MASON "
            "shuffles it every step)."
        )
    return (
        "- **Physics.** Our robots are pymunk bodies colliding through chipmunk's "
        "solver; the authors' robots were kinematic (turn, then move; a blocked move "
        "refused or retried sideways). Pushing, sliding along walls and jams differ, "
        "and with them the fitness landscape and the behaviours there are to find. "
        "Where the paper is silent the engine follows the authors' code: a robot "
        "moves in the step it is told (the commanded velocity is written before "
        "chipmunk's step), and in resource sharing a stop freezes the heading and "
        "the charging input means 'in the station'. These are the defaults since "
        "2026-12-01; studies made before drove robots by force (a robot moved one "
        "step after it was told), let a stopped robot turn and sensed 'charged at "
        "the last step'. What "
        "remains: a teammate can push a docked robot off the station (an option, "
        "`anchor_docked`, refuses that, but was off here), and contacts go through "
        "the solver rather than being refused."
    )


def _differences(analysis: Analysis) -> list[str]:
    claims = analysis.claims
    study = analysis.digest
    tasks = [ta.task for ta in analysis.tasks if is_paper_task(ta.task)]
    some = study.of(tasks[0])[0].config
    runs = Counter((r.task, r.treatment) for r in study.runs if r.task in tasks)
    least = min(runs.values())
    generations = " / ".join(
        str(study.of(t)[0].config.resolved_generations) for t in tasks
    )
    paper_gens = " / ".join(str(paper_generations(t) or "?") for t in tasks)
    lines = [
        "## Where we differ, and why we might",
        "",
        _totals_line(claims),
        "",
    ]
    disagreements = [c for c in claims if c.verdict is Verdict.DISAGREE]
    if disagreements:
        lines += ["Disagreements:", ""]
        lines += [f"- {c.statement}: {c.ours}." for c in disagreements]
        lines += [""]
    lines += _plateau(analysis)
    lines += [
        "Reasons that apply to every number above:",
        "",
        f"- **Scale.** Runs here have population {some.ga.population_size}, "
        f"{some.evaluation.trials} trials and {generations} generations, against "
        f"the paper's {PAPER.ga.population_size}, {PAPER.evaluation.trials} and "
        f"{paper_gens}; and as few as {least} runs per treatment against "
        f"{PAPER_RUNS}. Differences that need long evolution to open up (the paper's "
        "NS-TS vs NS-SD+ gap is 'relatively small') cannot show, and a Mann-Whitney "
        "test on so few runs has little power: *inconclusive* means our runs cannot "
        "tell, not that the paper is wrong.",
        _physics_difference(some),
        "- **Task details.** The paper's parameter table is lost; the tasks follow "
        "docs/reference-setup.md, i.e. the authors' code where the paper is silent, "
        "and the paper's fitness formulas (gate escape uses (g + t/tau)/(1 + N), "
        "not the code's variant).",
        "- **Mutual information.** Fitness in 10 k-means clusters, features in 10 "
        "equal-width bins, estimated on one population of "
        f"{some.ga.population_size}: with few individuals per cell the plug-in "
        "estimate is biased upwards and its scale is not the paper's (a Weka "
        "discretisation on 200 individuals); compare ranks rather than bits. The "
        "chance column of each relevance table measures that bias; where it is close "
        "to the MI, NS-SD+'s weights are mostly noise.",
        "- **Curves.** Re-evaluation in "
        f"{some.evaluation.reevaluation_trials} fresh trials (the paper: up to "
        f"{PAPER.evaluation.reevaluation_trials}), harmonic mean as in the authors' "
        "code.",
        "- **Maps.** minisom instead of R's kohonen, fitness percentile "
        f"{analysis.settings.som.fitness_percentile:g} as in the authors' scripts; "
        "the high-fitness region is our explicit rule where the paper circled one by "
        "eye. With short runs, early (random) generations weigh more in every map.",
        "",
    ]
    return lines


def _plateau(analysis: Analysis) -> list[str]:
    """Resource sharing's deceptive optimum, and how many runs ended on it."""
    study = analysis.digest
    if "resource_sharing" not in study.tasks():
        return []
    task = study.task("resource_sharing")
    finals = {t: [r.curve[-1] for r in task.of(t)] for t in task.treatments()}
    on = {
        t: sum(abs(v - NO_CHARGE_OPTIMUM) <= PLATEAU_MARGIN for v in f)
        for t, f in finals.items()
    }
    above = {
        t: sum(v > NO_CHARGE_OPTIMUM + PLATEAU_MARGIN for v in f)
        for t, f in finals.items()
    }
    per = "; ".join(
        f"{label(t)} {on[t]} on it, {above[t]} above, of {len(finals[t])}"
        for t in finals
    )
    return [
        "Resource sharing's plateau is a deceptive optimum of its fitness, ours and "
        "the authors' alike: F_s averages energy over the trial's actual length, so "
        "the best team that never charges stands still for 200 steps and then "
        "drives flat out to die sooner, at step 345, for F = "
        f"{NO_CHARGE_OPTIMUM:.6f} (worked out in `sdbc_sim/tasks/resource_sharing.py`"
        " and tested through the engine). The harmonic mean over trials makes "
        "leaving it fragile: a controller that charges in one trial of five scores "
        "below the plateau unless it charges well. Runs whose last best "
        f"(re-evaluated) is within {PLATEAU_MARGIN} of it, and above it: {per}.",
        "",
    ]


def _projection(analysis: Analysis) -> list[str]:
    with_paper = any(is_paper_task(ta.task) for ta in analysis.tasks)
    lines = [
        "## Cost, and the paper's study on a cluster" if with_paper else "## Cost",
        "",
        "Measured in the run directories (`wall_time`, `evaluation_time`, trial "
        "lengths from the SDBC's 'Simulation length', workers from `study_run.json`); "
        "a robot-step is one body of one trial advanced one step. Rates are those "
        "of this study's batch sizes; the engine does more per step on the paper's "
        "larger batches (2000 trials a generation), so the projection errs on the "
        "long side.",
        "",
    ]
    lines += markdown_table(
        [
            "task",
            "runs",
            "robot-steps/s per worker",
            "s per generation (ours)",
            "generations/s",
            "serial s per individual",
            "mean trial length (max)",
        ],
        [
            [
                task_title(c.task),
                str(c.runs),
                f"{c.rate:,.0f}",
                f"{c.seconds_per_generation:.3f}",
                f"{c.generations_per_second:.2f}",
                f"{c.serial_per_individual * 1e3:.2f} ms",
                f"{c.mean_length:.0f} ({c.max_steps})",
            ]
            for c in (ta.cost for ta in analysis.tasks)
        ],
    )
    if not analysis.projections:
        return lines
    lines += [
        "Projected wall time of the `paper` preset (docs/reference-setup.md: 20 runs "
        "x 4 treatments, population 200, 10 trials, 50 re-evaluation trials, "
        "500/750/750 generations) run by "
        "`sdbc-study run --preset paper --scheduler ADDRESS` on a "
        "Dask cluster of W workers, runs one after the other, each generation's "
        "controllers spread over min(W, 200) workers: T(W) = runs x treatments x G x "
        "(c N + B L (N T + T_r) / (r min(W, N))), r and c as measured above, L the "
        "measured mean trial length (expected) or max_steps (bound). Dask's overhead "
        "and longer or shorter trials of better-evolved controllers are not "
        "modelled. Run side by side instead, one single-core job per share of the "
        "runs (`--shard K/N`, docs/study/README.md), the study takes about CPU "
        "hours / W on W cores, and no less than its longest run (hours per run).",
        "",
    ]
    workers = sorted({p.workers for p in analysis.projections})
    by_task: dict[str, dict[int, Projection]] = {}
    for p in analysis.projections:
        by_task.setdefault(p.task, {})[p.workers] = p
    # CPU hours and runs do not depend on W: any projection of the task has them.
    task_wide = {task: next(iter(values.values())) for task, values in by_task.items()}
    rows = []
    for task, values in by_task.items():
        some = task_wide[task]
        rows.append(
            [
                task_title(task),
                f"{some.cpu_hours:,.0f}",
                f"{some.cpu_hours / some.runs:,.1f}",
            ]
            + [
                f"{values[w].expected_hours:,.1f} ({values[w].bound_hours:,.1f})"
                for w in workers
            ]
        )
    rows.append(
        [
            "**all tasks**",
            f"{sum(p.cpu_hours for p in task_wide.values()):,.0f}",
            f"{max(p.cpu_hours / p.runs for p in task_wide.values()):,.1f}",
        ]
        + [
            f"{sum(by_task[t][w].expected_hours for t in by_task):,.1f} "
            f"({sum(by_task[t][w].bound_hours for t in by_task):,.1f})"
            for w in workers
        ]
    )
    lines += markdown_table(
        ["task", "CPU hours", "hours per run"]
        + [f"hours on W = {w} (bound)" for w in workers],
        rows,
    )
    return lines


def _preset_line(analysis: Analysis) -> list[str]:
    preset = analysis.digest.preset
    if analysis.digest.preset_error is not None:
        return [f"`{STUDY_FILE}` unreadable: {analysis.digest.preset_error}", ""]
    if preset is None:
        return [f"No `{STUDY_FILE}`: the runs were not made by `sdbc-study run`.", ""]
    return [
        f"Preset **{preset.name}** (study seed {preset.seed}): {preset.description}",
        "",
    ]


def _problem_lines(problems: list[RunProblem], tasks_with_runs: set[str]) -> list[str]:
    """One line per run left out, except a task not run at all: one line for it."""
    by_task: dict[str, list[RunProblem]] = {}
    for problem in problems:
        by_task.setdefault(problem.name.split("/")[0], []).append(problem)
    lines = []
    for task, group in by_task.items():
        if task not in tasks_with_runs and all(p.reason == MISSING for p in group):
            lines.append(f"- `{task}`: not run yet ({len(group)} runs missing)")
        else:
            lines += [f"- `{p.name}`: {p.reason}" for p in group]
    return lines


def write_report(
    analysis: Analysis, path: Path, command: list[str] | None = None
) -> Path:
    """Writes the Markdown report of ``analysis`` to ``path``."""
    study = analysis.digest
    paper_tasks = [ta.task for ta in analysis.tasks if is_paper_task(ta.task)]
    if paper_tasks:
        lines = [
            "# Replication of Gomes, Mariano & Christensen (ALIFE 2014): our numbers",
            "",
            "Novelty search with systematically derived behaviour characterisations "
            "(SDBC), replicated with sdbc. Every number, table and figure below "
            "comes from the run directories of the study, through its digest "
            "(`digest/`, from which `sdbc-study analyse --from-digest` makes them "
            "again); the paper's claims are set beside ours one by one.",
            "",
        ]
    else:
        # No task of the paper's: nothing of the paper's applies.
        lines = [
            "# A study with sdbc: "
            + ", ".join(task_title(ta.task) for ta in analysis.tasks),
            "",
            "Novelty search with systematically derived behaviour characterisations "
            "(SDBC) on tasks the paper did not run, so no claim or number of the "
            "paper is set beside ours. Every number, table and figure below comes "
            "from the run directories of the study, through its digest (`digest/`, "
            "from which `sdbc-study analyse --from-digest` makes them again).",
            "",
        ]
    lines += _preset_line(analysis)
    lines += ["## What ran", ""]
    lines += _sizes(analysis)
    lines += [
        "Wall time per task, from the study log (`study_log.jsonl`): the time "
        "during which some session of the task ran.",
        "",
    ]
    lines += _wall_times(analysis)
    shown = [shlex.join(s["command"]) for s in analysis.sessions if s.get("command")]
    # The analysis that made the digest; a report made again from the digest
    # (--from-digest) is the same report, so its own command is not added.
    analysis_command = list(study.command) or list(command or ())
    if analysis_command:
        shown.append(shlex.join(analysis_command))
    commands = list(dict.fromkeys(shown))
    if commands:
        lines += [
            f"Commands (a run's `--out` given as the study directory analysed, "
            f"`{study.study_dir}`):",
            "",
            "```",
        ]
        lines += commands
        lines += ["```", ""]
    expected = f" of {study.expected} expected" if study.expected is not None else ""
    lines += [f"{len(study.runs)} usable runs{expected}.", ""]
    if analysis.problems:
        lines += ["Runs left out:", ""]
        lines += _problem_lines(analysis.problems, set(study.tasks()))
        lines += [""]
    if analysis.predictions:
        lines += _predictions_section(analysis)
    if paper_tasks:
        lines += _claims_section(analysis)
    for ta in analysis.tasks:
        lines += _task_section(ta, analysis)
    if paper_tasks:
        lines += _differences(analysis)
    lines += _projection(analysis)
    path.write_text("\n".join(lines))
    return path


def _claims_section(analysis: Analysis) -> list[str]:
    lines = ["## The paper's claims, one by one", ""]
    lines += [
        _rules_text(analysis.settings.alpha),
        "",
    ]
    for topic, heading in CLAIM_TOPICS.items():
        claims = [c for c in analysis.claims if c.topic == topic]
        if claims:
            lines += [f"### {heading}", ""]
            lines += _claims_table(claims)
    others = [ta.task for ta in analysis.tasks if not is_paper_task(ta.task)]
    if others:
        lines += [
            "The paper did not run "
            + ", ".join(task_title(t) for t in others)
            + ": no claim of the paper applies there.",
            "",
        ]
    return lines


def _predictions_section(analysis: Analysis) -> list[str]:
    lines = [
        "## The study's predictions",
        "",
        "What the study's preset predicts, judged on each run's best fitness "
        "by the rules of the paper's claims: *held* where a claim would agree, "
        "*did not hold* where it would disagree, *cannot tell* otherwise. "
        + _rules_text(analysis.settings.alpha)
        + " (`judge_predictions`).",
        "",
    ]
    rows = [
        [
            str(i + 1),
            r.prediction.statement,
            task_title(r.task),
            r.prediction.rule_text(),
            r.evidence,
            _p(r.p),
            "" if r.test is None else _p(r.test.p_holm),
            _interval(r.test),
            f"**{r.outcome}**",
        ]
        for i, r in enumerate(analysis.predictions)
    ]
    lines += markdown_table(
        [
            "#",
            "prediction",
            "task",
            "rule",
            "ours",
            "p",
            "Holm p",
            "A [95 % CI]",
            "outcome",
        ],
        rows,
    )
    return lines

"""The study's figures, as PNG files (matplotlib, no display needed).

- ``curves_<task>.png``: best fitness per generation, mean over runs with a band of
  +-1 standard error (the paper's figure 2, left);
- ``bests_<task>.png``: boxplots of each run's best, whiskers at 1.5 IQR, runs as
  dots (figure 2, right);
- ``exploration_<task>.png``: one SOM panel per treatment, circle area proportional
  to the mean share of the treatment's individuals in the unit, colour the unit's
  fitness percentile, one colour scale for all panels; the high-fitness region
  outlined (figure 3).
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np

from sdbc_evolution.ga.treatments import label
from sdbc_evolution.study.exploration import ExplorationMaps
from sdbc_evolution.study.paper import task_title
from sdbc_evolution.study.quality import Curves

COLOURS = {
    "fit": "#555555",
    "ns-ts": "#1f77b4",
    "ns-sd": "#ff7f0e",
    "ns-sd+": "#2ca02c",
}
"""The paper's treatments' colours, in every figure."""
OTHER_COLOURS = ("#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf")
"""Colours of other treatments, in the order a study lists them."""


def colour(treatment: str, treatments: tuple[str, ...] | list[str]) -> str:
    """A treatment's colour among a figure's ``treatments``: the paper's four keep
    theirs; the others take :data:`OTHER_COLOURS` in the order they are listed (a
    task's figures list them in one order), then grey shades."""
    if treatment in COLOURS:
        return COLOURS[treatment]
    others = [t for t in treatments if t not in COLOURS]
    k = others.index(treatment)
    if k < len(OTHER_COLOURS):
        return OTHER_COLOURS[k]
    return str(0.3 + 0.5 * ((k - len(OTHER_COLOURS)) % 5) / 4)


DPI = 120
"""Resolution of the PNG files."""
MAX_CIRCLE_AREA = 160.0
"""Area (points^2) of the circle of the largest mean share in any panel."""


def _pyplot() -> ModuleType:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_curves(curves: Curves, path: Path) -> Path:
    """Plots the best fitness per generation of every treatment (mean, +-1 standard
    error) to ``path``; returns ``path``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    x = curves.generations
    for i, treatment in enumerate(curves.treatments):
        line_colour = colour(treatment, curves.treatments)
        legend = f"{label(treatment)} (n = {int(curves.n[i].max())})"
        ax.plot(x, curves.mean[i], color=line_colour, label=legend, linewidth=1.4)
        se = np.nan_to_num(curves.se[i])
        ax.fill_between(
            x, curves.mean[i] - se, curves.mean[i] + se, color=line_colour, alpha=0.2
        )
    ax.set_xlabel("generation")
    source = "re-evaluated" if "reevaluated" in "".join(curves.sources) else "selected"
    ax.set_ylabel(f"best fitness ({source})")
    ax.set_title(f"{task_title(curves.task)}: mean +- SE over runs")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def plot_bests(task: str, bests: dict[str, np.ndarray], path: Path) -> Path:
    """Plots each run's best fitness as one boxplot per treatment to ``path``; returns
    ``path``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(4.8, 4.0))
    treatments = list(bests)
    data = [bests[t] for t in treatments]
    box = ax.boxplot(data, whis=1.5, showfliers=False, patch_artist=True)
    ax.set_xticks(range(1, len(treatments) + 1), [label(t) for t in treatments])
    for patch, t in zip(box["boxes"], treatments, strict=True):
        patch.set_facecolor(colour(t, treatments))
        patch.set_alpha(0.35)
    jitter = np.random.default_rng(0)
    for i, values in enumerate(data):
        ax.scatter(
            i + 1 + jitter.uniform(-0.12, 0.12, values.size),
            values,
            s=12,
            color=colour(treatments[i], treatments),
            zorder=3,
        )
    ax.set_ylabel("best fitness of the run")
    ax.set_title(task_title(task))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def plot_exploration(maps: ExplorationMaps, path: Path) -> Path:
    """Plots one SOM exploration map per treatment to ``path``; returns ``path``."""
    plt = _pyplot()
    rows, columns = maps.settings.rows, maps.settings.columns
    k = len(maps.treatments)
    fig, axes = plt.subplots(
        1, k, figsize=(2.8 * k + 1.2, 3.4), squeeze=False, layout="constrained"
    )
    uy, ux = np.divmod(np.arange(maps.settings.units), columns)
    finite = maps.percentile[np.isfinite(maps.percentile)]
    vmin, vmax = (float(finite.min()), float(finite.max())) if finite.size else (0, 1)
    if vmax <= vmin:
        vmax = vmin + 1e-9
    scale = MAX_CIRCLE_AREA / max(float(maps.mean_share.max()), 1e-12)
    mappable = None
    for i, treatment in enumerate(maps.treatments):
        ax = axes[0, i]
        share = maps.mean_share[i]
        shown = share > 0
        mappable = ax.scatter(
            ux[shown],
            uy[shown],
            s=share[shown] * scale,
            c=maps.percentile[i][shown],
            cmap="viridis",
            vmin=vmin,
            vmax=vmax,
            linewidths=0,
        )
        ax.scatter(
            ux[maps.region],
            uy[maps.region],
            s=MAX_CIRCLE_AREA * 0.6,
            facecolors="none",
            edgecolors="red",
            linewidths=0.6,
        )
        ax.set_xlim(-1, columns)
        ax.set_ylim(-1, rows)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"{label(treatment)} ({maps.shares[i].shape[0]} runs)", fontsize=9)
    if mappable is not None:
        bar = fig.colorbar(mappable, ax=axes[0, -1], shrink=0.8)
        bar.set_label(f"fitness, {maps.settings.fitness_percentile:g}th percentile")
    fig.suptitle(
        f"{task_title(maps.task)}: behaviour-space exploration "
        f"({rows} x {columns} SOM; red: high-fitness region)",
        fontsize=10,
    )
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path

"""A look at one trial: an animated GIF of its task state.

Drawing is generic: every entity group of the task state is drawn from its
geometry (circles, points, polygons), and every body from the physics with a line
for its heading, so a new task renders without code of its own.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

from sdbc_sim.engine import EngineSettings, TrialStepper  # noqa: E402
from sdbc_sim.network import check_genomes, forward  # noqa: E402
from sdbc_sim.task import Task  # noqa: E402
from sdbc_sim.task_state import Geometry, GroupState, TaskState  # noqa: E402

_COLOURS = plt.rcParams["axes.prop_cycle"].by_key()["color"]


def record_trial(
    task: Task, genome: np.ndarray, seed: int, settings: EngineSettings | None = None
) -> tuple[list[TaskState], list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """Runs one trial and keeps its task state and its bodies after every step.

    Returns:
        (states, bodies), bodies as (position (R, 2), angle (R,), enabled (R,))
        per step; the first entry of each is the start.
    """
    genome = check_genomes(np.asarray(genome)[None], task.network)[0]
    stepper = TrialStepper(task, settings)
    stepper.reset(seed)
    states: list[TaskState] = []
    bodies = []

    def keep() -> None:
        b = stepper.sim.bodies
        bodies.append((b.position[0].copy(), b.angle[0].copy(), b.enabled[0].copy()))

    keep()
    while not stepper.done:
        stepper.step(forward(genome, task.network, stepper.sensors()))
        state = stepper.state()
        states.append(_copy_state(state))
        keep()
    return states, bodies


def _first_trial(array: np.ndarray | None) -> np.ndarray | None:
    return None if array is None else np.array(array[:1], copy=True)


def _copy_state(state: TaskState) -> TaskState:
    groups = tuple(
        GroupState(
            present=np.array(g.present[:1], copy=True),
            attributes=np.array(g.attributes[:1], copy=True),
            centres=_first_trial(g.centres),
            radii=_first_trial(g.radii),
            segments=_first_trial(g.segments),
        )
        for g in state.groups
    )
    return TaskState(step=state.step, active=state.active.copy(), groups=groups)


def render_trial(
    task: Task,
    genome: np.ndarray,
    seed: int,
    path: str | Path,
    *,
    every: int = 5,
    fps: int = 20,
    settings: EngineSettings | None = None,
) -> Path:
    """Renders one trial of ``genome`` to an animated GIF.

    Args:
        task: The task.
        genome: (W,) network weights.
        seed: Seed of the trial's initial conditions.
        path: Where to write the GIF.
        every: Draw one step in this many (and always the last).
        fps: Frames per second of the GIF.
        settings: Engine settings.

    Returns:
        The path written.
    """
    if every < 1 or fps < 1:
        raise ValueError(f"render: every and fps must be >= 1, got {every}, {fps}")
    states, bodies = record_trial(task, genome, seed, settings)
    frames = list(range(0, len(states), every))
    if frames[-1] != len(states) - 1:
        frames.append(len(states) - 1)
    x0, y0, x1, y1 = task.extent
    fig, ax = plt.subplots(figsize=(5, 5), dpi=80)
    radii = np.asarray(task.layout.radii)

    def draw(k: int) -> None:
        ax.clear()
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        state = states[k]
        for g, (spec, group) in enumerate(
            zip(task.description.groups, state.groups, strict=True)
        ):
            colour = _COLOURS[g % len(_COLOURS)]
            present = np.broadcast_to(group.present, (1, spec.max_size))[0]
            if spec.geometry is Geometry.POLYGON:
                segments = group.shapes("segments")
                segs = np.broadcast_to(segments, (1, *segments.shape[1:]))[0]
                lines = segs[present].reshape(-1, 2, 2)
                ax.add_collection(
                    LineCollection(list(lines), colors=colour, linewidths=2)
                )
            else:
                centres = group.shapes("centres")[0][present]
                if spec.geometry is Geometry.CIRCLE:
                    radii_of = group.shapes("radii")
                    rr = np.broadcast_to(radii_of, (1, spec.max_size))[0][present]
                    for c, r in zip(centres, rr, strict=True):
                        ax.add_patch(Circle(c, r, color=colour, alpha=0.5))
                else:
                    ax.plot(centres[:, 0], centres[:, 1], "x", color=colour)
        pos, angle, enabled = bodies[k + 1]
        tips = pos + radii[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)
        heading = np.stack([pos, tips], axis=1)
        ax.add_collection(
            LineCollection(
                list(heading),
                colors=np.where(enabled, "k", "0.7").tolist(),
                linewidths=1,
            )
        )
        for p, r, on in zip(pos, radii, enabled, strict=True):
            ax.add_patch(Circle(p, r, fill=False, color="k" if on else "0.7"))
        names = ", ".join(s.name for s in task.description.groups)
        ax.set_title(f"{task.name}  step {state.step}  ({names})", fontsize=9)

    animation = FuncAnimation(fig, draw, frames=frames)
    path = Path(path)
    animation.save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return path

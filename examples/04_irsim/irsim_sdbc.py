"""Tutorial 04: SDBCs and novelty search in another Python simulator, ir-sim, without
writing a sdbc Task.

ir-sim runs the world of ``world.yaml`` (three differential-drive robots with 2D
lidars, three round obstacles, a goal across the room) headless. This script only
adds what sdbc needs to know about it:

1. a **task description**: the entity groups ``Robot`` (x, y, linear speed,
   turning speed, collided), ``Obstacle`` and ``Goal``, with their sizes and shapes;
2. after every ir-sim step, a **task state**: those groups' attributes and
   positions, read from ir-sim's objects;
3. a controller: one small neural network shared by the team, its weights the
   genome, reading each robot's lidar and the goal's bearing and distance.

From the description alone, ``SdbcExtractor`` derives each trial's behaviour
characterisation, and ``NoveltySearch`` (ask/tell) evolves the controller with NS-SD,
the paper's novelty search over the SDBC (standardisation against population and
archive, NSGA-II on fitness and novelty, the paper's GA).

    python examples/04_irsim/irsim_sdbc.py            # --generations, --population
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import irsim
import numpy as np
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
)

from sdbc_evolution import GaConfig, NoveltyConfig, NoveltySearch, SdbcExtractor

WORLD = Path(__file__).resolve().parent / "world.yaml"
ROBOTS, OBSTACLES = 3, 3
STEPS = 80
"""Control steps of a trial (8 s of ir-sim time at its 0.1 s step)."""
BEAMS = 8
"""Lidar beams per robot (world.yaml)."""
INPUTS = BEAMS + 4
"""Network inputs: the lidar ranges, the goal's bearing (sin, cos) and distance,
and a bias."""
GENOME_LENGTH = INPUTS * 2
"""A single-layer network: (linear, angular) velocity = tanh(W @ inputs)."""
MAX_SPEED = np.array([1.0, 1.5])
"""Linear and angular speed limits (world.yaml's vel_max)."""

DESCRIPTION = TaskDescription(
    name="irsim_goal_crossing",
    groups=(
        EntityGroupSpec(
            name="Robot",
            attributes=("x", "y", "linear speed", "turning speed", "collided"),
            min_size=ROBOTS,
            max_size=ROBOTS,
            static=False,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Obstacle",
            attributes=(),
            min_size=OBSTACLES,
            max_size=OBSTACLES,
            static=True,
            geometry=Geometry.CIRCLE,
        ),
        EntityGroupSpec(
            name="Goal",
            attributes=(),
            min_size=1,
            max_size=1,
            static=True,
            geometry=Geometry.POINT,
        ),
    ),
)
"""What sdbc knows of the world: nothing else goes into the SDBC."""


def task_state(env: irsim.EnvBase, step: int, goal: np.ndarray) -> TaskState:
    """The world after ``step`` as a task state of one trial."""
    robots, obstacles = env.robot_list, env.obstacle_list
    pose = np.array([r.state[:3, 0] for r in robots])
    velocity = np.array([r.velocity[:2, 0] for r in robots])
    collided = np.array([float(r.collision) for r in robots])
    robot_group = GroupState(
        present=np.ones((1, ROBOTS), dtype=bool),
        attributes=np.column_stack([pose[:, :2], velocity, collided])[None],
        centres=pose[None, :, :2].copy(),
        radii=np.array([[r.radius for r in robots]]),
    )
    obstacle_group = GroupState(
        present=np.ones((1, OBSTACLES), dtype=bool),
        attributes=np.zeros((1, OBSTACLES, 0)),
        centres=np.array([[o.state[:2, 0] for o in obstacles]]),
        radii=np.array([[o.radius for o in obstacles]]),
    )
    goal_group = GroupState(
        present=np.ones((1, 1), dtype=bool),
        attributes=np.zeros((1, 1, 0)),
        centres=goal[None, None, :].copy(),
    )
    return TaskState(
        step=step,
        active=np.ones(1, dtype=bool),
        groups=(robot_group, obstacle_group, goal_group),
    )


def act(env: irsim.EnvBase, weights: np.ndarray, goal: np.ndarray) -> list[np.ndarray]:
    """Every robot's (linear, angular) velocity from its lidar and the goal."""
    actions = []
    for robot in env.robot_list:
        scan = robot.get_lidar_scan()
        ranges = np.asarray(scan["ranges"], dtype=float) / scan["range_max"]
        x, y, heading = robot.state[:3, 0]
        bearing = np.arctan2(goal[1] - y, goal[0] - x) - heading
        distance = np.hypot(goal[0] - x, goal[1] - y) / 10.0
        inputs = np.concatenate(
            [ranges, [np.sin(bearing), np.cos(bearing), distance, 1]]
        )
        actions.append((np.tanh(weights @ inputs) * MAX_SPEED)[:, None])
    return actions


def trial(genome: np.ndarray, seed: int) -> tuple[float, np.ndarray]:
    """One trial of ``genome``: its fitness and raw SDBC vector."""
    env = irsim.make(str(WORLD), headless=True, log_level="ERROR", seed=seed)
    # Starts jittered by the trial's seed: each trial sees a slightly other world.
    jitter = np.random.default_rng(seed).uniform(-0.4, 0.4, (ROBOTS, 2))
    for robot, offset in zip(env.robot_list, jitter, strict=True):
        start = robot.state[:3, 0].astype(float)
        start[:2] += offset
        robot.set_state(start[:, None], init=True)
    goal = env.robot_list[0].goal[:2, 0].astype(float)
    start_distance = np.mean(
        [np.hypot(*(r.state[:2, 0] - goal)) for r in env.robot_list]
    )
    weights = genome.reshape(2, INPUTS)
    extractor = SdbcExtractor()
    extractor.start(DESCRIPTION, 1)
    for step in range(1, STEPS + 1):
        env.step(act(env, weights, goal))
        extractor.observe(task_state(env, step, goal))
    final_distance = np.mean(
        [np.hypot(*(r.state[:2, 0] - goal)) for r in env.robot_list]
    )
    env.end(0)
    fitness = max(0.0, 1.0 - final_distance / start_distance)
    return fitness, extractor.characterisations()[0]


def evaluate(genomes: np.ndarray, seeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) fitness and (N, D) raw SDBC vectors, each averaged over its trials."""
    results = [
        [trial(g, int(s)) for s in row] for g, row in zip(genomes, seeds, strict=True)
    ]
    fitness = np.array([[f for f, _ in row] for row in results]).mean(axis=1)
    sdbc = np.array([np.mean([v for _, v in row], axis=0) for row in results])
    return fitness, sdbc


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=5)
    parser.add_argument("--population", type=int, default=8)
    parser.add_argument("--trials", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    # NS-SD: novelty search over the SDBC, standardised against population and
    # archive, ranked with fitness by NSGA-II; the paper's GA breeds.
    search = NoveltySearch(
        "ns-sd",
        genome_length=GENOME_LENGTH,
        population=args.population,
        seed=args.seed,
        ga=GaConfig(population_size=args.population, elites=1, tournament_size=2),
        novelty=NoveltyConfig(k=min(15, args.population - 1)),
    )
    print(f"SDBC of the ir-sim world: {len(dimension_names())} dimensions, e.g.")
    for name in dimension_names()[:4]:
        print(f"  {name}")
    print("generation  best fitness  mean fitness  archive")
    for generation in range(args.generations):
        genomes = search.ask()
        fitness, sdbc = evaluate(genomes, search.trial_seeds(args.trials))
        search.tell(fitness, sdbc)
        best, mean, archived = fitness.max(), fitness.mean(), len(search.archive)
        print(f"{generation:>10}  {best:>12.4f}  {mean:>12.4f}  {archived:>7}")
    return 0


def dimension_names() -> tuple[str, ...]:
    """The SDBC's dimensions, named from the task description's groups."""
    from sdbc_evolution.sdbc import dimension_names as names

    return names(DESCRIPTION)


if __name__ == "__main__":
    sys.exit(main())

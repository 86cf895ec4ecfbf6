"""An evaluator that runs every trial through the live ROS 2 graph.

It plugs into the experiment runner like the local and Dask evaluators
(:class:`sdbc_evolution.run.evaluators.Evaluator`): for each genome it sets the genome
on the controller nodes, runs the genome's trials one after another on the
simulator node, and builds the SDBC vectors from the task state topic
(:class:`~sdbc_evolution.graph.client.GraphClient`): the paper's SDBC, and that of
a declared treatment with any SDBC options. Characterisations made from the robots'
network arrays (``state_count``, ``sensor_effector_mean``) are refused when the
evaluator is made, naming them. A controller's values
sum up exactly as in :func:`sdbc_evolution.run.evaluators.evaluate_chunk`: fitness by
the engine's controller aggregate (harmonic mean by default), the task-specific
characterisation and the SDBC as arithmetic means over trials. Live and batched
evaluations of a genome then agree to round-off.

It is slow by nature (one trial at a time, paced by lockstep): it is for
inspection, recording and hardware in the loop, not for the paper's runs.
"""

from __future__ import annotations

import numpy as np
from sdbc_sim.engine import controller_fitness

from sdbc_evolution.graph.client import GraphClient, check_live_characterisations
from sdbc_evolution.run.evaluators import Evaluation, Evaluator, TaskSpec


class LiveEvaluator(Evaluator):
    """Evaluates genomes through the live graph.

    Args:
        spec: The task (must be the one the graph runs).
        client: The graph client.

    Raises:
        ValueError: A characterisation of ``spec`` cannot be made on the graph.
    """

    def __init__(self, spec: TaskSpec, client: GraphClient) -> None:
        self.others = check_live_characterisations(spec.characterisations)
        self.spec = spec
        self.client = client

    @property
    def workers(self) -> int:
        # One graph, one trial at a time.
        return 1

    def _run(
        self, genomes: np.ndarray, seeds: np.ndarray, bounds: list[tuple[int, int]]
    ) -> list[Evaluation]:
        return [self.evaluate_genomes(genomes[a:b], seeds[a:b]) for a, b in bounds]

    def evaluate_genomes(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        """Evaluates genome g in the trials ``seeds[g]``, one trial at a time."""
        n, t = seeds.shape
        fitness = np.empty((n, t))
        # Sizes come from the trials: a task of another system is known only so.
        characterisation: list[list[np.ndarray]] = []
        sdbc: list[list[np.ndarray]] = []
        others: dict[str, list[list[np.ndarray]]] = {s.key: [] for s in self.others}
        for g in range(n):
            with self.client.lock:
                self.client.set_genome(genomes[g])
                trials = [self.client.run_trial(int(s), self.others) for s in seeds[g]]
            fitness[g] = [trial.fitness for trial in trials]
            characterisation.append([trial.characterisation for trial in trials])
            sdbc.append([trial.sdbc for trial in trials])
            for key, vectors in others.items():
                vectors.append([trial.behaviours[key] for trial in trials])
        return Evaluation(
            fitness=controller_fitness(fitness, self.spec.fitness_mean),
            trial_fitness=fitness,
            behaviours={
                "task": np.asarray(characterisation).mean(axis=1),
                "sdbc": np.asarray(sdbc).mean(axis=1),
                **{k: np.asarray(v).mean(axis=1) for k, v in others.items()},
            },
        )

    def close(self) -> None:
        """Nothing to release: the graph belongs to its launcher."""

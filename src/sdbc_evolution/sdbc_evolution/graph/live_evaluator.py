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

Each graph runs one trial at a time, paced by lockstep. Given several graphs (one
client each, e.g. graphs in namespaces ``graph_0``, ``graph_1``, ...), the
evaluator hands out a batch's genomes one by one to whichever graph is free, in a
thread per graph. Trials are deterministic and each genome's values are put in
its own row, so the results are those of one graph, whatever the order the graphs
finish in; only the wall time changes. It is still for inspection, recording and
hardware in the loop more than for the paper's runs.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from sdbc_sim.engine import controller_fitness

from sdbc_evolution.graph.client import (
    GraphClient,
    LiveTrial,
    check_live_characterisations,
)
from sdbc_evolution.run.evaluators import Evaluation, Evaluator, TaskSpec


class LiveEvaluator(Evaluator):
    """Evaluates genomes through one live graph or several.

    Args:
        spec: The task (must be the one every graph runs).
        client: The graph client, or one per graph.

    Raises:
        ValueError: A characterisation of ``spec`` cannot be made on the graph, or
            no client is given.
    """

    def __init__(
        self, spec: TaskSpec, client: GraphClient | Sequence[GraphClient]
    ) -> None:
        self.others = check_live_characterisations(spec.characterisations)
        self.spec = spec
        self.clients = [client] if isinstance(client, GraphClient) else list(client)
        if not self.clients:
            raise ValueError("live evaluator: no graph client given")
        self._pool: ThreadPoolExecutor | None = None

    @property
    def client(self) -> GraphClient:
        """The first graph's client."""
        return self.clients[0]

    @property
    def workers(self) -> int:
        # One batch: the graphs take its genomes one by one as they get free.
        return 1

    def _run(
        self, genomes: np.ndarray, seeds: np.ndarray, bounds: list[tuple[int, int]]
    ) -> list[Evaluation]:
        return [self.evaluate_genomes(genomes[a:b], seeds[a:b]) for a, b in bounds]

    @property
    def joins_requests(self) -> bool:
        """Never: a graph runs one trial at a time, so joining requests saves
        nothing, and a row per trial would set each genome on the controllers
        once per trial."""
        return False

    def _genome_trials(
        self, client: GraphClient, genome: np.ndarray, seeds: np.ndarray
    ) -> list[LiveTrial]:
        with client.lock:
            client.set_genome(genome)
            return [client.run_trial(int(s), self.others) for s in seeds]

    def _all_trials(
        self, genomes: np.ndarray, seeds: np.ndarray
    ) -> list[list[LiveTrial]]:
        """Every genome's trials, in genome order, spread over the graphs."""
        n = genomes.shape[0]
        if len(self.clients) == 1 or n == 1:
            return [
                self._genome_trials(self.client, genomes[g], seeds[g]) for g in range(n)
            ]
        results: list[list[LiveTrial] | None] = [None] * n
        next_genome = iter(range(n))
        take = threading.Lock()
        failed = threading.Event()

        def serve(client: GraphClient) -> None:
            while not failed.is_set():
                with take:
                    g = next(next_genome, None)
                if g is None:
                    return
                try:
                    results[g] = self._genome_trials(client, genomes[g], seeds[g])
                except BaseException:
                    failed.set()  # the other graphs stop after their genome
                    raise

        if self._pool is None:
            self._pool = ThreadPoolExecutor(
                len(self.clients), thread_name_prefix="live-graph"
            )
        futures = [self._pool.submit(serve, client) for client in self.clients]
        for future in futures:
            future.exception()  # waits for every graph before raising
        for future in futures:
            future.result()
        return [trials for trials in results if trials is not None]

    def evaluate_genomes(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        """Evaluates genome g in the trials ``seeds[g]``, each genome on one graph,
        one trial at a time."""
        n, t = seeds.shape
        every = self._all_trials(genomes, seeds)
        fitness = np.empty((n, t))
        # Sizes come from the trials: a task of another system is known only so.
        characterisation: list[list[np.ndarray]] = []
        sdbc: list[list[np.ndarray]] = []
        others: dict[str, list[list[np.ndarray]]] = {s.key: [] for s in self.others}
        for g, trials in enumerate(every):
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
        """Ends the threads that drive the graphs (the graphs belong to their
        launcher)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

"""Runs side by side in one process, their trials joined into one engine batch.

The engine's cost per step has a part that does not grow with the batch: at the
local studies' 260 trials per generation (population 50 x 5 trials and 10 of
re-evaluation) a robot-step cost 1.3-1.6 times what it costs at 2000
(``docs/speed.md``). Runs of one task evolve independently, but their
generations can share the engine: here each run goes in a thread of its own with
a :class:`JoinedEvaluator`, and what the runs ask to evaluate is joined into one
``evaluate_together`` call of one evaluator, a generation of every run at once.

- **Results** are each run's alone to the bit: a trial's result depends only on
  (task settings, genome, seed), and ``Evaluator.evaluate_together`` sums each
  request up from its own trials. Each run's values are checked on their own
  (``check_values``), so a run that brings a bad value stops alone, its message
  naming its own genome and trial.
- **Threads:** the engine runs in the thread that calls :func:`run_joined` (the
  main thread, where Ctrl-C lands), one batch at a time; the runs' own work
  (scoring, breeding, outputs, checkpoints) goes on in their threads between
  batches, one at a time under the interpreter's lock.
- **Stopping:** a KeyboardInterrupt in the serving thread reaches every run at
  its next evaluation (its evaluator raises KeyboardInterrupt), so each stops as
  it would alone, its checkpoint as atomic as ever. In the main thread, Ctrl-C
  and SIGTERM stop a batch at once, as they stop a run alone; anywhere else the
  serving thread holds them until it has let go of the joiner's lock
  (:class:`_Signals`), since an exception raised just after a lock is taken
  leaves it taken and every run waiting on it waits forever.
- **Time:** each run's clock counts the batches it waited for whole, the other
  runs' trials included; a study notes the runs joined (``study_run.json``) and
  its digest gives each run its share.
"""

from __future__ import annotations

import contextlib
import copy
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from types import FrameType
from typing import Any, Generic, TypeVar

import numpy as np

from sdbc_evolution.characterise.evaluation import Evaluation
from sdbc_evolution.run.evaluators import Evaluator, TaskSpec, check_values
from sdbc_evolution.run.stopping import STOP_SIGNALS, stop_signals_to

T = TypeVar("T")

JOINED_TRIALS = 2000
"""Trials per batch that a study joins runs up to by default: a robot-step costs
about the same in larger batches (``docs/speed.md``)."""

HELD_SIGNAL_POLL_SECONDS = 0.1
"""How soon the serving thread, waiting for the runs' requests, acts on a stop
signal it holds."""

Request = tuple[np.ndarray, np.ndarray]


class _Signals:
    """The stop signals while runs are joined in the main thread
    (:func:`_holding_signals`): inside a batch the handler they had acts at
    once (raising KeyboardInterrupt, the engine stops); anywhere else the first
    one is held until :meth:`act`, called where no lock is held."""

    def __init__(self) -> None:
        self.held: int | None = None
        self.in_batch = False
        self.previous: dict[int, Any] = {}

    def handle(self, signum: int, frame: FrameType | None) -> None:
        if self.in_batch:
            self.previous[signum](signum, frame)
        elif self.held is None:
            self.held = signum

    def act(self) -> None:
        """Hands a held signal to the handler it had (which usually raises)."""
        if self.held is not None:
            signum, self.held = self.held, None
            self.previous[signum](signum, None)


@contextlib.contextmanager
def _holding_signals() -> Iterator[_Signals]:
    """:class:`_Signals` for the stop signals that have a handler: an ignored
    one stays ignored. Outside the main thread nothing changes: signals never
    land there."""
    signals = _Signals()
    handled = [sig for sig in STOP_SIGNALS if callable(signal.getsignal(sig))]
    with stop_signals_to(signals.handle, handled) as previous:
        signals.previous = previous
        yield signals


class _Joiner:
    """Collects the runs' requests and answers them in batches (module docstring)."""

    def __init__(self, evaluator: Evaluator) -> None:
        self.evaluator = evaluator
        self._changed = threading.Condition()
        self._members: set[JoinedEvaluator] = set()
        self._asked: dict[JoinedEvaluator, list[Request]] = {}
        self._answers: dict[JoinedEvaluator, list[Evaluation] | BaseException] = {}
        self._stopped = False

    def join(self, member: JoinedEvaluator) -> None:
        with self._changed:
            self._members.add(member)

    def leave(self, member: JoinedEvaluator) -> None:
        with self._changed:
            self._members.discard(member)
            self._asked.pop(member, None)
            self._changed.notify_all()

    def ask(self, member: JoinedEvaluator, requests: list[Request]) -> list[Evaluation]:
        """Waits for ``member``'s answer (in the member's thread)."""
        with self._changed:
            if self._stopped:
                raise KeyboardInterrupt
            self._asked[member] = requests
            self._changed.notify_all()
            # Stopped, a request may be lost with the batch it was taken into:
            # a Ctrl-C can land anywhere in the serving thread.
            while member not in self._answers and not self._stopped:
                self._changed.wait()
            if member not in self._answers:
                raise KeyboardInterrupt
            answer = self._answers.pop(member)
        if isinstance(answer, BaseException):
            raise answer
        return answer

    def serve(self, signals: _Signals) -> None:
        """Answers batches until every member has left (in the serving thread),
        acting on a held stop signal between them."""
        while True:
            signals.act()
            with self._changed:
                while (
                    self._members
                    and len(self._asked) < len(self._members)
                    and signals.held is None
                ):
                    self._changed.wait(HELD_SIGNAL_POLL_SECONDS)
                if not self._members:
                    return
                if signals.held is not None:
                    continue  # acted on once the lock is let go
                asked, self._asked = self._asked, {}
            self._answer(asked, signals)

    def _answer(
        self, asked: dict[JoinedEvaluator, list[Request]], signals: _Signals
    ) -> None:
        answers: dict[JoinedEvaluator, list[Evaluation] | BaseException] = {}
        try:
            signals.in_batch = True
            try:
                evaluations = self.evaluator.unchecked_together(
                    [request for requests in asked.values() for request in requests]
                )
            finally:
                signals.in_batch = False
        except Exception as error:
            # Every run of the batch met it: each raises its own copy.
            answers = {member: copy.copy(error) for member in asked}
        else:
            start = 0
            for member, requests in asked.items():
                share = evaluations[start : start + len(requests)]
                start += len(requests)
                try:
                    for evaluation in share:
                        check_values(evaluation, member.spec)
                except ValueError as error:
                    answers[member] = error
                else:
                    answers[member] = share
        with self._changed:
            self._answers.update(answers)
            self._changed.notify_all()

    def stop(self) -> None:
        """Every member waiting and not answered yet gets KeyboardInterrupt, and
        so does every later request."""
        with self._changed:
            self._stopped = True
            self._changed.notify_all()


class JoinedEvaluator(Evaluator):
    """One run's evaluator among runs joined by :func:`run_joined`: its requests
    wait for a batch of every run's.

    Args:
        joiner: The joiner of the runs.
        spec: The run's task (that of the evaluator the runs share).
    """

    def __init__(self, joiner: _Joiner, spec: TaskSpec) -> None:
        self._joiner = joiner
        self.spec = spec

    @property
    def workers(self) -> int:
        return self._joiner.evaluator.workers

    def _run(
        self, genomes: np.ndarray, seeds: np.ndarray, bounds: list[tuple[int, int]]
    ) -> list[Evaluation]:
        return self.unchecked_together([(genomes[a:b], seeds[a:b]) for a, b in bounds])

    def evaluate(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        return self.evaluate_together([(genomes, seeds)])[0]

    def evaluate_together(self, requests: Sequence[Request]) -> list[Evaluation]:
        """The requests' evaluations, checked (by the joiner), in one batch with
        the other runs' requests."""
        return self._joiner.ask(self, list(requests))

    def unchecked_together(self, requests: Sequence[Request]) -> list[Evaluation]:
        # Checked all the same: the joiner checks every run's values.
        return self.evaluate_together(requests)

    def close(self) -> None:
        self._joiner.leave(self)


class _Job(Generic[T]):
    """A run's work in its thread, and what became of it."""

    def __init__(
        self, joiner: _Joiner, spec: TaskSpec, work: Callable[[Evaluator], T]
    ) -> None:
        self.evaluator = JoinedEvaluator(joiner, spec)
        joiner.join(self.evaluator)
        self.work = work
        self.result: T | None = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._main, daemon=True)

    def _main(self) -> None:
        try:
            self.result = self.work(self.evaluator)
        except BaseException as error:  # raised in the caller's thread
            self.error = error
        finally:
            self.evaluator.close()


def run_joined(
    evaluator: Evaluator,
    jobs: Sequence[tuple[TaskSpec, Callable[[Evaluator], T]]],
) -> list[T | None]:
    """Runs every job in a thread of its own, its evaluations joined with the
    other jobs' into batches of ``evaluator``, which runs them in this thread.

    Args:
        evaluator: Evaluates the joined batches (its task spec must evaluate
            like every job's, ``TaskSpec.evaluates_like``).
        jobs: (task, work) pairs; ``work(evaluator)`` is called with the job's
            :class:`JoinedEvaluator`.

    Returns:
        What each job's work returned, in order, once every job has ended. A
        KeyboardInterrupt here stops every job at its next evaluation (module
        docstring) and is not raised again: the jobs' answers say what stopped
        (None for a job it stopped before its thread started).

    Raises:
        ValueError: A job's task spec does not evaluate like the evaluator's.
        BaseException: The first exception a job's work raised, once every job
            has ended.
        KeyboardInterrupt: A stop signal that came between batches as the last
            jobs ended, once they have (it stops the caller as it would stop a
            run alone at its end).
    """
    for spec, _ in jobs:
        if not spec.evaluates_like(evaluator.spec):
            raise ValueError(
                f"joined runs share one task: {spec} is not the evaluator's "
                f"{evaluator.spec}"
            )
    joiner = _Joiner(evaluator)
    started = [_Job(joiner, spec, work) for spec, work in jobs]
    with _holding_signals() as signals:
        stopped = False
        try:
            for job in started:
                job.thread.start()
            joiner.serve(signals)
        except KeyboardInterrupt:
            joiner.stop()
            stopped = True
        except BaseException:
            joiner.stop()
            raise
        finally:
            for job in started:
                if job.thread.ident is not None:
                    job.thread.join()
        if not stopped:
            # A signal held as the last runs ended stops the caller, as it
            # would stop a run alone at its end; one held while they stopped
            # asked for what was under way.
            signals.act()
    for job in started:
        if job.error is not None:
            raise job.error
    return [job.result for job in started]

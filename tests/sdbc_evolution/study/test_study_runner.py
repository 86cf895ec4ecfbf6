"""The study runner: seeds, resume, skipping, broken runs, and where runs go."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from sdbc_evolution.run.evaluators import LocalEvaluator
from sdbc_evolution.run.experiment import Experiment, task_spec
from sdbc_evolution.run.lock import RunLock
from sdbc_evolution.run.results import read_generations
from sdbc_evolution.study import runner
from sdbc_evolution.study.plan import (
    DISCARDED_DIR,
    LOG_FILE,
    STUDY_FILE,
    RunProgress,
    Shard,
    run_seed,
    run_status,
    study_plan,
)
from sdbc_evolution.study.presets import (
    StudyPreset,
    load_preset_file,
    preset_from_dict,
)
from sdbc_evolution.study.runner import (
    EXECUTION_FILE,
    Execution,
    StudyError,
    prepare_study_directory,
    run_study,
)
from study_helpers import TINY, assert_same_study, run_contents, straight_study


def files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != LOG_FILE
    }


def test_plan_interleaves_treatments_and_seeds_depend_on_names(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    plan = study_plan(tiny_preset, tmp_path)
    assert [s.name for s in plan] == [
        "gate_escape/fit/run_00",
        "gate_escape/ns-sd-plus/run_00",
        "gate_escape/fit/run_01",
        "gate_escape/ns-sd-plus/run_01",
    ]
    seeds = [s.config.seed for s in plan]
    assert len(set(seeds)) == len(seeds)
    assert all(0 <= s < 2**63 for s in seeds)
    # Another task, another treatment: the existing runs keep their seeds.
    bigger = preset_from_dict(
        {
            **TINY,
            "tasks": ["resource_sharing", "gate_escape"],
            "treatments": ["ns-ts", "fit", "ns-sd+"],
            "generations": {"resource_sharing": 2, "gate_escape": 2},
        }
    )
    again = {s.name: s.config.seed for s in study_plan(bigger, tmp_path)}
    assert all(again[s.name] == s.config.seed for s in plan)
    assert run_seed(5, "gate_escape", "fit", 0) != run_seed(6, "gate_escape", "fit", 0)
    with pytest.raises(ValueError, match="not in preset"):
        study_plan(tiny_preset, tmp_path, ("predator_prey",))


def test_shards_partition_the_plan_and_mix_treatments(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    plan = study_plan(tiny_preset, tmp_path)
    shards = [Shard(k, 2).select(plan) for k in range(2)]
    assert sorted(s.name for shard in shards for s in shard) == sorted(
        s.name for s in plan
    )
    assert [s.treatment.name for s in shards[0]] == ["fit", "fit"]
    assert Shard.parse("1/2") == Shard(1, 2) and str(Shard(1, 2)) == "1/2"
    for bad in ("2/2", "-1/2", "0/0", "1", "a/b", "1/2/3", " 1/2"):
        with pytest.raises(ValueError, match="shard"):
            Shard.parse(bad)


def test_a_second_run_skips_finished_runs_and_touches_nothing(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    root = tmp_path / "study"
    said: list[str] = []
    first = run_study(
        tiny_preset, root, execution=Execution(workers=1), quiet=True, say=said.append
    )
    assert not first.failed and not first.interrupted and not first.skipped
    assert sorted(r.name for r in first.ran if r.finished) == sorted(
        s.name for s in study_plan(tiny_preset, root)
    )
    for spec in study_plan(tiny_preset, root):
        assert run_status(spec).state is RunProgress.FINISHED
        assert len(read_generations(spec.path)["generation"]) == 2
    before = files(root)
    second = run_study(
        tiny_preset, root, execution=Execution(workers=1), quiet=True, say=said.append
    )
    assert len(second.skipped) == 4 and not second.ran
    assert "4 of 4 runs already finished: skipped" in said
    assert files(root) == before
    log = [json.loads(line) for line in (root / LOG_FILE).read_text().splitlines()]
    assert [e["finished_now"] for e in log] == [4]  # nothing to log the second time


def test_an_interrupted_run_resumes_to_the_same_results(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    straight = straight_study(tiny_preset, tmp_path / "straight")
    resumed = tmp_path / "resumed"
    spec = study_plan(tiny_preset, resumed)[1]
    with LocalEvaluator(task_spec(spec.config), workers=1) as evaluator:
        Experiment.create(spec.config, spec.path, evaluator).step()
    status = run_status(spec)
    assert status.state is RunProgress.PARTIAL and status.generations_done == 1
    outcome = run_study(
        tiny_preset, resumed, execution=Execution(workers=1), quiet=True
    )
    resumed_run = next(r for r in outcome.ran if r.name == spec.name)
    assert resumed_run.finished and resumed_run.generations_done == 2
    assert_same_study(tiny_preset, straight, resumed)
    segments = json.loads((spec.path / EXECUTION_FILE).read_text())
    assert [(s["from_generation"], s["to_generation"]) for s in segments] == [(1, 2)]


def test_a_run_without_usable_checkpoint_is_moved_aside_and_run_again(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    root = straight_study(tiny_preset, tmp_path / "study")
    spec = study_plan(tiny_preset, root)[0]
    (spec.path / "checkpoint.npz").write_bytes(b"PK\x03\x04 not a zip")
    said: list[str] = []
    outcome = run_study(
        tiny_preset, root, execution=Execution(workers=1), quiet=True, say=said.append
    )
    assert [name for name, _, _ in outcome.discarded] == [spec.name]
    moved = outcome.discarded[0][1]
    assert moved.parent == root / DISCARDED_DIR and (moved / "config.yaml").is_file()
    assert any(spec.name in line and "cannot resume" in line for line in said)
    assert run_status(spec).state is RunProgress.FINISHED
    assert len(outcome.skipped) == 3


@pytest.mark.parametrize("damage", ["individuals deleted", "csv cut"])
def test_a_finished_run_with_damaged_outputs_is_moved_aside_and_run_again(
    tiny_preset: StudyPreset, tmp_path: Path, damage: str
) -> None:
    straight = straight_study(tiny_preset, tmp_path / "straight")
    root = straight_study(tiny_preset, tmp_path / "study")
    spec = study_plan(tiny_preset, root)[2]
    if damage == "individuals deleted":
        (spec.path / "individuals" / "gen_00001.npz").unlink()
    else:
        csv_file = spec.path / "generations.csv"
        csv_file.write_text("".join(csv_file.read_text().splitlines(True)[:-1]))
    status = run_status(spec)
    assert status.state is RunProgress.BROKEN
    said: list[str] = []
    outcome = run_study(
        tiny_preset, root, execution=Execution(workers=1), quiet=True, say=said.append
    )
    assert [name for name, _, _ in outcome.discarded] == [spec.name]
    assert any(spec.name in line and status.detail in line for line in said)
    assert [r.name for r in outcome.ran if r.finished] == [spec.name]
    assert_same_study(tiny_preset, straight, root)


def test_a_run_another_process_writes_is_left_to_it(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    root = tmp_path / "study"
    spec = study_plan(tiny_preset, root)[1]
    said: list[str] = []
    with RunLock(spec.path):
        outcome = run_study(
            tiny_preset,
            root,
            execution=Execution(workers=1),
            quiet=True,
            say=said.append,
        )
        assert outcome.busy == [spec.name]
        assert run_status(spec).state is RunProgress.NEW
    assert any(
        line.startswith(f"{spec.name}: left alone: {spec.path} is being written")
        for line in said
    )
    assert sorted(r.name for r in outcome.ran if r.finished) == sorted(
        s.name for s in study_plan(tiny_preset, root) if s.name != spec.name
    )
    again = run_study(tiny_preset, root, execution=Execution(workers=1), quiet=True)
    assert [r.name for r in again.ran if r.finished] == [spec.name]
    assert not again.busy


def test_a_directory_of_another_study_is_refused(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    root = tmp_path / "study"
    root.mkdir()
    other = preset_from_dict({**TINY, "runs": 3})
    (root / STUDY_FILE).write_text("name: other\nruns: 1\n")
    with pytest.raises(StudyError, match="another preset"):
        run_study(other, root, execution=Execution(workers=1), quiet=True)


def test_predictions_are_updated_in_a_study_of_the_same_runs(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    """Predictions make no run: a study directory takes the preset's new ones,
    and still refuses other runs however its predictions read."""
    root = tmp_path / "study"
    prepare_study_directory(tiny_preset, root)
    prediction = {"statement": "NS-SD+ beats Fit", "a": "ns-sd+", "b": "fit"}
    predicted = preset_from_dict(
        {**TINY, "predictions": [{**prediction, "rule": "above"}]}
    )
    prepare_study_directory(predicted, root)
    assert load_preset_file(root / STUDY_FILE).predictions == predicted.predictions
    assert load_preset_file(root / STUDY_FILE).same_runs(tiny_preset)
    more_runs = preset_from_dict(
        {**TINY, "runs": 3, "predictions": [{**prediction, "rule": "above"}]}
    )
    with pytest.raises(StudyError, match="another preset"):
        prepare_study_directory(more_runs, root)


def test_runs_side_by_side_and_on_dask_equal_runs_in_process(
    tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    from distributed import LocalCluster

    one = straight_study(tiny_preset, tmp_path / "one")
    two = tmp_path / "two"
    outcome = run_study(tiny_preset, two, execution=Execution(workers=2), quiet=True)
    assert not outcome.failed and all(r.finished for r in outcome.ran)
    dask = tmp_path / "dask"
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        run_study(
            tiny_preset,
            dask,
            execution=Execution(scheduler=cluster.scheduler_address),
            quiet=True,
        )
    for a, b, c in zip(
        study_plan(tiny_preset, one),
        study_plan(tiny_preset, two),
        study_plan(tiny_preset, dask),
        strict=True,
    ):
        assert run_contents(a.path) == run_contents(b.path) == run_contents(c.path)
        local = json.loads((b.path / EXECUTION_FILE).read_text())[0]
        assert local["evaluator"] == "local" and local["workers_per_run"] == 1
        assert local["concurrent_runs"] == 2
        remote = json.loads((c.path / EXECUTION_FILE).read_text())[0]
        assert remote["evaluator"] == "dask" and remote["workers_per_run"] == 1


@pytest.mark.parametrize("workers", [1, 2])
def test_joined_runs_equal_runs_alone_and_their_digest_takes_their_share(
    tiny_preset: StudyPreset, tmp_path: Path, workers: int
) -> None:
    from sdbc_evolution.study.reduce import reduce_run
    from sdbc_evolution.study.rundirs import load_run

    alone = straight_study(tiny_preset, tmp_path / "alone")
    joined = tmp_path / "joined"
    outcome = run_study(
        tiny_preset, joined, execution=Execution(workers=workers), quiet=True
    )
    assert not outcome.failed and all(r.finished for r in outcome.ran)
    assert_same_study(tiny_preset, alone, joined)
    group = 4 // workers  # the task's four runs, shared by the processes
    for spec in study_plan(tiny_preset, joined):
        note = json.loads((spec.path / EXECUTION_FILE).read_text())[0]
        assert note["joined_runs"] == group
        run = load_run(spec.path, joined)
        digest = reduce_run(run)  # type: ignore[arg-type]
        wall = read_generations(spec.path)["wall_time"]
        assert list(digest.wall_time) == list(wall / group)
    (entry,) = [
        json.loads(line) for line in (joined / LOG_FILE).read_text().splitlines()
    ]
    assert entry["joined_runs"] == group
    (entry,) = [
        json.loads(line) for line in (alone / LOG_FILE).read_text().splitlines()
    ]
    assert entry["joined_runs"] == 1


def test_bad_execution_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="at least 1"):
        Execution(workers=0)
    with pytest.raises(ValueError, match="exclude each other"):
        Execution(workers=2, scheduler="tcp://127.0.0.1:8786")
    with pytest.raises(ValueError, match="joined runs must be from 1 to"):
        Execution(joined_runs=0)


def test_ctrl_c_when_the_running_runs_had_finished_still_stops_the_session(
    tiny_preset: StudyPreset, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The parent alone gets Ctrl-C just as its children finish: no child reports
    # an interruption, yet the runs not started must not pass for done.
    original = runner._Children.poll

    def poll(self: runner._Children) -> None:
        original(self)
        if self.results and not self.stopping:
            raise KeyboardInterrupt

    def interrupt(self: runner._Children) -> None:
        self.stopping = True  # the children had nothing left to stop

    monkeypatch.setattr(runner._Children, "poll", poll)
    monkeypatch.setattr(runner._Children, "interrupt", interrupt)
    root = tmp_path / "study"
    # A run per process, so that two wait for a free one.
    execution = Execution(workers=2, joined_runs=1)
    outcome = run_study(tiny_preset, root, execution=execution, quiet=True)
    assert outcome.interrupted and not outcome.failed
    plan = study_plan(tiny_preset, root)
    assert [run_status(s).state for s in plan] == [
        RunProgress.FINISHED,
        RunProgress.FINISHED,
        RunProgress.NEW,
        RunProgress.NEW,
    ]
    assert sorted(r.name for r in outcome.ran if r.interrupted) == [
        s.name for s in plan[2:]
    ]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("stop", "workers"),
    [("ctrl-c", "2"), ("parent-only", "2"), ("sigterm", "2"), ("ctrl-c", "1")],
)
def test_ctrl_c_stops_runs_side_by_side_and_the_same_command_resumes(
    tmp_path: Path, stop: str, workers: str
) -> None:
    """Ctrl-C in a terminal (the whole process group), SIGINT to the study alone
    where it was started with SIGINT ignored (a shell's background job), and a
    batch scheduler's SIGTERM all stop the study, and the same command resumes;
    with one worker, Ctrl-C stops the runs joined in the study's own process."""
    preset = tmp_path / "longer.yaml"
    preset.write_text(
        yaml.safe_dump(
            {
                **TINY,
                "generations": {"gate_escape": 12},
                "task_config": {"gate_escape": {"max_steps": 100}},
            }
        )
    )
    root = tmp_path / "study"
    command = [
        sys.executable, "-m", "sdbc_evolution.study", "run", "--preset", str(preset),
        "--out", str(root), "--workers", workers, "--quiet",
    ]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    process = subprocess.Popen(
        command,
        env=env,
        start_new_session=True,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=(
            (lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
            if stop == "parent-only"
            else None
        ),
    )
    plan = study_plan(load_preset_file(preset), root)
    deadline = time.monotonic() + 120
    while not any(run_status(s).generations_done >= 1 for s in plan):
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() < deadline, "no generation within two minutes"
        time.sleep(0.2)
    if stop == "ctrl-c":
        os.killpg(process.pid, signal.SIGINT)
    else:
        process.send_signal(signal.SIGTERM if stop == "sigterm" else signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert "interrupted; resume with the same command" in stderr
    states = [run_status(s).state for s in plan]
    assert RunProgress.FINISHED not in states[2:]  # the later runs never ended
    assert subprocess.run(command, env=env, timeout=600).returncode == 0
    assert all(run_status(s).state is RunProgress.FINISHED for s in plan)
    reference = tmp_path / "reference"
    run_study(
        load_preset_file(preset), reference, execution=Execution(workers=1), quiet=True
    )
    for a, b in zip(plan, study_plan(load_preset_file(preset), reference), strict=True):
        assert run_contents(a.path) == run_contents(b.path), a.name


def test_on_dask_every_run_gets_its_own_treatments_characterisation(
    tmp_path: Path,
) -> None:
    """Runs of one task share one cluster connection, yet each is evaluated with
    its own treatment's characterisation: here Fit's run comes first and the
    state-count treatment's second."""
    from distributed import LocalCluster

    preset = preset_from_dict(
        {
            **TINY,
            "runs": 1,
            "treatments": [
                "fit",
                {"name": "ns-state-count", "characterisation": "state_count"},
            ],
        }
    )
    one = straight_study(preset, tmp_path / "one")
    dask = tmp_path / "dask"
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        outcome = run_study(
            preset,
            dask,
            execution=Execution(scheduler=cluster.scheduler_address),
            quiet=True,
        )
    assert not outcome.failed, outcome.failed[0].error
    for a, b in zip(study_plan(preset, one), study_plan(preset, dask), strict=True):
        assert run_contents(a.path) == run_contents(b.path)

"""``sdbc-study``: bad input exits 2 with a clear message before any run; a run that
fails is named and the others go on."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from sdbc_evolution.study import runner
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.plan import LOG_FILE, RunProgress, run_status, study_plan
from sdbc_evolution.study.presets import StudyPreset
from sdbc_evolution.study.runner import Execution, run_study
from study_helpers import TINY, assert_same_study, straight_study


@pytest.fixture
def tiny_file(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "--preset", "huge"], "unknown preset 'huge'"),
        (["run", "--preset", "smoke", "--task", "football"], "--task football"),
        (["run", "--preset", "smoke", "--workers", "0"], "at least 1"),
        (["measure", "--preset", "smoke", "--generations", "1"], "--generations"),
        (["run", "--preset", "smoke", "--shard", "2/2"], "shard 2/2: needs 0 <="),
        (["run", "--preset", "smoke", "--shard", "first"], "expected K/N"),
        (["run", "--preset", "smoke", "--shard", "30/40"], "at most 24 shards"),
    ],
)
def test_bad_input_exits_2_before_any_run(
    args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    assert main([*args, "--out", str(out)] if args[0] == "run" else args) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_a_study_directory_of_another_preset_exits_2(
    tiny_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    out.mkdir()
    (out / "study.yaml").write_text("name: other\n")
    assert main(["run", "--preset", str(tiny_file), "--out", str(out)]) == 2
    assert "another preset" in capsys.readouterr().err


def test_a_failing_run_is_named_and_the_others_finish(
    tiny_preset: StudyPreset, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    root = tmp_path / "study"
    doomed = study_plan(tiny_preset, root)[2].name
    original = runner.Experiment.create

    def create(config, out_dir, evaluator, info=None, lock=None):
        if str(out_dir).endswith(doomed):
            raise RuntimeError("the disk is on fire")
        return original(config, out_dir, evaluator, info, lock)

    monkeypatch.setattr(runner.Experiment, "create", create)
    said: list[str] = []
    outcome = run_study(
        tiny_preset, root, execution=Execution(workers=1), quiet=True, say=said.append
    )
    assert [r.name for r in outcome.failed] == [doomed]
    assert any(doomed in line and "the disk is on fire" in line for line in said)
    states = {s.name: run_status(s).state for s in study_plan(tiny_preset, root)}
    assert states.pop(doomed) is RunProgress.NEW
    assert set(states.values()) == {RunProgress.FINISHED}


def test_run_then_analyse_by_default(
    tiny_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    assert (
        main(
            ["--preset", str(tiny_file), "--out", str(out), "--workers", "1", "--quiet"]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert f"study: {out.resolve()}" in printed
    assert f"report: {(out / 'report' / 'report.md').resolve()}" in printed


def test_measure_probes_every_treatment_and_projects_the_study(
    tiny_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from sdbc_evolution.study.measure import probe, projected_task_seconds
    from sdbc_evolution.study.presets import load_preset_file

    preset = load_preset_file(tiny_file)
    probes = probe(preset, "gate_escape", generations=2)
    assert [p.treatment for p in probes] == ["fit", "ns-sd+"]
    for p in probes:
        assert p.cpu_per_generation > 0 and 0 < p.evaluation_share <= 1
        assert 0 < p.mean_length <= p.max_steps == 60
        assert p.worst_cpu_per_generation >= p.cpu_per_generation
    expected = 2 * sum(2 * p.cpu_per_generation for p in probes) / 2
    assert projected_task_seconds(preset, probes, 2, False) == pytest.approx(expected)
    assert main(["measure", "--preset", str(tiny_file), "--generations", "2"]) == 0
    captured = capsys.readouterr()
    assert "gate_escape: 2 generations; projected study time" in captured.out
    # The tiny preset's two runs of a treatment, joined as a study joins them.
    assert "gate_escape: probing 2 run(s) of each treatment joined" in captured.err
    for p in probe(preset, "gate_escape", generations=2, joined=2):
        assert p.cpu_per_generation > 0 and 0 < p.evaluation_share <= 1
        assert 0 < p.mean_length <= p.max_steps == 60
    assert main(["measure", "--preset", str(tiny_file), "--joined-runs", "0"]) == 2
    assert "error: joined runs must be from 1 to" in capsys.readouterr().err


def study_command(preset: Path, out: Path) -> list[str]:
    """``sdbc-study run`` of ``preset`` into ``out``, in process, as a command."""
    return [
        sys.executable, "-m", "sdbc_evolution.study", "run", "--preset", str(preset),
        "--out", str(out), "--workers", "1", "--quiet",
    ]  # fmt: skip


def test_shards_run_at_once_make_the_study_run_in_one_go(
    tiny_file: Path, tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    whole = straight_study(tiny_preset, tmp_path / "whole")
    sharded = tmp_path / "sharded"
    shards = [
        subprocess.Popen(
            [*study_command(tiny_file, sharded), "--shard", f"{k}/3"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        for k in range(3)
    ]
    for shard in shards:
        _, err = shard.communicate(timeout=300)
        assert shard.returncode == 0, err.decode()
    assert_same_study(tiny_preset, whole, sharded)
    log = [json.loads(line) for line in (sharded / LOG_FILE).read_text().splitlines()]
    assert sorted(e["shard"] for e in log) == ["0/3", "1/3", "2/3"]
    assert sorted(e["worked_on"] for e in log) == [1, 1, 2]


def test_two_sessions_at_once_on_one_study_share_its_runs(
    tiny_file: Path, tiny_preset: StudyPreset, tmp_path: Path
) -> None:
    whole = straight_study(tiny_preset, tmp_path / "whole")
    shared = tmp_path / "shared"
    command = study_command(tiny_file, shared)
    sessions = [
        subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        for _ in range(2)
    ]
    for session in sessions:
        _, err = session.communicate(timeout=300)
        # 3: it left runs to the other session, and said so.
        assert session.returncode in (0, 3), err.decode()
        if session.returncode == 3:
            assert b"were being written by another process" in err
    third = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert third.returncode == 0, third.stderr
    assert "4 of 4 runs already finished: skipped" in third.stderr
    assert_same_study(tiny_preset, whole, shared)


def test_a_busy_run_ends_the_session_with_exit_3(
    tiny_file: Path,
    tiny_preset: StudyPreset,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from sdbc_evolution.run.lock import RunLock

    out = tmp_path / "study"
    spec = study_plan(tiny_preset, out)[0]
    with RunLock(spec.path):
        status = main(
            [
                "run",
                "--preset",
                str(tiny_file),
                "--out",
                str(out),
                "--workers",
                "1",
                "--quiet",
            ]
        )
    assert status == 3
    assert "1 run(s) were being written by another process" in capsys.readouterr().err

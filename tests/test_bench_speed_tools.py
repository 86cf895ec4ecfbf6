"""The speed benchmarks' own logic: the bit-identity check finds a one-bit change,
the profile's parts add up to the run and leave the engine as it was, and physics
overrides are parsed and refused as the command line needs."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench"
# Appended, not prepended: bench/profile.py must not shadow the standard library's
# profile module for the rest of the session, so it is loaded under its own name.
sys.path.append(str(BENCH))

import common  # noqa: E402
import engine as engine_bench  # noqa: E402
import identity  # noqa: E402
import replay  # noqa: E402
from sdbc_sim.engine import BatchSimulation, EngineSettings, run_batch  # noqa: E402
from sdbc_sim.kinematic import KinematicTrials  # noqa: E402
from sdbc_sim.physics import PhysicsSettings, TrialSpaces  # noqa: E402
from sdbc_sim.tasks import make_task  # noqa: E402

from sdbc_sim import compiled  # noqa: E402

engine_profile = common.bench_module("profile")


def test_identity_finds_a_one_bit_change(tmp_path: Path) -> None:
    data = identity.run_task("predator_prey", 3, 2, 30, 1, EngineSettings())
    assert set(data) == {
        f"predator_prey/{layout}/{f}"
        for layout in identity.LAYOUTS
        for f in identity.FIELDS
    }
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    np.savez(a, **data)
    np.savez(b, **data)
    assert identity.compare(a, b)
    sdbc = data["predator_prey/space7/sdbc"]
    sdbc[2, 1, 0] = np.nextafter(sdbc[2, 1, 0], np.inf)
    np.savez(b, **data)
    assert not identity.compare(a, b)
    assert identity.differing_trials(np.load(a)["predator_prey/space7/sdbc"], sdbc) == 1


def test_identity_says_when_both_files_came_from_the_same_engine_sources(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two files of the same sources agree whatever the change was: a comparison
    of them must not read as a change shown harmless."""
    data = identity.run_task("predator_prey", 2, 1, 5, 1, EngineSettings())
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    np.savez(a, **data, **{identity.SOURCES: np.array(identity.sources_digest())})
    np.savez(b, **data, **{identity.SOURCES: np.array(identity.sources_digest())})
    assert identity.compare(a, b)
    assert "same engine sources" in capsys.readouterr().out
    np.savez(b, **data, **{identity.SOURCES: np.array("another")})
    assert identity.compare(a, b)
    assert "same engine sources" not in capsys.readouterr().out


def test_identity_writes_with_the_sources_of_the_checkout_it_is_given(
    tmp_path: Path,
) -> None:
    """``--engine DIR`` runs the batches with DIR's sources, not the ones the
    environment put first on the path (here another checkout's, linked)."""
    repo = BENCH.parent
    other = tmp_path / "other"
    for package in ("sdbc_sim", "sdbc_evolution"):
        (other / "src" / package).mkdir(parents=True)
        (other / "src" / package / package).symlink_to(repo / "src" / package / package)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(
            [
                str(other / "src" / "sdbc_sim"),
                str(other / "src" / "sdbc_evolution"),
                os.environ.get("PYTHONPATH", ""),
            ]
        ),
    }
    out = tmp_path / "a.npz"
    small = ["--write", str(out), "--task", "predator_prey"]
    small += ["--genomes", "2", "--trials", "1", "--steps", "5"]

    def written(*engine: str) -> str:
        done = subprocess.run(
            [sys.executable, str(BENCH / "identity.py"), *engine, *small],
            capture_output=True,
            text=True,
            env=env,
            check=True,
        )
        return done.stdout

    assert f"engine sources: {other})" in written()
    assert f"engine sources: {repo})" in written("--engine", str(repo))
    assert str(np.load(out)[identity.SOURCES]) == identity.sources_digest()
    missing = subprocess.run(
        [sys.executable, str(BENCH / "identity.py"), "--engine", str(tmp_path)]
        + ["--write", str(out)],
        capture_output=True,
        text=True,
    )
    assert missing.returncode != 0
    assert (
        f"identity: --engine: {tmp_path.resolve()} is not a source tree of this "
        "project (no src/sdbc_sim/sdbc_sim/engine.py)" in missing.stderr
    )


def test_profile_parts_add_up_and_unwrap() -> None:
    saved = (TrialSpaces.step, BatchSimulation.state, BatchSimulation.__init__)
    p = engine_profile.profile_task(
        "gate_escape", 2, 2, 20, 0, EngineSettings(), sdbc=True
    )
    assert sum(p.seconds.values()) == pytest.approx(p.total)
    assert p.calls["chipmunk step"] == 20
    assert p.calls["SDBC extractor"] == 20
    assert p.robot_steps == 4 * 20 * 4
    assert (TrialSpaces.step, BatchSimulation.state, BatchSimulation.__init__) == saved


def test_profile_times_the_kinematic_step_in_place_of_chipmunk() -> None:
    settings = common.engine_settings(["model=kinematic"])
    p = engine_profile.profile_task("gate_escape", 2, 2, 20, 0, settings, sdbc=True)
    assert sum(p.seconds.values()) == pytest.approx(p.total)
    # 20 steps and the read that fills the rows at the start.
    assert p.calls["kinematic step"] == 21
    assert p.calls["chipmunk step"] == p.calls["bulk transfer"] == 0
    assert "chipmunk + bulk transfer" not in engine_profile.report(p)


def test_profile_takes_the_compiled_loops_out_of_their_parts() -> None:
    """With ``loops``, the calls of the compiled loops (the SDBC extractor's
    kernels included) are counted in a part of their own, and numpy's ``exp`` and
    ``arctan2`` in another: the parts still add up, and the loops and numpy are
    unwrapped after; without it those parts stay empty."""
    call, load = compiled._Loop.__call__, compiled._Loop.load
    exp, arctan2 = np.exp, np.arctan2
    settings = common.engine_settings(["model=kinematic"])
    args = ("gate_escape", 2, 2, 20, 0, settings)
    p = engine_profile.profile_task(*args, sdbc=True, loops=True)
    assert (compiled._Loop.__call__, compiled._Loop.load) == (call, load)
    assert (np.exp, np.arctan2) == (exp, arctan2)
    # Every step takes the exp of the network's two layers.
    assert p.calls["numpy maths"] >= 2 * 20
    # The SDBC extractor's kernels, which it calls directly, count too.
    bare = engine_profile.profile_task(*args, sdbc=False, loops=True)
    assert p.calls["compiled loops"] >= bare.calls["compiled loops"] + 20
    assert sum(p.seconds.values()) == pytest.approx(p.total)
    # Every step calls the drive's loop at least.
    assert p.calls["compiled loops"] >= 20
    whole = engine_profile.profile_task(*args, sdbc=True)
    assert whole.calls["compiled loops"] == whole.calls["numpy maths"] == 0
    assert whole.seconds["compiled loops"] == whole.seconds["numpy maths"] == 0.0


@pytest.mark.parametrize("model", ["rigid", "kinematic"])
def test_engine_bench_floor_times_each_model(model: str) -> None:
    saved = [(c.read, c.step, c.separate) for c in (TrialSpaces, KinematicTrials)]
    task = make_task("gate_escape", max_steps=10)
    rng = np.random.default_rng(0)
    genomes = rng.uniform(-1.0, 1.0, (2, task.genome_length))
    seeds = rng.integers(0, 2**31, (2, 2))
    settings = common.engine_settings([f"model={model}"])
    rates = engine_bench.measure(task, genomes, seeds, settings, naive_trials=1)
    assert rates.steps == 4 * 10
    # The floor is a part of the engine's own time, and of the physics' with the
    # projection: never slower than either.
    assert np.isfinite(rates.floor) and rates.floor >= rates.physics >= rates.engine
    assert [
        (c.read, c.step, c.separate) for c in (TrialSpaces, KinematicTrials)
    ] == saved


def test_replay_times_recorded_calls_in_the_step_and_alone() -> None:
    """The recorded loop's calls are timed in the step and alone, repeated and
    varied; the loops are unwrapped after; a loop that is not there is named."""
    call = compiled._Loop.__call__
    settings = common.engine_settings(["model=kinematic"])
    rows = replay.replay(
        "gate_escape", 2, 2, 12, 0, settings, ["engine._drive_rows"], start=3, record=4
    )
    assert [r.name for r in rows] == ["engine._drive_rows"]
    (row,) = rows
    assert row.calls == 12
    assert min(row.in_step, row.repeated, row.varied) > 0.0
    assert compiled._Loop.__call__ is call
    with pytest.raises(ValueError, match=r"no recorded calls of \['engine._nope'\]"):
        replay.replay(
            "gate_escape", 2, 2, 12, 0, settings, ["engine._nope"], start=3, record=4
        )
    assert compiled._Loop.__call__ is call


def test_replay_times_in_one_run_and_copies_in_another() -> None:
    """The timed run keeps no inputs (their copies grew the heap, and the step's
    loops paid page faults); the recording run copies the named loop's calls
    ``start`` to ``start + count - 1`` only, as they were at the call."""
    task = make_task("gate_escape", max_steps=12)
    g, s = common.random_batch(task, 2, 2, np.random.default_rng(0))
    settings = common.engine_settings(["model=kinematic"])
    run_batch(task, g[:1], s[:1, :1], settings=settings)
    with replay.timing(3, 4) as log:
        run_batch(task, g, s, settings=settings)
    drive = log["engine._drive_rows"]
    assert drive.calls == 12 and len(drive.in_step) == 4
    assert not hasattr(drive, "recorded")
    seen: list[np.ndarray] = []
    call = compiled._Loop.__call__

    def spy(loop: compiled._Loop, *args: object) -> object:
        if replay.loop_name(loop) == "engine._drive_rows":
            seen.append(np.array(args[0], copy=True))
        return call(loop, *args)

    with (
        common.patched(compiled._Loop, "__call__", spy),
        replay.recording({"engine._drive_rows"}, 3, 4) as kept,
    ):
        run_batch(task, g, s, settings=settings)
    assert compiled._Loop.__call__ is call
    assert list(kept) == ["engine._drive_rows"]
    copies = kept["engine._drive_rows"]
    assert len(copies) == 4
    for k, args in enumerate(copies):
        assert np.array_equal(args[0], seen[3 + k])


def test_replay_copies_keep_a_views_strides() -> None:
    rows = np.arange(40.0).reshape(8, 5)
    column = rows[:, 2].reshape(2, 4)
    copy = replay._copy_array(column)
    assert copy.strides == column.strides and np.array_equal(copy, column)
    assert not np.shares_memory(copy, rows)


def test_physics_overrides() -> None:
    assert common.physics_overrides(["hash_cell=32", "iterations=4"]) == {
        "hash_cell": 32,
        "iterations": 4,
    }
    assert common.physics_overrides(["hash_cell=none"]) == {"hash_cell": None}
    with pytest.raises(ValueError, match="unknown setting 'bogus'"):
        common.physics_overrides(["bogus=1"])
    with pytest.raises(ValueError, match="NAME=VALUE"):
        common.physics_overrides(["iterations"])
    with pytest.raises(ValueError, match="power of two"):
        common.engine_settings(["hash_cell=3"])


def test_physics_sweep() -> None:
    base = PhysicsSettings(iterations=4)
    sweep = common.physics_sweep(base, "hash_cell=8,none,64")
    assert [p.hash_cell for p in sweep] == [8, None, 64]
    assert all(p.iterations == 4 for p in sweep)
    with pytest.raises(ValueError, match="NAME=V1,V2"):
        common.physics_sweep(base, "8,16")
    with pytest.raises(ValueError, match="unknown setting 'cell'"):
        common.physics_sweep(base, "cell=8")
    with pytest.raises(ValueError, match="power of two"):
        common.physics_sweep(base, "hash_cell=8,12")


def test_mase_verdicts_read_the_median_ratio_s_interval(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A task reaches its goal when the whole interval of its median ratio does,
    is short when the whole interval is, and is at the goal within the noise
    otherwise; with too few alternations there is no interval to read."""
    mase = common.bench_module("mase")
    series = {
        ("gate_escape", "mase+sdbc"): mase.Series(cpu=[2.0] * 5),
        ("gate_escape", "rigid+sdbc"): mase.Series(cpu=[2.5, 2.6, 2.45, 2.42, 2.7]),
        ("gate_escape", "kinematic+sdbc"): mase.Series(cpu=[7.8, 8.2, 7.9, 7.0, 7.5]),
        ("predator_prey", "mase+sdbc"): mase.Series(cpu=[1.0] * 5),
        ("predator_prey", "rigid+sdbc"): mase.Series(cpu=[1.2, 1.3, 1.1, 1.4, 1.3]),
        ("predator_prey", "kinematic+sdbc"): mase.Series(
            cpu=[4.0, 4.1, 4.2, 4.05, 4.3]
        ),
    }
    names, models = ["gate_escape", "predator_prey"], ["rigid", "kinematic"]
    mase.verdicts(series, names, models, None)
    out = capsys.readouterr().out
    assert "gate_escape      rigid     1.250 (1.21-1.35)   reaches the goal 1.2" in out
    assert "gate_escape      kinematic 3.900 (3.50-4.10)   AT the goal within" in out
    assert "predator_prey    rigid     1.300 (1.10-1.40)   AT the goal within" in out
    assert "predator_prey    kinematic 4.100 (4.00-4.30)   reaches the goal 4" in out
    mase.verdicts(series, names, models, None, {"rigid": 1.5, "kinematic": 3.5})
    out = capsys.readouterr().out
    assert "gate_escape      rigid     1.250 (1.21-1.35)   SHORT of the goal 1.5" in out
    assert "gate_escape      kinematic 3.900 (3.50-4.10)   reaches the goal 3.5" in out
    three = {key: mase.Series(cpu=v.cpu[:3]) for key, v in series.items()}
    mase.verdicts(three, names, models, None)
    out = capsys.readouterr().out
    assert (
        "predator_prey    kinematic 4.100 (too few alternations) CANNOT TELL, goal 4"
        in out
    )


def test_mase_runs_each_configuration_of_ours_in_a_warm_process_of_its_own(
    tmp_path: Path,
) -> None:
    """Each configuration of ours runs its batches in its own process, warmed up
    first, with the genomes and seeds the same generator gives in this one
    (the batch's robot-steps and mean fitness)."""
    mase = common.bench_module("mase")
    configs = [("kinematic", True), ("rigid", False)]
    ours = [
        mase.EngineProcess(
            "resource_sharing", model, sdbc, 2, 2, 7, tmp_path / f"{k}.log"
        )
        for k, (model, sdbc) in enumerate(configs)
    ]
    try:
        assert len({os.getpid(), *(e.proc.pid for e in ours)}) == 3
        for e, (model, sdbc) in zip(ours, configs, strict=True):
            rng = np.random.default_rng(7)
            mase.engine_batch("resource_sharing", 10, 2, sdbc, rng, model)
            want = mase.engine_batch("resource_sharing", 2, 2, sdbc, rng, model)
            steps, cpu, wall, fitness = e.batch()
            assert (steps, fitness) == (want[0], want[3])
            assert cpu > 0 and wall > 0
    finally:
        for e in ours:
            e.close()
    assert [e.proc.returncode for e in ours] == [0, 0]


def test_the_median_interval_takes_the_order_statistics_of_its_coverage() -> None:
    mase = common.bench_module("mase")
    assert mase.median_interval([5.0, 1.0, 3.0, 2.0, 4.0]) == (1.0, 5.0)
    assert mase.median_interval([float(v) for v in range(1, 10)]) == (2.0, 8.0)
    assert mase.median_interval([float(v) for v in range(1, 21)]) == (6.0, 15.0)
    assert mase.median_interval([1.0, 2.0, 3.0]) is None
    assert mase.median_interval([1.0, 2.0, 3.0], level=0.75) == (1.0, 3.0)


def test_mase_goals_parse_and_refuse() -> None:
    mase = common.bench_module("mase")
    assert mase.parse_goals(None) == mase.GOALS
    assert mase.parse_goals(["rigid=1.5"])["rigid"] == 1.5
    with pytest.raises(ValueError, match="MODEL=RATIO"):
        mase.parse_goals(["soft=2"])
    with pytest.raises(ValueError, match="number > 0"):
        mase.parse_goals(["kinematic=zero"])


def test_study_bench_runs_a_cut_preset_alone_and_joined(
    capsys: pytest.CaptureFixture[str],
) -> None:
    study = common.bench_module("study")
    preset = BENCH.parent / "configs" / "study" / "smoke.yaml"
    argv = ["--preset", str(preset), "--task", "gate_escape", "--runs", "1"]
    cores = os.sched_getaffinity(0)
    try:
        assert study.main([*argv, "--generations", "2", "--alternations", "1"]) == 0
    finally:
        os.sched_setaffinity(0, cores)  # the bench pins the process it runs in
    out = capsys.readouterr().out
    assert "smoke.yaml cut to 1 runs per treatment and 2 generations" in out
    (row,) = [line for line in out.splitlines() if line.startswith("gate_escape")]
    assert row.endswith("yes")


def test_mase_says_whether_a_fused_step_could_reach_the_goal() -> None:
    """What a step fused into its compiled passes would still pay (the physics
    and the compiled loops, as a share of the profiled step, at the runs' median
    step) is set against the cost per robot-step the goal allows: above it, no
    fusing reaches the goal; below it, the rest is what would have to go; a
    median step within it is short by the runs' spread."""
    mase = common.bench_module("mase")
    seconds = dict.fromkeys(engine_profile.PARTS, 0.0)
    seconds |= {"kinematic step": 20e-9, "compiled loops": 140e-9, "network": 40e-9}
    p = engine_profile.Profile(
        task="gate_escape",
        sdbc=True,
        n_trials=1,
        steps=1,
        robot_steps=1,
        total=200e-9,
        seconds=seconds,
        calls=dict.fromkeys(engine_profile.PARTS, 0),
    )
    floor = engine_profile.FUSED_FLOOR
    assert p.ns(*floor) == pytest.approx(160.0)
    # 80 % of the profiled step, at a median step of 180 ns: 144.
    short = mase.fused_floor(p, 180.0, 139.0, floor)
    assert "80% of this batch's step, so about 144 of the runs' median 180" in short
    assert "more than the 139 the goal allows" in short
    assert "would be short" in short
    room = mase.fused_floor(p, 180.0, 160.0, floor)
    assert "so about 144 of the runs' median 180 ns per robot-step;" in room
    assert "the goal allows 160, so 20 of the other 36" in room
    within = mase.fused_floor(p, 180.0, 190.0, floor)
    assert "median step, 180 ns per robot-step, is within the 190" in within

"""Trial slots in pymunk, and what the contact solver lets robots do."""

from __future__ import annotations

import math

import numpy as np
import pymunk.batch as pb
import pytest
from sdbc_sim.engine import BatchSimulation, EngineSettings, TrialStepper
from sdbc_sim.physics import PhysicsSettings, SlotGrid, TrialSpaces
from sdbc_sim.sensors import point_segment_distance
from sdbc_sim.separation import project_apart
from sdbc_sim.tasks import make_task


def test_slots_share_one_float_exponent_and_never_overlap() -> None:
    grid = SlotGrid.fit((-100.0, 0.0, 200.0, 200.0), margin=13.0, cell=8.0)
    assert grid.spacing == 512.0 and grid.columns == 128
    offsets = np.array([grid.offset(s) for s in range(grid.capacity)])
    lows = offsets + [-100.0, 0.0]
    highs = offsets + [200.0, 200.0]
    assert np.all(np.frexp(lows)[1] == 17) and np.all(np.frexp(highs)[1] == 17)
    assert np.all(np.mod(offsets, 8.0) == 0.0)
    corners = offsets - grid.origin
    assert np.all(lows - 13.0 >= corners) and np.all(highs + 13.0 <= corners + 512.0)


def test_bad_physics_settings_are_named() -> None:
    with pytest.raises(ValueError, match="hash_cell must be a power of two"):
        PhysicsSettings(hash_cell=6.0)
    with pytest.raises(ValueError, match="trials_per_space must be >= 1"):
        PhysicsSettings(trials_per_space=0)
    with pytest.raises(ValueError, match="dt must be positive"):
        PhysicsSettings(dt=-1.0)
    with pytest.raises(ValueError, match="too large for one slot"):
        SlotGrid.fit((0.0, 0.0, 70000.0, 10.0), margin=1.0, cell=8.0)
    # An arena that fits, with robots whose default cell does not: the message
    # names the cell, which the caller can set smaller.
    with pytest.raises(ValueError, match="hash cell of 32768.0.*smaller hash_cell"):
        SlotGrid.fit(
            (0.0, 0.0, 20000.0, 20000.0), margin=4000.0 + 32768.0, cell=32768.0
        )
    assert SlotGrid.fit((0.0, 0.0, 20000.0, 20000.0), 4000.0 + 4096.0, 4096.0).columns


def test_random_controllers_never_sink_into_walls_or_each_other(pushing_crowd) -> None:
    """8 robots in a 60 x 60 arena under random outputs for 1000 steps: no robot
    overlaps a wall or another robot by more than 5% of its radius."""
    task = pushing_crowd
    r = task.config.robot_radius
    sim = BatchSimulation(task, np.arange(40))
    rng = np.random.default_rng(0)
    worst_wall = worst_robot = -np.inf
    touching = 0
    while not sim.finished:
        out = rng.uniform(0.0, 1.0, (sim.live.shape[0], 8, 3))
        out[..., 2] *= 0.55  # stop rarely, so robots keep pushing
        sim.step(out)
        on = sim.bodies.enabled
        pos = sim.bodies.position
        wall = r - point_segment_distance(pos, task.walls).min(axis=-1)
        worst_wall = max(worst_wall, float(np.max(wall[on], initial=-np.inf)))
        gap = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
        both = on[:, :, None] & on[:, None] & ~np.eye(8, dtype=bool)
        sink = 2 * r - gap[both]
        touching += int((sink > -0.01).sum())
        worst_robot = max(worst_robot, float(np.max(sink, initial=-np.inf)))
    assert touching > 1000  # they did push against each other
    assert worst_wall <= 0.05 * r
    assert worst_robot <= 0.05 * r


def test_a_robot_driven_into_a_wall_slides_along_it(placed) -> None:
    task = placed(
        make_task("gate_escape"),
        [[100.0, 190.0], [150.0, 20.0], [150.0, 60.0], [150.0, 100.0]],
        [math.pi / 4, 0.0, 0.0, 0.0],
    )
    sim = BatchSimulation(task, np.array([0]))
    out = np.zeros((1, 4, 3))
    out[0, 0] = [1.0, 0.5, 0.0]
    out[0, 1:, 2] = 1.0
    for _ in range(60):
        sim.step(out)
    x, y = sim.bodies.position[0, 0]
    # Heading 45 degrees into the top wall: it stops at y = 200 - r and keeps
    # sliding right at cos 45 per step (friction 0).
    assert y == pytest.approx(197.5, abs=0.05 * 2.5)
    assert x > 100.0 + 50 * math.cos(math.pi / 4)


def _track(actuation: str, placed, commands: list[float]) -> list[float]:
    """x of a gate-escape robot facing +x in the open, after each step, driven
    straight at ``commands[k - 1]`` x max speed (1) at step k; the other robots
    stay parked far away."""
    task = placed(
        make_task("gate_escape"),
        [[100.0, 100.0], [150.0, 20.0], [150.0, 60.0], [150.0, 180.0]],
        [0.0, 0.0, 0.0, 0.0],
    )
    settings = EngineSettings(PhysicsSettings(actuation=actuation))
    stepper = TrialStepper(task, settings)
    stepper.reset(0)
    xs = []
    for speed in commands:
        out = np.zeros((4, 3))
        out[:, 1] = 0.5
        out[:, 2] = 1.0
        out[0] = [speed, 0.5, 0.0 if speed > 0.0 else 1.0]
        stepper.step(out)
        xs.append(float(stepper.state().groups[0].centres[0, 0, 0]))
    return xs


def test_velocity_actuation_moves_a_robot_in_the_step_it_is_commanded(
    placed,
) -> None:
    """Stopped for steps 1-2, full speed (1 per step) at steps 3-5, stopped at 6-7.

    Velocity actuation writes v* before chipmunk integrates positions, so the
    robot is at 101 after step 3 and 103 after step 5, and the stop at step 6
    leaves it at 103. Force actuation gives it v* only at the end of step 3, so it
    first moves during step 4 (101 after step 4, 102 after step 5), and at the
    stop of step 6 it still coasts 1 unit during that step, stopping at 103.
    """
    commands = [0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0]
    velocity = _track("velocity", placed, commands)
    force = _track("force", placed, commands)
    np.testing.assert_allclose(
        velocity, [100, 100, 101, 102, 103, 103, 103], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        force, [100, 100, 100, 101, 102, 103, 103], rtol=0, atol=1e-12
    )
    # Stop after full speed: moved 0 (velocity) and 1 (force) after the stop.
    assert velocity[5] - velocity[4] == 0.0
    assert force[5] - force[4] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("actuation", ["velocity", "force"])
def test_headings_are_kept_beside_chipmunk_through_steps_and_compaction(
    actuation: str,
) -> None:
    task = make_task("gate_escape")
    rng = np.random.default_rng(0)
    _, position, angle = task.reset([np.random.default_rng(s) for s in range(5)])
    spaces = TrialSpaces.of_task(
        task, position, angle, PhysicsSettings(actuation=actuation, trials_per_space=2)
    )
    rows = np.empty((angle.size, 5))
    spaces.read(rows)
    np.testing.assert_array_equal(rows[:, 2], angle.reshape(-1))
    drive = np.zeros((angle.size, 4))
    col = spaces.drive_columns
    for _ in range(3):
        drive[:, col.angle] = rng.uniform(-np.pi, np.pi, angle.size)
        spaces.step(drive, rows)
        np.testing.assert_array_equal(rows[:, 2], drive[:, col.angle])
    keep = np.array([True, False, True, True, False])
    spaces.compact(keep)
    kept = np.empty((int(keep.sum()) * angle.shape[1], 5))
    spaces.read(kept)
    np.testing.assert_array_equal(kept, rows.reshape(5, -1, 5)[keep].reshape(-1, 5))
    # Chipmunk's bodies never turn: the heading is not its business.
    assert all(
        body.angle == 0.0
        for sp in spaces.spaces
        for bodies in sp.bodies.values()
        for body in bodies
    )


def test_actuation_must_be_known() -> None:
    with pytest.raises(ValueError, match="actuation must be one of velocity, force"):
        PhysicsSettings(actuation="impulse")  # type: ignore[arg-type]


def test_pymunk_buffers_are_reused_batch_after_batch(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # pymunk 7.3.1's Buffer never frees its C arrays, so a new one per Space and
    # batch grew memory without bound (bench/memory.py measures it): after a
    # warm-up, batches make no new Buffers.
    import gc

    import pymunk.batch as pb
    from sdbc_sim.engine import run_batch

    made: list[int] = []
    real = pb.Buffer

    class CountedBuffer(real):
        def __init__(self) -> None:
            made.append(1)
            super().__init__()

    monkeypatch.setattr(pb, "Buffer", CountedBuffer)
    task = make_task("gate_escape", max_steps=10)
    rng = np.random.default_rng(0)
    genomes = rng.uniform(-1, 1, (6, task.genome_length))
    counts = []
    for _ in range(8):
        seeds = rng.integers(0, 2**62, (6, 2), dtype=np.int64)
        run_batch(task, genomes, seeds)
        gc.collect()
        counts.append(len(made))
    assert counts[2:] == [counts[2]] * 6, counts


def array_separate(spaces: TrialSpaces, out: np.ndarray, enabled: np.ndarray) -> None:
    """TrialSpaces.separate as whole-array numpy (deep contacts mapped to rows by
    searchsorted, the trials by np.unique, the moved centres by fancy indexing):
    the formulation the compiled loops replaced, kept as their oracle."""
    n = spaces.n_bodies
    tol = spaces._tolerance
    found = []
    for sp, rows in spaces._ranges:
        buf = pb.Buffer()
        fields = pb.ArbiterFields
        which = fields.BODY_A_ID | fields.BODY_B_ID | fields.CONTACT_COUNT
        pb.get_space_arbiters(sp.space, which | fields.DISTANCE_1, buf)
        ints = np.frombuffer(buf.int_buf(), dtype=np.uintp).reshape(-1, 3)
        depth = -np.frombuffer(buf.float_buf(), dtype=np.float64)
        ids = ints[(ints[:, 2] > 0) & (depth > tol), :2].ravel()
        at = np.minimum(np.searchsorted(sp.sorted_ids, ids), len(sp.sorted_ids) - 1)
        deep = np.where(sp.sorted_ids[at] == ids, sp.sorted_rows[at], -1)
        found.append((rows.start + deep[deep >= 0]) // n)
    trials = np.unique(np.concatenate(found))
    pos = out[:, 0:2].reshape(-1, n, 2)[trials]
    new = project_apart(
        pos,
        enabled[trials],
        spaces._radii,
        spaces._walls,
        tol,
        spaces.settings.separation_iterations,
    )
    t, i = np.nonzero(np.any(new != pos, axis=-1))
    rows = trials[t] * n + i
    out[rows, 0:2] = (new[t, i] + spaces._offsets[rows]) - spaces._offsets[rows]
    for sp, span in spaces._ranges:
        if np.any((rows >= span.start) & (rows < span.stop)):
            sp.moved = True


@pytest.mark.parametrize("per_space", [3, 500])
def test_the_compiled_separation_equals_the_array_formulation(per_space: int) -> None:
    """To the bit, and the same Spaces marked for a position write: a step that
    drives gate-escape robots, started in a heap and against the walls, into each
    other and into the walls at full speed (most trials overlap; in six, robots
    far apart do not), and two still trials whose overlap is just above and just
    below the tolerance."""
    task = make_task("gate_escape")
    rng = np.random.default_rng(per_space)
    b, r = 40, task.layout.n_bodies
    position = rng.uniform(2.0, 14.0, (b, r, 2))
    position[::7] += 60.0
    # The first two Spaces of three trials: robots far from everything.
    position[:6] = 50.0 + 20.0 * np.arange(r)[:, None]
    # Standing still, two robots that overlap by a little more and a little less
    # than the tolerance (0.02 of the radius 2.5).
    position[6:8] = 50.0 + 20.0 * np.arange(r)[:, None]
    position[6, 1] = position[6, 0] + (5.0 - 0.06, 0.0)
    position[7, 1] = position[7, 0] + (5.0 - 0.04, 0.0)
    angle = rng.uniform(-math.pi, math.pi, (b, r))
    settings = PhysicsSettings(trials_per_space=per_space)
    results = []
    for separate in (TrialSpaces.separate, array_separate):
        spaces = TrialSpaces.of_task(task, position, angle, settings)
        state = np.empty((b * r, 5))
        spaces.read(state)
        drive = np.zeros((b * r, 4))
        cols = spaces.drive_columns
        drive[:, cols.angle] = state[:, 2]
        drive[:, cols.x] = -np.cos(state[:, 2])
        drive[:, cols.y] = -1.0
        drive[6 * r : 8 * r, cols.x :] = 0.0
        spaces.step(drive, state)
        enabled = np.ones((b, r), dtype=bool)
        enabled[1] = False
        before = state.copy()
        separate(spaces, state, enabled)
        results.append((state, [sp.moved for sp in spaces.spaces]))
    (got, got_moved), (want, want_moved) = results
    np.testing.assert_array_equal(got, want)
    assert got_moved == want_moved
    assert any(want_moved) and (per_space == 500 or not all(want_moved))
    assert not np.array_equal(got[6 * r : 7 * r], before[6 * r : 7 * r])
    np.testing.assert_array_equal(got[7 * r : 8 * r], before[7 * r : 8 * r])

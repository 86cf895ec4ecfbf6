"""Rendering a trial to an animated GIF."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image
from sdbc_sim.render import record_trial, render_trial
from sdbc_sim.tasks import make_task


def test_gif_has_a_frame_per_drawn_step(tmp_path) -> None:
    task = make_task("gate_escape", max_steps=23)
    genome = np.random.default_rng(0).uniform(-1, 1, task.genome_length)
    path = render_trial(task, genome, 4, tmp_path / "trial.gif", every=5)
    with Image.open(path) as gif:
        assert gif.n_frames == 6  # steps 1, 6, 11, 16, 21 and the last, 23
        assert gif.size[0] > 100


def test_recording_matches_the_trial() -> None:
    task = make_task("gate_escape", max_steps=12)
    genome = np.random.default_rng(1).uniform(-1, 1, task.genome_length)
    states, bodies = record_trial(task, genome, 2)
    assert [s.step for s in states] == list(range(1, 13))
    assert len(bodies) == 13
    np.testing.assert_array_equal(states[-1].groups[0].centres[0], bodies[-1][0])


def test_bad_render_settings() -> None:
    task = make_task("gate_escape", max_steps=5)
    with pytest.raises(ValueError, match="every and fps must be >= 1"):
        render_trial(task, np.zeros(108), 0, "x.gif", every=0)

"""When the compiled loops are loaded: never on import, always at a batch's setup.

Each check runs in a fresh interpreter: in the test process, other tests will
have loaded the loops already.
"""

from __future__ import annotations

import subprocess
import sys


def fresh(code: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    return done.stdout.strip()


def test_importing_the_simulator_and_its_tasks_does_not_import_numba() -> None:
    """A controller node or a command-line tool never pays for numba."""
    code = (
        "import sys, sdbc_sim, sdbc_sim.tasks, sdbc_sim.nodes.controller_node\n"
        "print('numba' in sys.modules)"
    )
    assert fresh(code) == "False"


def test_a_start_drawn_before_the_loops_load_does_not_import_numba() -> None:
    """The starts drawn in bulk (resource sharing's, gate escape's) are drawn one
    by one in a process that has not loaded the loops."""
    code = (
        "import sys, numpy as np\n"
        "from sdbc_sim.tasks import make_task\n"
        "for name in ('gate_escape', 'resource_sharing'):\n"
        "    make_task(name).reset([np.random.default_rng(s) for s in range(3)])\n"
        "print('numba' in sys.modules)"
    )
    assert fresh(code) == "False"


def test_setting_up_a_batch_loads_every_loop() -> None:
    """Even a trial that never needs a loop (a still team, no walls) loads them."""
    code = (
        "import numpy as np\n"
        "from sdbc_sim import compiled\n"
        "from sdbc_sim.engine import run_batch\n"
        "from sdbc_sim.tasks import make_task\n"
        "task = make_task('resource_sharing', max_steps=2)\n"
        "run_batch(task, np.zeros((1, task.genome_length)), np.zeros((1, 1), int))\n"
        "loops = compiled._LOOPS\n"
        "print(len(loops) > 0, all(loop.kernel is not None for loop in loops))"
    )
    assert fresh(code) == "True True"


def test_a_helper_edited_in_another_module_is_compiled_again(tmp_path) -> None:
    """numba keeps a loop's cache while the loop's own file is unchanged, though
    the cached loop holds its helpers' code: a helper of another module that was
    edited must not go on running as it was."""
    (tmp_path / "helper.py").write_text("def combine(a, b):\n    return a + b\n")
    (tmp_path / "loop.py").write_text(
        "from sdbc_sim.compiled import compiled\n"
        "from helper import combine\n"
        "@compiled('float64(float64, float64)', calls=(combine,))\n"
        "def apply(a, b):\n"
        "    return combine(a, b)\n"
    )
    run = (
        "import sys; sys.path.insert(0, sys.argv[1]); import loop; "
        "print(loop.apply(3.0, 1.0))"
    )

    def fresh_run() -> str:
        done = subprocess.run(
            [sys.executable, "-c", run, str(tmp_path)],
            capture_output=True,
            text=True,
            check=True,
        )
        return done.stdout.strip()

    assert fresh_run() == "4.0"
    assert fresh_run() == "4.0"  # from the cache
    (tmp_path / "helper.py").write_text("def combine(a, b):\n    return a - b\n")
    assert fresh_run() == "2.0"

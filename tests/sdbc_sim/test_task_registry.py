"""Tasks named from anywhere: a registered name, package.module:Class, a file of
one's own, or an entry point of an installed distribution."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from sdbc_sim.tasks import (
    ENTRY_POINT_GROUP,
    UnknownTask,
    available_tasks,
    find_task,
    is_file_reference,
    make_task,
    resolve_task,
    task_reference,
)
from sdbc_sim.tasks.gate_escape import GateEscape

MY_TASK = '''\
"""A gate escape with a wider gate: a task of one's own, outside the package."""

from sdbc_sim.settings import settings
from sdbc_sim.tasks.gate_escape import GateEscape, GateEscapeConfig


@settings
class WideGateConfig(GateEscapeConfig):
    """Gate escape's settings with a wider gate."""

    gate_width: float = 40.0
    """Width of the gate opening."""


class WideGate(GateEscape):
    """Gate escape through a 40-unit gate."""

    name = "wide_gate"
    config_class = WideGateConfig
    default_generations = 30
'''


@pytest.fixture
def task_file(tmp_path: Path) -> Path:
    path = tmp_path / "my_tasks" / "wide.py"
    path.parent.mkdir()
    path.write_text(MY_TASK)
    return path


@pytest.fixture
def fresh_registry() -> Iterator[None]:
    available_tasks.cache_clear()
    yield
    available_tasks.cache_clear()


def test_a_registered_name_and_a_module_reference_name_the_same_class() -> None:
    assert resolve_task("gate_escape") is GateEscape
    assert resolve_task("sdbc_sim.tasks.gate_escape:GateEscape") is GateEscape
    assert (
        make_task("sdbc_sim.tasks.gate_escape:GateEscape", max_steps=7).max_steps == 7
    )


def test_a_task_in_a_file_of_ones_own(
    task_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(task_file.parent.parent)
    relative = "my_tasks/wide.py:WideGate"
    assert is_file_reference(relative)
    absolute = task_reference(relative)
    assert absolute == f"{task_file}:WideGate"
    task = make_task(relative, max_steps=20)
    assert type(task).name == "wide_gate" and task.config.gate_width == 40.0
    assert resolve_task(absolute) is type(task)  # loaded once per process
    with pytest.raises(ValueError, match="gate_width: .* valid number, got 'wide'"):
        make_task(relative, gate_width="wide")


def test_a_file_task_runs_the_same_in_another_process(task_file: Path) -> None:
    import numpy as np
    from sdbc_sim.engine import run_batch

    reference = task_reference(str(task_file) + ":WideGate")
    task = make_task(reference, max_steps=40)
    genome = np.linspace(-1, 1, task.genome_length)[None]
    here = run_batch(task, genome, np.array([[3]])).fitness[0, 0]
    program = (
        "import numpy as np, sys\n"
        "from sdbc_sim.engine import run_batch\n"
        "from sdbc_sim.tasks import make_task\n"
        "task = make_task(sys.argv[1], max_steps=40)\n"
        "g = np.linspace(-1, 1, task.genome_length)[None]\n"
        "print(run_batch(task, g, np.array([[3]])).fitness[0, 0].hex())\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", program, reference],
        capture_output=True,
        text=True,
        check=True,
        cwd="/",
    ).stdout
    assert float.fromhex(out.strip()) == here


def test_an_entry_point_registers_a_task(
    tmp_path: Path,
    task_file: Path,
    monkeypatch: pytest.MonkeyPatch,
    fresh_registry: None,
) -> None:
    # An installed distribution, as pip writes it: its module and its dist-info.
    site = tmp_path / "site"
    (site / "wide_pkg").mkdir(parents=True)
    (site / "wide_pkg" / "__init__.py").write_text(MY_TASK)
    info = site / "wide_pkg-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: wide-pkg\nVersion: 1.0\n"
    )
    (info / "entry_points.txt").write_text(
        f"[{ENTRY_POINT_GROUP}]\nwide_gate = wide_pkg:WideGate\n"
    )
    monkeypatch.syspath_prepend(str(site))
    assert "wide_gate" in available_tasks() and "gate_escape" in available_tasks()
    assert make_task("wide_gate").config.gate_width == 40.0


def test_an_unknown_task_lists_the_known_ones_and_how_to_register_one() -> None:
    with pytest.raises(UnknownTask) as caught:
        resolve_task("gate_scape")
    message = str(caught.value)
    for part in ("unknown task 'gate_scape'", "gate_escape", "predator_prey"):
        assert part in message
    assert "package.module:Class" in message and "path/to/file.py:Class" in message
    assert f"'{ENTRY_POINT_GROUP}'" in message and "pyproject.toml" in message
    assert find_task("gate_scape") is None


@pytest.mark.parametrize(
    ("reference", "message"),
    [
        ("no_such_module_xyz:Task", "cannot import module 'no_such_module_xyz'"),
        ("sdbc_sim.tasks.gate_escape:Nothing", "has no 'Nothing'"),
        ("sdbc_sim.tasks.gate_escape:GateEscapeConfig", "not a subclass of"),
        ("/no/such/file.py:Task", "no file /no/such/file.py"),
    ],
)
def test_references_that_name_no_task_are_refused(reference: str, message: str) -> None:
    with pytest.raises(UnknownTask, match=message):
        resolve_task(reference)


def test_a_task_class_must_declare_its_default_generations(tmp_path: Path) -> None:
    path = tmp_path / "half.py"
    # GateEscape itself declares default_generations, so inherit from Task.
    path.write_text(
        "from sdbc_sim.task import Task\n"
        "from sdbc_sim.tasks.gate_escape import GateEscapeConfig\n"
        "class Half(Task):\n"
        "    name = 'half'\n"
        "    config_class = GateEscapeConfig\n"
    )
    with pytest.raises(UnknownTask, match="does not declare default_generations"):
        resolve_task(f"{path}:Half")

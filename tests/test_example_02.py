"""The method as a library: tutorial 02 runs, ``import sdbc_evolution`` is light,
and the two packages install without ROS 2 into a fresh venv where the tutorial,
the command lines and the ROS programs' one-line refusal work.

The fresh venv is made offline and honestly: the two packages are built into
wheels, installed with ``--no-deps --no-index``, and the venv sees, through one
``.pth`` file, links to exactly the distributions their declared requirements
name (transitively, as this environment has them installed), so a requirement
missing from a ``setup.py`` is an import error there; ROS 2 (rclpy, sdbc_msgs),
which this environment also has, stays out of it.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import zipfile
from importlib.metadata import Distribution, PackageNotFoundError, distribution
from pathlib import Path

import pytest
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "02_own_loop" / "own_loop.py"
PACKAGES = ("sdbc_sim", "sdbc_evolution")
HEAVY = ("rclpy", "pymunk", "numba")
SOURCE_PATH = os.pathsep.join(str(ROOT / "src" / p) for p in PACKAGES)


def python(code: str, env: dict[str, str] | None = None) -> str:
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env=env or {**os.environ, "PYTHONPATH": SOURCE_PATH},
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_the_tutorial_fits_in_twenty_lines() -> None:
    assert len(EXAMPLE.read_text().splitlines()) <= 20


@pytest.mark.slow
def test_the_tutorial_evolves_with_ns_sd_plus() -> None:
    out = python(EXAMPLE.read_text())
    best = re.fullmatch(r"best fitness (\d\.\d{3}), generation (\d+)\n", out)
    assert best, out
    # A robot that stays where it starts scores about 0.5 on average; the
    # search finds controllers that walk to the beacon.
    assert float(best.group(1)) > 0.8


@pytest.mark.parametrize(
    ("module", "absent"),
    [
        ("sdbc_evolution", HEAVY),
        ("sdbc_evolution.sdbc", ("rclpy", "pymunk")),
        ("sdbc_sim.task_state", ("rclpy", "pymunk", "numba")),
        ("sdbc_sim.settings", ("rclpy", "pymunk", "numba")),
    ],
)
def test_importing_the_method_loads_neither_ros_nor_the_simulator(
    module: str, absent: tuple[str, ...]
) -> None:
    loaded = python(
        f"import sys, {module}\n"
        f"print(sorted({set(absent)!r} & {{m.split('.')[0] for m in sys.modules}}))"
    )
    assert loaded.strip() == "[]"


def test_the_curated_names_load_on_first_use_and_no_others() -> None:
    out = python(
        "import sys, sdbc_evolution as sd\n"
        "names = {n: getattr(sd, n) for n in sd.__all__}\n"
        "print(sorted(set(dir(sd)) >= set(sd.__all__) and names))\n"
        "print(sorted({'rclpy', 'pymunk', 'numba'} & set(sys.modules)))\n"
        "try:\n    sd.Nope\nexcept AttributeError as e:\n    print(e)\n"
    )
    lines = out.splitlines()
    assert "NoveltySearch" in lines[0] and "TaskState" in lines[0]
    assert lines[1] == "[]"
    assert lines[2] == "module 'sdbc_evolution' has no attribute 'Nope'"


# --- a fresh venv without ROS 2 ------------------------------------------------------


def normalised(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def closure(names: list[str]) -> dict[str, Distribution]:
    """The installed distributions ``names`` require, transitively (no extras)."""
    found: dict[str, Distribution] = {}
    todo = list(names)
    while todo:
        requirement = Requirement(todo.pop())
        key = normalised(requirement.name)
        if key in found:
            continue
        if requirement.marker is not None and not requirement.marker.evaluate(
            {"extra": ""}
        ):
            continue
        try:
            found[key] = distribution(requirement.name)
        except PackageNotFoundError:
            pytest.fail(f"{requirement.name} is required but not installed here")
        todo += found[key].requires or []
    return found


def link_distributions(dists: dict[str, Distribution], into: Path) -> None:
    """Links every top-level file and folder of ``dists`` into ``into``."""
    into.mkdir()
    for dist in dists.values():
        base = Path(str(dist.locate_file("")))
        tops = {Path(str(f)).parts[0] for f in dist.files or []}
        for top in sorted(tops - {"..", "__pycache__"}):
            target = into / top
            if (base / top).exists() and not target.exists():
                target.symlink_to(base / top)


def requirements_of(wheel: Path) -> list[str]:
    """The Requires-Dist of a wheel but its extras' requirements."""
    with zipfile.ZipFile(wheel) as archive:
        name = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        text = archive.read(name).decode()
    return [
        line.split(":", 1)[1].strip()
        for line in text.splitlines()
        if line.startswith("Requires-Dist:") and "extra ==" not in line
    ]


@pytest.mark.slow
def test_the_packages_install_and_work_without_ros(tmp_path: Path) -> None:
    # This environment's own paths (the colcon install, ROS 2) stay out of it.
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    sources = tmp_path / "src"
    for package in PACKAGES:
        shutil.copytree(
            ROOT / "src" / package,
            sources / package,
            ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"),
        )
    wheels = tmp_path / "wheels"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps"]
        + ["--no-build-isolation", "--no-index", "--wheel-dir", str(wheels)]
        + [str(sources / p) for p in PACKAGES],
        check=True,
        capture_output=True,
        env=clean,
    )
    built = sorted(wheels.glob("*.whl"))
    assert [w.name.split("-")[0] for w in built] == sorted(PACKAGES)
    needed = [
        r
        for w in built
        for r in requirements_of(w)
        if normalised(Requirement(r).name) not in {normalised(p) for p in PACKAGES}
    ]
    deps = closure(needed)
    assert not {"ros-jazzy-rclpy", "sdbc-sim", "sdbc-evolution"} & set(deps)
    venv = tmp_path / "venv"
    subprocess.run(
        [sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True
    )
    link_distributions(deps, tmp_path / "deps")
    (site,) = (venv / "lib").glob("python3*/site-packages")
    (site / "deps.pth").write_text(f"{tmp_path / 'deps'}\n")
    subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(venv / "bin" / "python")]
        + ["install", "--quiet", "--no-deps", "--no-index"]
        + [str(w) for w in built],
        check=True,
        capture_output=True,
        env=clean,
    )
    bin_dir = venv / "bin"
    env = {"PATH": f"{bin_dir}:/usr/bin:/bin", "HOME": str(tmp_path)}

    def run(*command: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            command, capture_output=True, text=True, env=env, cwd=tmp_path, check=False
        )

    # Every declared requirement is met, at its floor or above.
    checked = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(bin_dir / "python"), "check"],
        capture_output=True,
        text=True,
        env=clean,
        check=False,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr
    probe = run(
        str(bin_dir / "python"),
        "-c",
        "import importlib.util, sys, sdbc_evolution, sdbc_sim.tasks\n"
        "assert not {'rclpy', 'pymunk', 'numba'} & set(sys.modules)\n"
        "find = importlib.util.find_spec\n"
        "print(find('rclpy'), find('sdbc_msgs'))",
    )
    assert probe.returncode == 0, probe.stderr
    assert probe.stdout.split() == ["None", "None"]
    example = run(str(bin_dir / "python"), str(EXAMPLE))
    assert example.returncode == 0, example.stderr
    assert example.stdout.startswith("best fitness ")
    for command in ("sdbc-evolve", "sdbc-study", "sdbc-conformance"):
        helped = run(str(bin_dir / command), "--help")
        assert helped.returncode == 0, helped.stderr
    listed = run(str(bin_dir / "sdbc-evolve"), "--list-tasks")
    assert listed.returncode == 0 and "gate_escape" in listed.stdout, listed.stderr
    for node in ("simulator_node", "controller_node", "evolution_node", "sdbc-graph"):
        refused = run(str(bin_dir / node))
        assert refused.returncode == 2, refused.stderr
        assert refused.stderr.count("\n") == 1, refused.stderr
        assert "rclpy" in refused.stderr and "scripts/sdbc setup" in refused.stderr

"""The packages declare what they import, and depend on each other one way only.

sdbc_evolution builds on sdbc_sim; sdbc_sim must not import sdbc_evolution, or a
ROS 2 build (colcon orders packages by their package.xml) would see a cycle.

Every module a package imports at run time is declared in its package.xml under its
rosdep key, so that ``rosdep install --from-paths src`` on a ROS machine installs
it: a ROS package under its own name, a Python library under the key rosdep's
database gives it (``python3-numpy``), and one the database does not name under a
pip key (``python3-pymunk-pip``) that the root ``rosdep.yaml`` defines, naming pip
packages that requirements.txt pins.
"""

from __future__ import annotations

import ast
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
PYTHON_PACKAGES = ("sdbc_sim", "sdbc_evolution")
WORKSPACE = {"sdbc_msgs", "sdbc_sim", "sdbc_evolution"}

ROS_PACKAGES = {
    "ament_index_python",
    "builtin_interfaces",
    "geometry_msgs",
    "rcl_interfaces",
    "rclpy",
    "rosgraph_msgs",
    "std_msgs",
    "std_srvs",
    "visualization_msgs",
}
"""Imported ROS packages: their rosdep key is their name."""
ROSDEP_KEYS = {
    "matplotlib": "python3-matplotlib",
    "numba": "python3-numba",
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "sklearn": "python3-sklearn",
    "tqdm": "python3-tqdm",
    "yaml": "python3-yaml",
    # Not in rosdep's database: pip keys, defined in the root rosdep.yaml (the
    # database has python3-rosbags-pip; ours says the same).
    "dcor": "python3-dcor-pip",
    "distributed": "python3-dask-distributed-pip",
    "minisom": "python3-minisom-pip",
    "pymunk": "python3-pymunk-pip",
    # The database's python3-pydantic is pydantic 1 on Ubuntu 24.04.
    "pydantic": "python3-pydantic-pip",
    "rosbags": "python3-rosbags-pip",
    "threadpoolctl": "python3-threadpoolctl-pip",
}
"""Imported Python libraries and their rosdep keys (checked against rosdep's
database: ros/rosdistro, rosdep/python.yaml)."""


def imported_top_modules(package_dir: Path) -> set[str]:
    modules: set[str] = set()
    for path in package_dir.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                modules.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                modules.add(node.module.split(".")[0])
    return modules


def declared(package: str, tags: tuple[str, ...]) -> set[str]:
    root = ET.parse(SRC / package / "package.xml").getroot()
    return {e.text.strip() for e in root if e.tag in tags and e.text}


def exec_depends(package: str) -> set[str]:
    return declared(package, ("depend", "exec_depend"))


def rosdep_key(module: str) -> str | None:
    """The key that declares ``module``; None for the standard library."""
    if module in sys.stdlib_module_names:
        return None
    if module in WORKSPACE or module in ROS_PACKAGES:
        return module
    if module not in ROSDEP_KEYS:
        raise AssertionError(
            f"{module} is imported but has no rosdep key here: add it to "
            "ROSDEP_KEYS (its rosdep key, or a pip key defined in rosdep.yaml)"
        )
    return ROSDEP_KEYS[module]


def undeclared(imported: set[str], depends: set[str]) -> dict[str, str]:
    """The modules of ``imported`` whose key is not in ``depends``, with the key
    each needs."""
    keys = {module: rosdep_key(module) for module in sorted(imported)}
    return {m: k for m, k in keys.items() if k is not None and k not in depends}


def pinned_requirements() -> set[str]:
    """Names (normalised, extras kept) that requirements.txt pins with ``==``."""
    pinned = set()
    for line in (ROOT / "requirements.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            pinned.add(normalise(line.split("==", 1)[0]))
    return pinned


def normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower().strip()


def pip_key_problems(keys: set[str]) -> list[str]:
    """Pip keys that rosdep.yaml does not define, or whose pip packages
    requirements.txt does not pin."""
    path = ROOT / "rosdep.yaml"
    rules = yaml.safe_load(path.read_text()) if path.exists() else {}
    pinned = pinned_requirements()
    problems = []
    for key in sorted(k for k in keys if k.endswith("-pip")):
        rule = rules.get(key)
        try:
            packages = rule["ubuntu"]["pip"]["packages"]
        except (KeyError, TypeError):
            problems.append(f"{key}: not defined for ubuntu/pip in rosdep.yaml")
            continue
        for name in packages:
            # A floor ("pydantic>=2.0") names the package before its specifier.
            if normalise(re.split(r"[<>=!~;\s]", name, maxsplit=1)[0]) not in pinned:
                problems.append(
                    f"{key}: pip package {name} not pinned in requirements.txt"
                )
    return problems


def test_sdbc_sim_does_not_import_sdbc_evolution():
    assert "sdbc_evolution" not in imported_top_modules(SRC / "sdbc_sim" / "sdbc_sim")


def test_every_workspace_package_imported_is_declared():
    for package in PYTHON_PACKAGES:
        used = imported_top_modules(SRC / package / package) & WORKSPACE - {package}
        missing = used - exec_depends(package)
        assert not missing, f"{package} imports {missing} without an exec_depend"


def test_every_runtime_import_is_declared_with_its_rosdep_key():
    for package in PYTHON_PACKAGES:
        imported = imported_top_modules(SRC / package / package) - {package}
        missing = undeclared(imported, exec_depends(package))
        assert not missing, (
            f"{package}/package.xml lacks <exec_depend> for {missing} "
            "(module: rosdep key)"
        )


def test_every_pip_key_is_defined_and_pinned():
    keys = set()
    for package in (*PYTHON_PACKAGES, "sdbc_msgs"):
        keys |= declared(
            package,
            (
                "depend",
                "exec_depend",
                "build_depend",
                "test_depend",
                "buildtool_depend",
            ),
        )
    problems = pip_key_problems(keys)
    assert not problems, "\n".join(problems)


def test_the_checks_see_an_undeclared_import():
    assert undeclared({"os", "numpy", "pymunk"}, {"python3-numpy"}) == {
        "pymunk": "python3-pymunk-pip"
    }
    with pytest.raises(AssertionError, match="no_such_module is imported"):
        undeclared({"no_such_module"}, set())


def test_the_checks_see_an_undefined_or_unpinned_pip_key():
    problems = pip_key_problems({"python3-pymunk-pip", "python3-no-such-thing-pip"})
    assert problems == [
        "python3-no-such-thing-pip: not defined for ubuntu/pip in rosdep.yaml"
    ]
    assert normalise("dask[distributed]") in pinned_requirements()
    assert normalise("no-such-thing") not in pinned_requirements()

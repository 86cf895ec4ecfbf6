"""The packages depend on each other in one direction only, as package.xml says.

sdbc_evolution builds on sdbc_sim; sdbc_sim must not import sdbc_evolution, or a
ROS 2 build (colcon orders packages by their package.xml) would see a cycle.
"""

from __future__ import annotations

import ast
import xml.etree.ElementTree as ET
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"


def imported_top_modules(package_dir: Path) -> set[str]:
    modules: set[str] = set()
    for path in package_dir.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                modules.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                modules.add(node.module.split(".")[0])
    return modules


def exec_depends(package: str) -> set[str]:
    root = ET.parse(SRC / package / "package.xml").getroot()
    tags = ("depend", "exec_depend")
    return {e.text for e in root if e.tag in tags and e.text}


def test_sdbc_sim_does_not_import_sdbc_evolution():
    assert "sdbc_evolution" not in imported_top_modules(SRC / "sdbc_sim" / "sdbc_sim")


def test_every_workspace_package_imported_is_declared():
    workspace = {"sdbc_msgs", "sdbc_sim", "sdbc_evolution"}
    for package in ("sdbc_sim", "sdbc_evolution"):
        used = imported_top_modules(SRC / package / package) & workspace - {package}
        missing = used - exec_depends(package)
        assert not missing, f"{package} imports {missing} without an exec_depend"

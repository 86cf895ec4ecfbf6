"""The type checker passes over the packages' source (configuration in
pyproject.toml: [tool.mypy]).

mypy reads every module of src/sdbc_sim/sdbc_sim and src/sdbc_evolution/
sdbc_evolution; only the ROS 2 interface packages and libraries that ship no type
information are taken as untyped (``ignore_missing_imports``). Every function is
annotated (``disallow_untyped_defs``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.slow


def test_mypy_finds_no_errors_in_src():
    result = subprocess.run(
        [sys.executable, "-m", "mypy"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Success: no issues found" in result.stdout

#!/usr/bin/env python3
"""Sets up the project on a fresh machine, idempotently: venv, wheels, colcon build.

Run by ``scripts/sdbc`` before every command; when nothing changed it does no work
(a few hundred milliseconds). Steps, each skipped when its stamp is current:

1. Checks the system tools that the build needs (a C and C++ compiler, cmake, make).
2. Creates ``.venv`` and installs ``requirements.txt`` (ROS 2 Jazzy from PyPI wheels
   and the Python dependencies), re-installing only when that file changes.
3. Rewrites the wheel builder's paths in the rosidl CMake exports to this
   interpreter's include directories (the wheels name ``/opt/python/cp3XX-cp3XX``).
4. Builds the workspace (``src/``) with colcon, again only when a package's
   definition or an interface changed. Python packages are symlink-installed, so
   editing their sources needs no rebuild.

Only the standard library is used: this runs before the venv exists.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
VENV_PYTHON = VENV / "bin" / "python"
REQUIREMENTS = ROOT / "requirements.txt"
SRC = ROOT / "src"
INSTALL = ROOT / "install"
PIP_STAMP = VENV / ".sdbc-requirements.sha256"
BUILD_STAMP = INSTALL / ".sdbc-build.sha256"

SUPPORTED_PYTHONS = ((3, 10), (3, 14))
# Tool -> how to get it on Debian/Ubuntu, the systems the ROS wheels target.
SYSTEM_TOOLS = {
    "cmake": "sudo apt-get install cmake",
    "make": "sudo apt-get install make",
    "cc": "sudo apt-get install gcc",
    "c++": "sudo apt-get install g++",
}


def fail(message: str) -> None:
    sys.stderr.write(f"sdbc set-up: {message}\n")
    sys.exit(1)


def say(message: str) -> None:
    sys.stderr.write(f"sdbc set-up: {message}\n")
    sys.stderr.flush()


def check_system() -> None:
    low, high = SUPPORTED_PYTHONS
    if not low <= sys.version_info[:2] <= high:
        fail(
            f"Python {sys.version_info.major}.{sys.version_info.minor} is not "
            "supported: "
            f"the ROS 2 Jazzy wheels exist for CPython {low[0]}.{low[1]} to "
            f"{high[0]}.{high[1]}. Run with PYTHON=python3.11 scripts/sdbc ..."
        )
    missing = [tool for tool in SYSTEM_TOOLS if shutil.which(tool) is None]
    if missing:
        hints = "; ".join(f"{tool}: {SYSTEM_TOOLS[tool]}" for tool in missing)
        fail(
            "missing system tools needed to build sdbc_msgs: "
            f"{', '.join(missing)} ({hints})"
        )


def digest(paths: list[Path], extra: str = "") -> str:
    h = hashlib.sha256(extra.encode())
    for path in sorted(paths):
        h.update(str(path.relative_to(ROOT)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def stamp_is(stamp: Path, value: str) -> bool:
    return stamp.is_file() and stamp.read_text().strip() == value


def run(cmd: list[str], env: dict[str, str] | None = None) -> None:
    say("$ " + " ".join(cmd))
    result = subprocess.run(cmd, cwd=ROOT, env=env)
    if result.returncode != 0:
        fail(f"command failed with exit code {result.returncode}: {' '.join(cmd)}")


def ensure_venv() -> None:
    if not VENV_PYTHON.exists():
        run([sys.executable, "-m", "venv", str(VENV)])
    wanted = digest([REQUIREMENTS], extra=sys.version)
    if stamp_is(PIP_STAMP, wanted):
        return
    run([str(VENV_PYTHON), "-m", "pip", "install", "--quiet", "-r", str(REQUIREMENTS)])
    PIP_STAMP.write_text(wanted + "\n")


def venv_include_dirs() -> tuple[str, str]:
    """This venv's Python and numpy include directories."""
    out = subprocess.run(
        [
            str(VENV_PYTHON),
            "-c",
            "import sysconfig, numpy; print(sysconfig.get_paths()['include']); "
            "print(numpy.get_include())",
        ],
        env={**os.environ, **runtime_env()},
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split("\n")
    return out[0], out[1]


def fix_cmake_exports() -> None:
    """Points the rosidl Python exports at this interpreter.

    docs/ros2-from-pypi.md, pitfall 1."""
    python_include, numpy_include = venv_include_dirs()
    builder_numpy = re.compile(
        r"/opt/python/cp3\d+-cp3\d+/lib/python3\.\d+/site-packages/numpy/[\w/]*include"
    )
    builder_python = re.compile(r"/opt/python/cp3\d+-cp3\d+/include/python3\.\d+")
    for path in (VENV / "share").glob("*/cmake/*__rosidl_generator_pyExport.cmake"):
        text = path.read_text()
        fixed = builder_python.sub(
            python_include, builder_numpy.sub(numpy_include, text)
        )
        if fixed != text:
            path.write_text(fixed)


def runtime_env() -> dict[str, str]:
    """The variables scripts/env.sh sets, for the build's subprocesses."""
    out = subprocess.run(
        ["bash", "-c", f"source {ROOT / 'scripts' / 'env.sh'} && env -0"],
        capture_output=True,
        check=True,
    ).stdout
    return dict(item.split("=", 1) for item in out.decode().split("\0") if "=" in item)


def package_definition_files() -> list[Path]:
    """Files whose change needs a colcon rebuild: interfaces and package metadata."""
    files = [p for p in (SRC / "sdbc_msgs").rglob("*") if p.is_file()]
    for package in ("sdbc_sim", "sdbc_evolution"):
        base = SRC / package
        files += [base / name for name in ("package.xml", "setup.py", "setup.cfg")]
        files += [p for p in (base / "resource").glob("*") if p.is_file()]
    return files


def build_workspace() -> None:
    wanted = digest(package_definition_files(), extra=sys.version)
    if stamp_is(BUILD_STAMP, wanted) and (INSTALL / "setup.bash").exists():
        return
    # The build sees only the venv's prefix: the workspace's install/ may not exist.
    env = {**runtime_env(), "AMENT_PREFIX_PATH": str(VENV)}
    run(
        [
            str(VENV / "bin" / "colcon"),
            "--log-base",
            str(ROOT / "log"),
            "build",
            "--base-paths",
            str(SRC),
            "--build-base",
            str(ROOT / "build"),
            "--install-base",
            str(INSTALL),
            "--symlink-install",
            "--event-handlers",
            "console_direct-",
            "--cmake-args",
            f"-DPython3_EXECUTABLE={VENV_PYTHON}",
            "-DBUILD_TESTING=OFF",
        ],
        env=env,
    )
    BUILD_STAMP.write_text(wanted + "\n")


def main() -> None:
    check_system()
    ensure_venv()
    fix_cmake_exports()
    build_workspace()


if __name__ == "__main__":
    main()

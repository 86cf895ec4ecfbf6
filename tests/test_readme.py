"""The README's Python example runs as it is written, and the README stays a front
page: short, with the example a newcomer can paste."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 250
"""The README is a front page: the rest lives in docs/."""
MAX_EXAMPLE_LINES = 20


def first_python_block(text: str) -> str:
    """The body of the first fenced ```python block of ``text``."""
    match = re.search(r"^```python\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    assert match, "README.md has no ```python block"
    return match.group(1)


def test_the_readme_is_a_front_page() -> None:
    lines = README.read_text().splitlines()
    assert len(lines) <= MAX_LINES, f"README.md has {len(lines)} lines"
    example = first_python_block(README.read_text()).splitlines()
    assert len(example) <= MAX_EXAMPLE_LINES, f"the example has {len(example)} lines"


def test_the_readme_example_runs_as_written(tmp_path: Path) -> None:
    script = tmp_path / "readme_example.py"
    script.write_text(first_python_block(README.read_text()))
    # From an empty folder, as a reader who pasted it would run it.
    done = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p)),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    printed = done.stdout.splitlines()
    # One line per generation, then the best controller told.
    assert [line.split()[0] for line in printed[:-1]] == [str(g) for g in range(8)]
    best = re.fullmatch(r"best fitness (\S+) in generation (\d+)", printed[-1])
    assert best, printed
    assert 0.0 < float(best.group(1)) <= 1.0 and int(best.group(2)) < 8


def test_a_missing_example_is_caught() -> None:
    try:
        first_python_block("# title\n```bash\necho\n```\n")
    except AssertionError as error:
        assert "no ```python block" in str(error)
    else:
        raise AssertionError("a README without a python block passed")


def test_conformance_of_a_task_file_runs_from_the_callers_folder(
    tmp_path: Path,
) -> None:
    # The README's `scripts/sdbc conformance my_task.py:MyTask`, from the folder
    # that holds the file (scripts/sdbc runs everything else from the root).
    task = ROOT / "examples" / "01_custom_task" / "beacon_homing" / "task.py"
    (tmp_path / "my_task.py").write_text(task.read_text())
    command = [str(ROOT / "scripts" / "sdbc"), "conformance", "my_task.py:BeaconHoming"]
    done = subprocess.run(
        [*command, "--check", "declaration"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1/1 checks passed for my_task.py:BeaconHoming" in done.stdout


RESULT_ROW = re.compile(
    r"^\|[^|]+\|[^|]+\| (\d+) / (\d+) / (\d+) \| "
    r"\[report\]\((docs/study/[\w\-/]+\.md)\) \|$",
    flags=re.MULTILINE,
)
"""A row of the README's results table that gives a report's verdict counts."""


def test_the_results_table_gives_each_reports_own_counts() -> None:
    rows = RESULT_ROW.findall(README.read_text())
    assert rows, "the README's results table gives no verdict counts"
    for agree, disagree, inconclusive, report in rows:
        counted = re.search(
            rf"Of \d+ claims: {agree} agree, {disagree} disagree, "
            rf"{inconclusive} inconclusive",
            (ROOT / report).read_text(),
        )
        assert counted, f"{report} does not count {agree} / {disagree} / {inconclusive}"

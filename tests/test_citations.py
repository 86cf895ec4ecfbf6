"""Everything the repository cites is in it.

- No tracked text file refers to a path outside the repository: a relative path
  whose ``..`` climbs above the root, this machine's workspace (``/work/...``), or
  the planning notes the project started from (named in :data:`OUTSIDE_NAMES`),
  whose content lives in ``docs/`` now.
- Every repository path that README.md or a page under docs/ cites (in backticks,
  or as a Markdown link) exists, and every section of a docs/ page that a text
  cites by name (``docs/method.md, "Aggregation"``) is a heading there.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path, PurePosixPath

import pytest

ROOT = Path(__file__).resolve().parents[1]
SELF = Path(__file__).resolve().relative_to(ROOT).as_posix()

OUTSIDE_NAMES = ("SPEC.md", "ROS2-WHEELS.md", "ARCHITECTURE.md")
"""Files outside the repository that texts used to cite (case matters:
``docs/architecture.md`` is ours)."""
OUTSIDE_ROOTS = ("/work/",)
"""Absolute paths of this machine's workspace, which no clone has."""
ROOT_FOLDERS = ("src", "docs", "configs", "tests", "bench", "scripts")
"""Folders at the root: a span starting with one is a path even without an
extension (``scripts/sdbc``)."""
BINARY_SUFFIXES = {".png", ".gif", ".npz", ".npy", ".mcap", ".db3", ".pdf", ".jpg"}

RELATIVE_PATH = re.compile(r"(?<![\w.])((?:\.\./)+)([\w.\-]+)")
"""A relative path that climbs: its ``../`` run and the component after it."""
BACKTICKED = re.compile(r"`([^`\n]+)`")
LINK = re.compile(r"\]\(([^)\s]+)\)")
SECTION_CITATION = re.compile(r"(docs/[\w\-/]+\.md)[,:]?\s+\"([^\"\n]+)\"")
"""A page of docs/ cited with a section: ``docs/method.md, "Aggregation"``."""
PATH_LIKE = re.compile(r"[\w.\-]+(?:/[\w.\-+]*)+")
"""A span made of path components only (no spaces, placeholders or globs)."""


def tracked_text_files() -> list[Path]:
    listed = subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True
    ).stdout.decode()
    files = []
    for name in filter(None, listed.split("\0")):
        path = ROOT / name
        if name == SELF or path.suffix in BINARY_SUFFIXES or not path.is_file():
            continue
        data = path.read_bytes()
        if b"\0" in data:
            continue
        files.append(path)
    return files


def outside_references(text: str, where: PurePosixPath) -> list[str]:
    """What ``text`` (the file ``where``, relative to the root) cites outside the
    repository."""
    found = [name for name in OUTSIDE_NAMES if name in text]
    found += [root for root in OUTSIDE_ROOTS if root in text]
    depth = len(where.parent.parts)
    for match in RELATIVE_PATH.finditer(text):
        # Read from the file's folder, as a link or an editor would.
        if match.group(1).count("../") > depth:
            found.append(match.group(0))
    return found


def cited_paths(text: str) -> list[str]:
    """Repository paths that a Markdown ``text`` cites: links that are not URLs or
    anchors, and backticked spans (or a backticked command's first word) that are
    paths (:func:`is_path`; a ``:name`` after a ``.py`` file is dropped)."""
    cited = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        cited.append(target.split("#")[0])
    for span in BACKTICKED.findall(text):
        # A command's program (``scripts/sdbc evolve``), or the whole span.
        span = re.sub(r"(\.py):\w+$", r"\1", span.split()[0])
        if is_path(span):
            cited.append(span)
    return cited


def is_path(span: str) -> bool:
    """A backticked span is a path when it is made of path components, names a
    file (an extension), a folder (a trailing slash) or starts at one of the
    root's folders; not an interface name (``std_msgs/String``), a placeholder
    (``STUDY/report``) or an output (``results/...``)."""
    if not PATH_LIKE.fullmatch(span) or span.startswith(("results/", ".")):
        return False
    parts = [p for p in span.split("/") if p]
    if any(re.fullmatch(r"[A-Z_]+", p) for p in parts):
        return False
    return "." in parts[-1] or span.endswith("/") or parts[0] in ROOT_FOLDERS


def package_folders() -> list[Path]:
    """Each package's folder and its Python package's, where texts cite from."""
    packages = sorted(p.parent for p in ROOT.glob("src/*/package.xml"))
    return packages + [p / p.name for p in packages if (p / p.name).is_dir()]


def resolves(citation: str, document: Path) -> bool:
    """A path cited in ``document`` exists: from the document's folder, from the
    root, or inside a package (``sdbc_evolution/study/claims.py``, ``tasks/``)."""
    bases = [document.parent, ROOT, *package_folders()]
    return any((base / citation).exists() for base in bases)


def documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def missing_sections(text: str) -> list[str]:
    """The ``docs/PAGE.md, "Section"`` citations of ``text`` whose page has no
    heading holding that section's name."""
    missing = []
    for page, section in SECTION_CITATION.findall(text):
        path = ROOT / page
        headings = (
            [line for line in path.read_text().splitlines() if line.startswith("#")]
            if path.is_file()
            else []
        )
        if not any(section.lower() in h.lower() for h in headings):
            missing.append(f'{page}, "{section}"')
    return missing


def test_no_tracked_text_refers_outside_the_repository() -> None:
    offending = {}
    for path in tracked_text_files():
        relative = PurePosixPath(path.relative_to(ROOT).as_posix())
        text = path.read_text(errors="replace")
        found = outside_references(text, relative)
        if found:
            offending[str(relative)] = found
    assert offending == {}


def test_every_section_cited_in_docs_exists() -> None:
    offending = {}
    for path in tracked_text_files():
        missing = missing_sections(path.read_text(errors="replace"))
        if missing:
            offending[str(path.relative_to(ROOT))] = missing
    assert offending == {}


def test_a_missing_section_is_caught() -> None:
    text = 'see docs/method.md, "Aggregation" and docs/reference-setup.md "Nowhere"'
    assert missing_sections(text) == ['docs/reference-setup.md, "Nowhere"']


def test_every_path_cited_in_readme_and_docs_exists() -> None:
    missing = {}
    for document in documents():
        absent = [
            c for c in cited_paths(document.read_text()) if not resolves(c, document)
        ]
        if absent:
            missing[str(document.relative_to(ROOT))] = absent
    assert missing == {}


@pytest.mark.parametrize(
    ("text", "where", "expected"),
    [
        ("see ../elsewhere/paper/x.tex", "README.md", ["../elsewhere"]),
        ("see ../../x.md", "docs/a.md", ["../../x.md"]),
        ("see ../x.md", "docs/a.md", []),
        ("(SPEC.md, Evolution)", "src/a.py", ["SPEC.md"]),
        ("--out /work/main/results", "docs/r.md", ["/work/"]),
        ("docs/architecture.md and `docs/method.md`", "README.md", []),
    ],
)
def test_outside_references_are_caught(
    text: str, where: str, expected: list[str]
) -> None:
    assert outside_references(text, PurePosixPath(where)) == expected


def test_cited_paths_are_the_path_like_citations() -> None:
    text = (
        "Run `scripts/sdbc evolve`; see `docs/method.md`, "
        "[the report](study/local/report.md#claims), [web](https://x.org/a/b), "
        "`sdbc_evolution/ga/archive.py:Archive`, `results/run/`, "
        "`install/<pkg>/lib`, `a/b/*.py`, `ROS_DOMAIN_ID`, `docs/nope.md`, "
        "`std_msgs/Float64MultiArray`, `STUDY/report/`, `tasks/`."
    )
    assert cited_paths(text) == [
        "study/local/report.md",
        "scripts/sdbc",
        "docs/method.md",
        "sdbc_evolution/ga/archive.py",
        "docs/nope.md",
        "tasks/",
    ]
    readme = ROOT / "README.md"
    assert resolves("docs/study/README.md", readme)
    assert resolves("sdbc_evolution/study/claims.py", readme)
    assert resolves("tasks/gate_escape.py", readme)
    assert not resolves("docs/nope.md", readme)

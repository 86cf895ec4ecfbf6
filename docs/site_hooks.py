"""MkDocs hooks of the documentation site (mkdocs.yml ``hooks:``).

The tutorials live under ``examples/NN_name/``, beside the code they run, so that a
clone runs them where they are; the site shows each one as a page: its README, then
the source of its scripts. Generating the pages at build time keeps one copy of each.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
TUTORIALS_SECTION = "Tutorials"
GUIDE_SECTION = "User guide"
STUDY = ROOT / "docs" / "study"
STUDY_SECTION = "The study"
STUDY_TITLES = {"report": "report", "comparison": "against the study before"}
"""Nav titles of a study folder's pages, after the folder's name."""
STUDY_OVERVIEWS = {"verdicts.md": "Every study's verdicts"}
"""Pages of docs/study/ itself beside the overview, and their nav titles."""
ROOT_PAGES = {"index.md": "README.md", "contributing.md": "CONTRIBUTING.md"}
"""Pages made from files at the repository's root, which GitHub shows there."""
ROOT_FILES = ("LICENSE", "CITATION.cff")
"""Root files the root pages link to that are not pages: named, not linked."""


def site_links(text: str) -> str:
    """A root Markdown file's links as the site needs them: ``docs/x.md`` is
    ``x.md``, a tutorial's README its page, CONTRIBUTING.md its page, and a link
    to a root file that is no page becomes its name in backticks."""
    text = re.sub(r"\]\(docs/", "](", text)
    text = re.sub(
        r"\]\(examples/(\d\d_[\w]+)/README\.md\)", r"](tutorials/\1.md)", text
    )
    text = text.replace("](CONTRIBUTING.md)", "](contributing.md)")
    for name in ROOT_FILES:
        text = re.sub(rf"\[([^\]]+)\]\({re.escape(name)}\)", rf"\1 (`{name}`)", text)
    return text


def tutorials() -> list[Path]:
    """The tutorial folders, in their numbered order."""
    return sorted(p.parent for p in EXAMPLES.glob("[0-9][0-9]_*/README.md"))


def page_uri(folder: Path) -> str:
    return f"tutorials/{folder.name}.md"


def page_title(folder: Path) -> str:
    """The README's first heading, numbered as the folder is."""
    first = (folder / "README.md").read_text().splitlines()[0].lstrip("# ").strip()
    return f"{folder.name[:2]} {first}"


def page_text(folder: Path) -> str:
    """The README, then every top-level script of the folder, whole."""
    parts = [(folder / "README.md").read_text().rstrip(), ""]
    for script in sorted(folder.glob("*.py")):
        relative = script.relative_to(ROOT).as_posix()
        parts += [f"## `{relative}`", "", "```python", script.read_text().rstrip()]
        parts += ["```", ""]
    return "\n".join(parts)


SPHINX_ROLE = re.compile(r":(?:mod|class|func|meth|attr|data|exc|obj):(<code>)")
"""A Sphinx cross-reference role before a rendered code span: the docstrings use
them (``:class:`SdbcExtractor```), and mkdocstrings renders them as literal text."""


def on_page_content(html: str, **_: Any) -> str:
    """Drop the Sphinx role names the docstrings use, keeping their code span, and
    a docstring's literal-block ``::`` down to one colon."""
    html = SPHINX_ROLE.sub(r"\1", html)
    return re.sub(r"::(</p>)", r":\1", html)


def study_pages() -> list[dict[str, str]]:
    """The study's overview, then every page of every study folder: a study
    committed with its report appears without an edit here."""
    pages = [{"Overview": "study/README.md"}]
    pages += [
        {title: f"study/{name}"}
        for name, title in STUDY_OVERVIEWS.items()
        if (STUDY / name).is_file()
    ]
    for page in sorted(STUDY.glob("*/*.md")):
        title = f"{page.parent.name}: {STUDY_TITLES.get(page.stem, page.stem)}"
        pages.append({title: page.relative_to(STUDY.parent).as_posix()})
    return pages


def nav_pages(entries: list[Any]) -> set[str]:
    """Every page a nav (or a section of one) names."""
    pages: set[str] = set()
    for entry in entries:
        value = next(iter(entry.values())) if isinstance(entry, dict) else entry
        if isinstance(value, list):
            pages |= nav_pages(value)
        else:
            pages.add(value)
    return pages


def on_config(config: MkDocsConfig, **_: Any) -> MkDocsConfig:
    """Fill the nav's (empty) tutorials and study sections from their folders, and
    add to the user guide any page of docs/ the nav does not name yet (by its
    first heading), so that a new page is in the site without an edit here."""
    named = nav_pages(config.nav or [])
    for entry in config.nav or []:
        if isinstance(entry, dict) and GUIDE_SECTION in entry:
            for page in sorted((ROOT / "docs").glob("*.md")):
                if page.name not in named and page.name not in ROOT_PAGES:
                    title = page.read_text().splitlines()[0].lstrip("# ").strip()
                    entry[GUIDE_SECTION].append({title: page.name})
        if isinstance(entry, dict) and TUTORIALS_SECTION in entry:
            entry[TUTORIALS_SECTION] = [
                {page_title(folder): page_uri(folder)} for folder in tutorials()
            ]
        if isinstance(entry, dict) and STUDY_SECTION in entry:
            entry[STUDY_SECTION] = study_pages()
    return config


def on_files(files: Files, config: MkDocsConfig, **_: Any) -> Files:
    """Add the home and contributing pages (from the root's README.md and
    CONTRIBUTING.md) and the tutorial pages, made from examples/ at build time."""
    for uri, source in ROOT_PAGES.items():
        text = site_links((ROOT / source).read_text())
        files.append(File.generated(config, uri, content=text))
    for folder in tutorials():
        files.append(
            File.generated(config, page_uri(folder), content=page_text(folder))
        )
    return files

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


def on_config(config: MkDocsConfig, **_: Any) -> MkDocsConfig:
    """Fill the nav's (empty) tutorials section with one page per tutorial."""
    for entry in config.nav or []:
        if isinstance(entry, dict) and TUTORIALS_SECTION in entry:
            entry[TUTORIALS_SECTION] = [
                {page_title(folder): page_uri(folder)} for folder in tutorials()
            ]
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

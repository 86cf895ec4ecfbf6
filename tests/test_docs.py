"""The documentation site builds with warnings as errors, its API reference covers
every module, every public name has a docstring, and the built pages' links lead
somewhere.

- ``mkdocs build --strict`` (what ``scripts/sdbc docs`` runs) into a temporary
  folder: a broken link, a missing page or a cross-reference to a name that no
  longer exists fails it.
- Every module of the Python packages appears as a ``::: module`` line of a page
  under ``docs/api/``, and nothing there names a module that does not exist.
- Every public module, class, function and method (names without a leading
  underscore, defined in the package) has a docstring of its own or inherits one
  from the method it overrides.
- Every relative link of the built HTML resolves to a file of the site, and every
  ``#anchor`` to an id of its page.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import os
import pkgutil
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api"
PACKAGES = ("sdbc_sim", "sdbc_evolution")
DIRECTIVE = re.compile(r"^:::\s+([\w.]+)\s*$", flags=re.MULTILINE)


def package_modules() -> list[str]:
    """Every module of the packages, by dotted name (``__main__`` scripts aside:
    importing one runs it)."""
    names = []
    for package in PACKAGES:
        names.append(package)
        path = [str(ROOT / "src" / package / package)]
        for info in pkgutil.walk_packages(path, package + "."):
            if not info.name.endswith(".__main__"):
                names.append(info.name)
    return sorted(names)


def documented_modules() -> list[str]:
    """The modules the API reference renders, in page order."""
    found = []
    for page in sorted(API.glob("*.md")):
        found += DIRECTIVE.findall(page.read_text())
    return found


def test_the_api_reference_covers_every_module_once() -> None:
    documented = documented_modules()
    twice = sorted({m for m in documented if documented.count(m) > 1})
    assert not twice, f"in the API reference twice: {twice}"
    existing = set(package_modules())
    assert set(documented) == existing, (
        f"missing from docs/api/: {sorted(existing - set(documented))}; "
        f"in docs/api/ but no module: {sorted(set(documented) - existing)}"
    )


def inherited_doc(owner: type, name: str) -> str | None:
    """The docstring of ``name`` on the first base class of ``owner`` that has one
    (an override inherits the contract of what it overrides)."""
    for base in owner.__mro__[1:]:
        member = vars(base).get(name)
        if member is None:
            continue
        function = getattr(member, "fget", None) or getattr(member, "__func__", member)
        if getattr(function, "__doc__", None):
            return str(function.__doc__)
    return None


def module_source(module_name: str) -> Path:
    module = importlib.import_module(module_name)
    return Path(inspect.getfile(module))


def undocumented(module_name: str) -> list[str]:
    """The public names ``module_name`` defines that have no docstring: read from
    the source (a dataclass's generated ``__doc__`` is no documentation), a
    method without one of its own inheriting its base's."""
    tree = ast.parse(module_source(module_name).read_text())
    missing = [] if ast.get_docstring(tree) else [module_name]
    definitions = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)
    for node in tree.body:
        if not isinstance(node, definitions) or node.name.startswith("_"):
            continue
        if not ast.get_docstring(node):
            missing.append(f"{module_name}.{node.name}")
        if not isinstance(node, ast.ClassDef):
            continue
        owner = getattr(importlib.import_module(module_name), node.name)
        for member in node.body:
            if (
                isinstance(member, definitions[:2])
                and not member.name.startswith("_")
                and not ast.get_docstring(member)
                and not inherited_doc(owner, member.name)
            ):
                missing.append(f"{module_name}.{node.name}.{member.name}")
    return missing


def test_every_public_name_has_a_docstring() -> None:
    missing = [name for module in package_modules() for name in undocumented(module)]
    assert not missing, f"{len(missing)} public names without a docstring: " + (
        ", ".join(missing)
    )


def test_a_name_without_a_docstring_is_caught(tmp_path: Path, monkeypatch) -> None:
    (tmp_path / "sdbc_probe_module.py").write_text(
        '"""A module."""\n\n'
        "class Base:\n"
        '    """A base."""\n\n'
        "    def step(self):\n"
        '        """Steps."""\n\n'
        "class Child(Base):\n"
        '    """A child."""\n\n'
        "    def step(self):\n"
        "        pass\n\n"
        "    def stop(self):\n"
        "        pass\n\n"
        "def helper():\n"
        "    pass\n\n"
        "def _private():\n"
        "    pass\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert undocumented("sdbc_probe_module") == [
        "sdbc_probe_module.Child.stop",
        "sdbc_probe_module.helper",
    ]


class _Links(HTMLParser):
    """The ``href``/``src`` targets and the ``id``s of one HTML page."""

    def __init__(self) -> None:
        super().__init__()
        self.targets: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for key, value in attrs:
            if key == "id" and value:
                self.ids.add(value)
            if key in ("href", "src") and value and tag in ("a", "img"):
                self.targets.append(value)


def broken_links(site: Path) -> list[str]:
    """Relative links of the built pages that lead to no file, or to no id of the
    page they name, as ``page -> target``."""
    pages: dict[Path, _Links] = {}
    # 404.html is served at whatever address was not found, so its links are
    # absolute from the site's root; every other page links relatively.
    for page in (p for p in site.rglob("*.html") if p.name != "404.html"):
        parser = _Links()
        parser.feed(page.read_text())
        pages[page] = parser
    broken = []
    for page, parser in pages.items():
        for target in parser.targets:
            parts = urlsplit(target)
            if parts.scheme or parts.netloc or target.startswith("mailto:"):
                continue
            destination = (page.parent / unquote(parts.path)).resolve()
            if parts.path == "":
                destination = page
            if destination.is_dir():
                destination = destination / "index.html"
            if not destination.exists():
                broken.append(f"{page.relative_to(site)} -> {target}")
                continue
            anchor = unquote(parts.fragment)
            if anchor and destination in pages and anchor not in pages[destination].ids:
                broken.append(f"{page.relative_to(site)} -> {target} (no such id)")
    return sorted(broken)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p)),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return out


def test_the_site_builds_strictly_with_every_page(site: Path) -> None:
    for page in ("index.html", "method/index.html", "contributing/index.html"):
        assert (site / page).is_file(), page
    for page in sorted(API.glob("*.md")):
        assert (site / "api" / page.stem / "index.html").is_file(), page.name
    tutorials = sorted(p.parent.name for p in ROOT.glob("examples/[0-9]*/README.md"))
    for tutorial in tutorials:
        assert (site / "tutorials" / tutorial / "index.html").is_file(), tutorial
    # The reference renders the docstrings, not only the headings.
    engine = (site / "api" / "sim" / "index.html").read_text()
    assert "Evaluates every genome in its trials." in engine


def test_every_link_of_the_built_site_leads_somewhere(site: Path) -> None:
    assert broken_links(site) == []


def test_a_broken_link_is_caught(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "index.html").write_text(
        '<h1 id="top">A</h1><a href="../b/">b</a><a href="#top">top</a>'
        '<a href="#gone">gone</a><img src="missing.png"><a href="https://x.org/">x</a>'
    )
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "index.html").write_text('<a href="../a/#top">a</a>')
    assert broken_links(tmp_path) == [
        "a/index.html -> #gone (no such id)",
        "a/index.html -> missing.png",
    ]

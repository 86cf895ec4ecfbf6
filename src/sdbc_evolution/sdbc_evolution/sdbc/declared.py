"""Declared parts: a characterisation, transform, relevance measure or ranking is
written in YAML as its name alone (default options) or as ``{name: {option: value}}``.

Each registry keeps a settings class per part (:mod:`sdbc_sim.settings`, the one
checked-settings mechanism); :func:`declared_part` reads a declaration against it and
:func:`changed_options` writes one back. Refusals are
:class:`~sdbc_sim.settings.SettingsError` s whose paths name the part and option
(``ranking.scalarised.weight``), relative to where the declaration sits.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from sdbc_sim.settings import SettingsError, load


def at(where: str, key: str) -> str:
    """The dotted path of ``key`` under ``where`` (which may be empty)."""
    return f"{where}.{key}" if where else key


def declared_part(
    declaration: Any, kinds: dict[str, type], what: str, where: str
) -> tuple[str, Any]:
    """A registered part from its declaration: ``name`` (default options) or
    ``{name: {option: value, ...}}``.

    Args:
        declaration: The plain data.
        kinds: Name -> settings class of the options of every registered part.
        what: What the part is, for messages ("ranking", "relevance measure").
        where: The dotted path of the declaration, for messages.

    Returns:
        ``(name, options)``, the options an instance of the part's settings class.

    Raises:
        SettingsError: Not a name or a one-key mapping, an unknown name, or bad
            options, naming the path (and the option).
    """
    options: Any
    if isinstance(declaration, str):
        name, options = declaration, {}
    elif isinstance(declaration, dict) and len(declaration) == 1:
        ((name, options),) = declaration.items()
    else:
        raise SettingsError.of(
            (
                (
                    where,
                    f"expected a {what} name or {{name: options}}, got "
                    f"{declaration!r}; known: {sorted(kinds)}",
                ),
            )
        )
    if name not in kinds:
        raise SettingsError.of(
            ((where, f"unknown {what} {name!r}; known: {sorted(kinds)}"),)
        )
    return name, load(kinds[name], options, at(where, name))


def changed_options(options: Any) -> dict[str, Any]:
    """The fields of an options class that differ from its defaults, as plain
    data (tuples as lists): what a declaration must say to rebuild it."""
    default = type(options)()
    changed = {}
    for f in dataclasses.fields(options):
        value = getattr(options, f.name)
        if value != getattr(default, f.name):
            changed[f.name] = list(value) if isinstance(value, tuple) else value
    return changed

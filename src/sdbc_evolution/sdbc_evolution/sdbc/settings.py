"""Typed settings from plain data (YAML): the one way every configuration section,
treatment part and option is checked.

A settings class is a frozen dataclass whose fields carry type hints and defaults and
whose ``__post_init__`` checks ranges. :func:`from_mapping` builds one from a mapping:
unknown keys, wrong types (a string or a float for an integer, NaN or infinity for a
number) and failed range checks raise :class:`ConfigError` naming the key. It lives
in the lowest layer so that every layer's parts (characterisers, relevance measures,
rankings, the run's configuration) use the same checks.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from enum import Enum
from typing import Any


class ConfigError(ValueError):
    """A configuration that cannot run; the message names the offending key."""


def coerce(value: Any, annotation: Any, key: str) -> Any:
    """Checks one YAML value against a field's type; returns it converted."""
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(annotation)
        if value is None and type(None) in options:
            return None
        last: ConfigError | None = None
        for option in options:
            if option is type(None):
                continue
            try:
                return coerce(value, option, key)
            except ConfigError as error:
                last = error
        assert last is not None
        raise last
    if origin is typing.Literal:
        allowed = typing.get_args(annotation)
        if value not in allowed:
            raise ConfigError(f"{key}: {value!r} is not one of {list(allowed)}")
        return value
    if hasattr(annotation, "from_plain"):
        # A type with a declaration syntax of its own (a treatment).
        return annotation.from_plain(value, key)
    if dataclasses.is_dataclass(annotation):
        return from_mapping(annotation, value, key)
    if isinstance(annotation, type) and issubclass(annotation, Enum):
        try:
            return annotation(value)
        except ValueError:
            raise ConfigError(
                f"{key}: {value!r} is not one of {[e.value for e in annotation]}"
            ) from None
    if annotation is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key}: expected true or false, got {value!r}")
        return value
    if annotation is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key}: expected an integer, got {value!r}")
        return value
    if annotation is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{key}: expected a finite number, got {value!r}")
        return float(value)
    if annotation is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key}: expected a string, got {value!r}")
        return value
    if origin is tuple:
        (item, *rest) = typing.get_args(annotation)
        if rest != [Ellipsis]:
            raise ConfigError(f"{key}: unsupported field type {annotation!r}")
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{key}: expected a list, got {value!r}")
        return tuple(coerce(v, item, f"{key}[{i}]") for i, v in enumerate(value))
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{key}: expected a mapping, got {value!r}")
        return dict(value)
    raise ConfigError(f"{key}: unsupported field type {annotation!r}")


def from_mapping(cls: type, data: Any, prefix: str) -> Any:
    """An instance of the dataclass ``cls`` from the mapping ``data`` (None: all
    defaults); ``prefix`` is the dotted key that error messages name."""
    if data is None:
        data = {}
    where = prefix or "configuration"
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(str(k) for k in data if k not in names)
    if unknown:
        dotted = [f"{prefix}.{k}" if prefix else k for k in unknown]
        raise ConfigError(
            f"unknown key(s) {dotted}; known keys of {where}: {sorted(names)}"
        )
    values = {}
    for name, value in data.items():
        key = f"{prefix}.{name}" if prefix else name
        values[name] = coerce(value, hints[name], key)
    try:
        return cls(**values)
    except ConfigError:
        raise
    except (TypeError, ValueError) as error:
        message = str(error)
        # A part's own check names the part ("scalarised: weight ..."): once is
        # enough after the dotted key that ends with it.
        last = where.rsplit(".", 1)[-1]
        if where != last and message.startswith(f"{last}: "):
            message = message[len(last) + 2 :]
        if not message.startswith(f"{where}:"):
            message = f"{where}: {message}"
        raise ConfigError(message) from None


def declared_part(
    declaration: Any, kinds: dict[str, type], what: str, where: str
) -> tuple[str, Any]:
    """A registered part from its declaration: ``name`` (default options) or
    ``{name: {option: value, ...}}``.

    Args:
        declaration: The plain data.
        kinds: Name -> options dataclass of every registered part.
        what: What the part is, for messages ("ranking", "relevance measure").
        where: The dotted key of the declaration, for messages.

    Returns:
        ``(name, options)``, the options an instance of the part's dataclass.

    Raises:
        ConfigError: Not a name or a one-key mapping, an unknown name, or bad
            options, naming ``where`` (and the option).
    """
    if isinstance(declaration, str):
        name, options = declaration, {}
    elif isinstance(declaration, dict) and len(declaration) == 1:
        ((name, options),) = declaration.items()
    else:
        raise ConfigError(
            f"{where}: expected a {what} name or {{name: options}}, got "
            f"{declaration!r}; known: {sorted(kinds)}"
        )
    if name not in kinds:
        raise ConfigError(f"{where}: unknown {what} {name!r}; known: {sorted(kinds)}")
    return name, from_mapping(kinds[name], options, f"{where}.{name}")


def changed_options(options: Any) -> dict[str, Any]:
    """The fields of an options dataclass that differ from its defaults, as plain
    data (tuples as lists): what a declaration must say to rebuild it."""
    default = type(options)()
    changed = {}
    for f in dataclasses.fields(options):
        value = getattr(options, f.name)
        if value != getattr(default, f.name):
            changed[f.name] = list(value) if isinstance(value, tuple) else value
    return changed

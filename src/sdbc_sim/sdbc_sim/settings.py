"""One way to declare checked settings: task settings, the experiment configuration
and its sections, study presets and the graph file's launcher settings all use it.

A settings class is a frozen, keyword-only dataclass decorated with
:func:`settings`; pydantic 2 checks every value when an instance is made:

- types are strict: an ``int`` field refuses ``300.5``, ``"300"`` and ``True``; a
  ``float`` field takes integers but refuses strings; a ``bool`` field takes only
  ``true``/``false``; a ``str`` field only strings. Enums and ``Literal`` fields
  take their values' names as YAML writes them; tuples take YAML lists;
- NaN and infinity are refused in every float field;
- limits sit in the annotations, e.g. ``Annotated[int, Field(ge=1)]`` or the
  aliases below (:data:`PositiveFloat`, :data:`Fraction`, ...);
- unknown keys are refused;
- checks across fields go in ``__post_init__``, raising :class:`SettingsError`
  through :func:`check` so that the message names the field.

Each field carries its docstring (the string literal under it), which pydantic
keeps as the field's description (:func:`field_docs`).

:func:`load` builds a settings class from plain data (a parsed YAML mapping) and
turns any refusal into one :class:`SettingsError` whose message names every bad
field by its dotted path and the value it got, e.g.
``task_config.max_steps: Input should be a valid integer, got 300.5``.

Example::

    @settings
    class ArenaSettings:
        size: PositiveFloat = 200.0
        \"\"\"Side of the square arena.\"\"\"
        robots: Annotated[int, Field(ge=1)] = 4
        \"\"\"Robots in the team.\"\"\"

    load(ArenaSettings, {"robots": 3.5}, where="task_config")
    # SettingsError: task_config.robots: Input should be a valid integer, got 3.5
"""

from __future__ import annotations

import dataclasses
import functools
import sys
import types
import typing
from collections.abc import Mapping
from enum import Enum
from typing import Annotated, Any, TypeVar, dataclass_transform

import pydantic
import pydantic.dataclasses
from pydantic import Field, Strict, ValidationError

from sdbc_sim.limits import excerpt

__all__ = [
    "Field",
    "Fraction",
    "NonNegativeFloat",
    "NonNegativeInt",
    "PositiveFloat",
    "PositiveInt",
    "SettingsError",
    "check",
    "field_docs",
    "is_settings",
    "load",
    "settings",
    "to_plain",
]

PositiveFloat = Annotated[float, Field(gt=0)]
"""A finite number above 0."""
NonNegativeFloat = Annotated[float, Field(ge=0)]
"""A finite number of at least 0."""
Fraction = Annotated[float, Field(ge=0, le=1)]
"""A number in [0, 1]."""
PositiveInt = Annotated[int, Field(ge=1)]
"""An integer of at least 1."""
NonNegativeInt = Annotated[int, Field(ge=0)]
"""An integer of at least 0."""

_CONFIG = pydantic.ConfigDict(
    extra="forbid",
    allow_inf_nan=False,
    use_attribute_docstrings=True,
    validate_default=True,
    arbitrary_types_allowed=False,
)
_STRICT_SCALARS = (bool, int, float, str)

T = TypeVar("T")


class SettingsError(ValueError):
    """Settings that cannot be used. ``problems`` holds (dotted path, message) per
    bad field; the message lists them all."""

    def __init__(
        self, message: str, problems: tuple[tuple[str, str], ...] = ()
    ) -> None:
        super().__init__(message)
        self.problems = problems or (("", message),)

    @classmethod
    def of(cls, problems: tuple[tuple[str, str], ...]) -> SettingsError:
        """An error listing ``problems``, each as "path: message"."""
        return cls(_describe(problems), problems)

    def prefixed(self, prefix: str) -> SettingsError:
        """The same problems, their paths under ``prefix`` (e.g. "task_config")."""
        return SettingsError.of(
            tuple((_join(prefix, path), message) for path, message in self.problems)
        )


def check(ok: bool, field: str, message: str) -> None:
    """For ``__post_init__``: refuses the settings unless ``ok``, naming ``field``
    (its path is completed with the section's own when loaded)."""
    if not ok:
        raise SettingsError.of(((field, message),))


def _join(prefix: str, path: str) -> str:
    if not prefix:
        return path
    return f"{prefix}.{path}" if path else prefix


def _describe(problems: tuple[tuple[str, str], ...]) -> str:
    return "; ".join(
        f"{path}: {message}" if path else message for path, message in problems
    )


def _strict(annotation: Any) -> Any:
    """``annotation`` with every bool, int, float and str made strict, inside
    ``Annotated``, unions, tuples, lists and dicts too."""
    if annotation in _STRICT_SCALARS:
        return Annotated[annotation, Strict()]
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is Annotated:
        return Annotated[(_strict(args[0]), *annotation.__metadata__)]
    if origin in (typing.Union, types.UnionType):
        return typing.Union[tuple(_strict(a) for a in args)]  # noqa: UP007
    if origin in (tuple, list, dict) and args:
        return origin[tuple(a if a is Ellipsis else _strict(a) for a in args)]
    return annotation


@dataclass_transform(
    kw_only_default=True, frozen_default=True, field_specifiers=(dataclasses.field,)
)
def settings(cls: type[T]) -> type[T]:
    """Makes ``cls`` a checked settings class (see the module docstring)."""
    module = sys.modules.get(cls.__module__)
    hints = typing.get_type_hints(
        cls, globalns=vars(module) if module else None, include_extras=True
    )
    own = cls.__dict__.get("__annotations__", {})
    cls.__annotations__ = {
        name: hints[name]
        if typing.get_origin(hints[name]) is typing.ClassVar
        # ClassVar stays as it is; every field becomes strict.
        else _strict(hints[name])
        for name in own
    }
    made = pydantic.dataclasses.dataclass(frozen=True, kw_only=True, config=_CONFIG)(
        cls
    )
    validating_init = made.__init__

    @functools.wraps(validating_init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        # Made directly (or by dataclasses.replace) too, a refusal is one
        # SettingsError naming the fields, as load gives.
        try:
            validating_init(self, *args, **kwargs)
        except ValidationError as error:
            raise errors_of(made, error) from None

    made.__init__ = __init__  # type: ignore[method-assign]
    return typing.cast(type[T], made)


def is_settings(cls: Any) -> bool:
    """Whether ``cls`` is a class made by :func:`settings`."""
    return isinstance(cls, type) and hasattr(cls, "__pydantic_fields__")


def field_docs(cls: type) -> dict[str, str]:
    """Field name -> its docstring, for a settings class (a field a subclass
    inherits keeps its base's docstring)."""
    fields = getattr(cls, "__pydantic_fields__", {})
    docs = {}
    for name in fields:
        docs[name] = next(
            (d for base in cls.__mro__ if (d := _description(base, name))), ""
        )
    return docs


def _description(cls: type, name: str) -> str | None:
    """The docstring of field ``name`` as ``cls`` itself declares it, if any."""
    field = getattr(cls, "__pydantic_fields__", {}).get(name)
    return None if field is None else field.description


def load(cls: type[T], data: Any, where: str = "") -> T:
    """An instance of the settings class ``cls`` from plain data (a mapping; None
    is an empty one).

    Raises:
        SettingsError: Naming every bad field by its path under ``where``.
    """
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise SettingsError.of(((where, f"expected a mapping, got {excerpt(data)}"),))
    try:
        return _adapter(cls).validate_python(dict(data))
    except ValidationError as error:
        raise SettingsError.of(_problems(cls, error, where)) from None


def _adapter(cls: type[T]) -> pydantic.TypeAdapter[T]:
    adapter = _ADAPTERS.get(cls)
    if adapter is None:
        adapter = _ADAPTERS[cls] = pydantic.TypeAdapter(cls)
    return adapter


_ADAPTERS: dict[type, pydantic.TypeAdapter[Any]] = {}


def errors_of(cls: type, error: ValidationError, where: str = "") -> SettingsError:
    """A pydantic error raised while making ``cls`` (directly, not through
    :func:`load`) as a :class:`SettingsError`."""
    return SettingsError.of(_problems(cls, error, where))


def _problems(
    cls: type, error: ValidationError, where: str
) -> tuple[tuple[str, str], ...]:
    problems: list[tuple[str, str]] = []
    for item in error.errors():
        loc = tuple(str(part) for part in item["loc"])
        path = _join(where, ".".join(loc))
        cause = (item.get("ctx") or {}).get("error")
        if isinstance(cause, SettingsError):
            # A check across fields in __post_init__: its paths are relative.
            problems.extend((_join(path, p), m) for p, m in cause.problems)
            continue
        kind = item["type"]
        message = item["msg"]
        if kind == "unexpected_keyword_argument":
            known = sorted(_fields_at(cls, loc[:-1]))
            problems.append((path, f"unknown key; known keys: {known}"))
            continue
        if kind == "value_error":
            message = message.removeprefix("Value error, ")
            problems.append((path, message))
            continue
        if kind == "missing_keyword_only_argument":
            problems.append((path, "missing (no default)"))
            continue
        problems.append((path, f"{message}, got {excerpt(item['input'])}"))
    return tuple(problems)


def _fields_at(cls: Any, loc: tuple[str, ...]) -> list[str]:
    """Field names of the settings class found at ``loc`` inside ``cls``."""
    for part in loc:
        fields = getattr(cls, "__pydantic_fields__", {})
        if part not in fields:
            return []
        cls = _settings_class(fields[part].annotation)
    return list(getattr(cls, "__pydantic_fields__", {}))


def _settings_class(annotation: Any) -> Any:
    if is_settings(annotation):
        return annotation
    for arg in typing.get_args(annotation):
        found = _settings_class(arg)
        if found is not None:
            return found
    return None


def to_plain(value: Any) -> Any:
    """Plain data (YAML-ready) of settings: dataclasses become mappings, enums
    their values, tuples lists; a value with a declaration syntax of its own (a
    treatment) gives that, through its ``to_plain`` method."""
    own = getattr(value, "to_plain", None)
    if callable(own) and not isinstance(value, type):
        return own()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: to_plain(getattr(value, f.name)) for f in dataclasses.fields(value)
        }
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, Mapping):
        return {str(k): to_plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_plain(v) for v in value]
    return value

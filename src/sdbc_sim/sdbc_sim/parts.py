"""One way to add a part of any kind: a task, a characterisation, a relevance
measure, a transform or a ranking.

A part is a class of its kind's base (``Characteriser``, ``RelevanceMeasure``,
``Transform``, ``Ranking``) that names its options in ``options_class`` (a settings
class, :mod:`sdbc_sim.settings`, every option with a default), is made from an
instance of it, and answers its kind's one method. A kind's :class:`Registry`
holds its parts by name, registered in one place: the package's own with
:meth:`Registry.register` in the kind's registry module, and those of installed
distributions as entry points of the kind's group, e.g. in a ``pyproject.toml``::

    [project.entry-points."sdbc.rankings"]
    elitist_novelty = "my_parts.ranking:ElitistNovelty"

Entry points are listed at the first lookup of a name the package lacks and each is
loaded when it is first named, so a broken distribution fails only the lookups
that name its parts, in one line naming its entry point (:class:`PartError`). A
name the package registers is never taken over by an entry point.

In YAML a part is declared by its name (default options) or as ``{name: {option:
value}}``; :meth:`PartSpec.parse` reads either, refusing an unknown name or bad
options with one :class:`~sdbc_sim.settings.SettingsError` whose path names the part
and the option (``ranking.scalarised.weight``), and :meth:`PartSpec.to_plain` writes
the declaration back (the name alone for default options), so that parse and
to_plain round-trip.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from typing import Any, ClassVar, Generic, Self, TypeVar, cast

from sdbc_sim.settings import SettingsError, is_settings, load, settings

P = TypeVar("P")


@settings
class NoOptions:
    """This part has no options of its own."""


class PartError(ValueError):
    """A part that cannot be used: an entry point that does not load, or a class
    that is not a part of its kind. The message names it."""


def at(where: str, key: str) -> str:
    """The dotted path of ``key`` under ``where`` (which may be empty)."""
    return f"{where}.{key}" if where else key


def load_entry_point(point: EntryPoint) -> Any:
    """What an entry point names.

    Raises:
        PartError: It does not load (any exception of its import), naming it.
    """
    try:
        return point.load()
    except Exception as error:  # noqa: BLE001 - any import failure, named
        raise PartError(
            f"entry point {point.name} = {point.value!r} of group '{point.group}' "
            f"does not load: {type(error).__name__}: {error}"
        ) from None


def group_entry_points(group: str) -> list[EntryPoint]:
    """The entry points of ``group`` of every installed distribution, by name."""
    return sorted(entry_points(group=group), key=lambda p: p.name)


def changed_options(options: Any) -> dict[str, Any]:
    """The fields of an options instance that differ from its class's defaults, as
    plain data (tuples as lists): what a declaration must say to rebuild it."""
    default = type(options)()
    changed = {}
    for f in dataclasses.fields(options):
        value = getattr(options, f.name)
        if value != getattr(default, f.name):
            changed[f.name] = list(value) if isinstance(value, tuple) else value
    return changed


@dataclass(frozen=True)
class Registered(Generic[P]):
    """A part in a registry.

    Attributes:
        name: Its name in declarations.
        part: Its class.
        options: Its options class.
        origin: Where it comes from: the module that registers it, or its entry
            point.
    """

    name: str
    part: type[P]
    options: type
    origin: str

    @property
    def summary(self) -> str:
        """The first line of the part's docstring, for listings."""
        doc = (self.part.__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""


class Registry(Generic[P]):
    """The parts of one kind, by name (see the module docstring).

    Args:
        what: What a part is, in messages ("ranking", "relevance measure").
        group: The entry point group of the kind (``sdbc.rankings``).
        base: The class every part of the kind subclasses.
        options_attribute: The class attribute that names a part's options class.
        check: Further checks of a part class, raising :class:`PartError` (its
            argument: the class and where it comes from, for the message).
    """

    def __init__(
        self,
        what: str,
        group: str,
        base: type,
        options_attribute: str = "options_class",
        check: Callable[[type[P], str], None] | None = None,
    ) -> None:
        self.what = what
        self.group = group
        self.base = base
        self.options_attribute = options_attribute
        self._check = check
        self._own: dict[str, Registered[P]] = {}
        self._points: dict[str, EntryPoint] | None = None
        self._loaded: dict[str, Registered[P]] = {}

    def register(self, name: str, part: type[P], origin: str | None = None) -> None:
        """Registers the package's part ``part`` as ``name`` (again: nothing).

        Raises:
            PartError: A name taken by another class, or a class that is not a
                part of this kind.
        """
        taken = self._own.get(name)
        if taken is not None and taken.part is not part:
            raise PartError(f"{self.what} {name!r} is registered twice")
        where = origin or f"{part.__module__}.{part.__qualname__}"
        self._own[name] = self.checked(name, part, where)

    def checked(self, name: str, part: Any, where: str) -> Registered[P]:
        """``part`` as registered under ``name``, if it is a part of this kind: a
        subclass of its base that passes the kind's own checks and names a settings
        class with a default for every option.

        Raises:
            PartError: It is not, naming ``where`` it comes from.
        """
        if not (isinstance(part, type) and issubclass(part, self.base)):
            raise PartError(
                f"{where}: {part!r} is not a subclass of "
                f"{self.base.__module__}.{self.base.__qualname__} (a {self.what})"
            )
        checked = cast(type[P], part)
        if self._check is not None:
            self._check(checked, where)
        options: Any = getattr(part, self.options_attribute, None)
        if not is_settings(options):
            raise PartError(
                f"{where}: {part.__name__}.{self.options_attribute} must be a settings "
                "class made with @sdbc_sim.settings.settings"
            )
        try:
            options()
        except SettingsError as error:
            raise PartError(
                f"{where}: {options.__name__} needs a default for every option "
                f"(a name alone declares the defaults): {error}"
            ) from None
        return Registered(name, checked, options, where)

    def _entry_points(self) -> dict[str, EntryPoint]:
        if self._points is None:
            self._points = {p.name: p for p in group_entry_points(self.group)}
        return self._points

    def refresh(self) -> None:
        """Forgets the entry points read so far (after installing a distribution
        in a running process)."""
        self._points = None
        self._loaded.clear()

    def names(self) -> tuple[str, ...]:
        """Every registered name, the package's and the entry points' (none
        loaded), sorted."""
        return tuple(sorted(set(self._own) | set(self._entry_points())))

    def find(self, name: str) -> Registered[P] | None:
        """The part registered as ``name``, None if there is none.

        Raises:
            PartError: ``name`` is an entry point that does not load or names no
                part of this kind.
        """
        if name in self._own:
            return self._own[name]
        if name in self._loaded:
            return self._loaded[name]
        point = self._entry_points().get(name)
        if point is None:
            return None
        where = f"entry point {point.name} = {point.value!r} of group '{self.group}'"
        found = self.checked(name, load_entry_point(point), where)
        self._loaded[name] = found
        return found

    def __getitem__(self, name: str) -> Registered[P]:
        found = self.find(name)
        if found is None:
            raise KeyError(f"unknown {self.what} {name!r}; known: {list(self.names())}")
        return found

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self.names()

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def all(self) -> Iterable[Registered[P]]:
        """Every registered part, entry points loaded (the first that does not
        load raises :class:`PartError`)."""
        return [self[name] for name in self.names()]

    def declared(self, declaration: Any, where: str) -> tuple[str, Any]:
        """``(name, options)`` of a declaration: ``name`` (default options) or
        ``{name: {option: value, ...}}``.

        Raises:
            SettingsError: Not a name or a one-key mapping, an unknown name, an
                entry point that does not load, or bad options, naming the path
                (and the option).
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
                        f"expected a {self.what} name or {{name: options}}, got "
                        f"{declaration!r}; known: {list(self.names())}",
                    ),
                )
            )
        try:
            found = self.find(str(name))
        except PartError as error:
            raise SettingsError.of(((where, str(error)),)) from None
        if found is None:
            raise SettingsError.of(
                ((where, f"unknown {self.what} {name!r}; known: {list(self.names())}"),)
            )
        return found.name, load(found.options, options, at(where, found.name))


@dataclass(frozen=True)
class PartSpec(Generic[P]):
    """A declared part: its name and options. Each kind subclasses it, naming its
    :class:`Registry` in ``registry``.

    Attributes:
        name: The part's registered name.
        options: An instance of its options class.
    """

    registry: ClassVar[Registry[Any]]
    name: str
    options: Any

    @property
    def registered(self) -> Registered[P]:
        """The part as registered."""
        return self.registry[self.name]

    def build(self) -> P:
        """The part, made from these options."""
        part: Any = self.registered.part
        made: P = part(self.options)
        return made

    def to_plain(self) -> str | dict[str, Any]:
        """The declaration, YAML-ready: the name alone for default options."""
        changed = changed_options(self.options)
        return {self.name: changed} if changed else self.name

    @classmethod
    def parse(cls, declaration: Any, where: str = "") -> Self:
        """A spec from ``name`` or ``{name: {option: value}}`` (a spec is kept).

        Raises:
            SettingsError: Unknown part or bad options, naming ``where``.
        """
        if isinstance(declaration, cls):
            return declaration
        return cls(*cls.registry.declared(declaration, where))

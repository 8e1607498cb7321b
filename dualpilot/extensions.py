"""The public extension points: registries of named parts filled from Python entry points.

Two registries can be extended without editing dualpilot: the planning methods of
System 1 and System 2 (entry-point group ``dualpilot.planners``,
:mod:`dualpilot.planners`) and the supervisors (group ``dualpilot.supervisors``,
:mod:`dualpilot.supervisor.registry`). A separately installed package names its parts in
its ``pyproject.toml`` (the entry points specification of the Python packaging guide)::

    [project.entry-points."dualpilot.planners"]
    straight = "dualpilot_example.straight:STRAIGHT"

The built-in parts are entry points of the same groups, written in the code (each
registry's ``BUILTIN`` table) rather than in dualpilot's own package metadata, so a
source tree flies without being installed; built-in and installed entry points pass
through one loader (:class:`Registry`). A registry discovers its names once per process,
when it is first asked, and loads a part (imports its module) when it is first used. A
name registered twice, a name of the wrong form, or an entry point that does not load or
does not give the registry's type is an :class:`ExtensionError` that names the package:
never a silent override, never a silent skip (docs/extending.md).
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Iterable, Mapping
from importlib.metadata import EntryPoint, entry_points
from typing import Generic, TypeVar

__all__ = ["ExtensionError", "Registry", "installed_points", "origin"]

T = TypeVar("T")


class ExtensionError(ValueError):
    """A registry that cannot be filled: a name registered twice, a name of the wrong form,
    or a part that does not load or is not of the registry's type."""


def installed_points(group: str) -> tuple[EntryPoint, ...]:
    """The entry points the installed packages declare in ``group``, by name and package."""
    found = entry_points(group=group)
    return tuple(sorted(found, key=lambda p: (p.name, p.dist.name if p.dist else "")))


def origin(point: EntryPoint) -> str:
    """Who registered ``point``: dualpilot itself or the installed package (name, version)."""
    dist = point.dist
    return "dualpilot (built in)" if dist is None else f"package {dist.name} {dist.version}"


class Registry(Generic[T]):
    """The named parts of one entry-point group: the built-ins first, in their order, then
    the installed ones by name.

    ``builtins`` maps a name to its entry point's value ("module:attribute"); ``kind`` is
    the type every part must have; a name must match ``name_pattern`` and not be one of
    ``reserved``; ``check(name, part)`` raises ValueError for a part the registry refuses;
    ``installed(group)`` lists the installed entry points (:func:`installed_points`).
    """

    def __init__(self, group: str, kind: type[T], builtins: Mapping[str, str], *, what: str,
                 name_pattern: str, reserved: Iterable[str] = (),
                 check: Callable[[str, T], None] | None = None,
                 installed: Callable[[str], Iterable[EntryPoint]] = installed_points):
        self.group = group
        self.kind = kind
        self.what = what
        self.builtins = tuple(EntryPoint(n, v, group) for n, v in builtins.items())
        self.pattern = re.compile(name_pattern)
        self.reserved = frozenset(reserved)
        self.check = check
        self._installed = installed
        self._points: dict[str, EntryPoint] | None = None
        self._parts: dict[str, T] = {}
        self._lock = threading.Lock()

    def points(self) -> Mapping[str, EntryPoint]:
        """Every registered name and its entry point (ExtensionError: a clash, a bad name)."""
        with self._lock:
            if self._points is None:
                self._points = self._discover()
            return self._points

    def _discover(self) -> dict[str, EntryPoint]:
        found: dict[str, EntryPoint] = {}
        for point in (*self.builtins, *self._installed(self.group)):
            name = point.name
            if name in found:
                first = found[name]
                raise ExtensionError(
                    f"{self.group}: {name!r} is registered twice, by {origin(first)} "
                    f"({first.value}) and by {origin(point)} ({point.value}); uninstall one "
                    f"or rename its entry point")
            if not self.pattern.fullmatch(name) or name in self.reserved:
                why = (f"it is reserved ({', '.join(sorted(self.reserved))})"
                       if name in self.reserved else f"a name must match {self.pattern.pattern}")
                raise ExtensionError(f"{self.group}: {origin(point)} registers {name!r} "
                                     f"({point.value}), a name it cannot take: {why}")
            found[name] = point
        return found

    def names(self) -> tuple[str, ...]:
        """The registered names, built-ins first."""
        return tuple(self.points())

    def get(self, name: str) -> T:
        """The part registered as ``name``, loaded on first use (ValueError: no such name;
        ExtensionError: it does not load or is refused)."""
        points = self.points()
        if name not in points:
            raise ValueError(f"unknown {self.what} {name!r}; installed: {', '.join(points)}")
        with self._lock:
            part = self._parts.get(name)
        if part is None:
            part = self._load(points[name])
            with self._lock:  # a part loaded twice at once: the first one stored counts
                part = self._parts.setdefault(name, part)
        return part

    def _load(self, point: EntryPoint) -> T:
        where = f"{self.group}: {point.name!r} = {point.value} of {origin(point)}"
        try:
            part = point.load()
        except Exception as err:  # noqa: BLE001 - any failure of a plug-in's import is its own
            raise ExtensionError(f"{where} does not load: {type(err).__name__}: {err}") from err
        if not isinstance(part, self.kind):
            raise ExtensionError(f"{where} is a {type(part).__name__}, not a "
                                 f"{self.kind.__name__}")
        if self.check is not None:
            try:
                self.check(point.name, part)
            except ValueError as err:
                raise ExtensionError(f"{where} is refused: {err}") from err
        return part

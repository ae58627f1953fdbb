"""Plugin registries: built-ins plus `importlib.metadata` entry points.

Groups: ``millpost.dialects`` (a `millpost.gcode.dialects.Dialect` instance) and
``millpost.force_models`` (a class with ``from_material(material, **settings)`` returning a model with
``predict`` and ``linear_loads``, as `millpost.forces.Mechanistic`). A third-party package adds a
plugin by declaring an entry point in its own group table; built-ins are declared the same way in
millpost's pyproject, so there is one mechanism for both. Plugins are read once per process.
"""

from __future__ import annotations

from functools import cache
from importlib.metadata import entry_points
from typing import Any

from .errors import MillpostError


@cache
def plugins(group: str) -> dict[str, Any]:
    """All plugins of an entry-point group, loaded, by name."""
    return {ep.name: ep.load() for ep in entry_points(group=f"millpost.{group}")}


def plugin(group: str, name: str) -> Any:
    """One plugin by name, or a clear error listing what exists."""
    found = plugins(group)
    if name not in found:
        raise MillpostError(f"unknown {group[:-1] if group.endswith('s') else group} {name!r}; "
                            f"known: {', '.join(sorted(found)) or 'none'}")
    return found[name]

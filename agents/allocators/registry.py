"""Allocators by name: the built-in modules, and plugins installed with an entry point.

A package adds an allocator to every robot process by declaring, in its ``pyproject.toml``::

    [project.entry-points."fleet_emu.allocators"]
    tiny = "tiny_alloc:Tiny"

The entry point's name is the allocator's name. The installed entry points are listed once, the first time the
registry is consulted, and each is imported only when its allocator is asked for (:func:`allocator_class`), so
a plugin that fails to import breaks only itself. The loaded object must be an :class:`Allocator` subclass; one
registered with ``plugin_name`` must use the entry point's name, one without is registered under it. Every
failure is a :class:`ConfigError` of one line naming the plugin.
"""

from __future__ import annotations

from collections.abc import Mapping
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from fleet_emu.agents.allocators.interface import Allocator
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.setting_names import near

GROUP = "fleet_emu.allocators"

_plugins: dict[str, EntryPoint] | None = None
_broken: dict[str, str] = {}  # plugin name -> why it did not load (it is not tried again)


def plugins() -> dict[str, EntryPoint]:
    """The installed entry points of :data:`GROUP` by name (listed once, not loaded)."""
    global _plugins
    if _plugins is None:
        _plugins = {ep.name: ep for ep in entry_points(group=GROUP)}
    return _plugins


def allocator_names() -> list[str]:
    """Every allocator that can be asked for: the registered ones and the installed plugins (built-ins win a
    name both have)."""
    return sorted(set(Allocator.registry) | set(plugins()))


def allocator_class(name: object) -> type[Allocator]:
    """The allocator class of ``name``, loading its plugin if need be; ConfigError on an unknown name (listing
    the known ones) or a plugin that does not load."""
    if isinstance(name, str):
        cls = Allocator.registry.get(name)
        if cls is not None:
            return cls
        if name in plugins():
            return _load(name)
    known = allocator_names()
    raise ConfigError(f"unknown allocator {name!r}{near(name, known)} (known: {', '.join(known)})")


def _load(name: str) -> type[Allocator]:
    if name in _broken:
        raise ConfigError(_broken[name])
    ep = plugins()[name]
    try:
        obj = ep.load()
        if not (isinstance(obj, type) and issubclass(obj, Allocator)):
            raise TypeError(f"{obj!r} is not an Allocator subclass")
        if Allocator.registry.get(obj.plugin_name) is not obj:
            obj.register(name)
        elif obj.plugin_name != name:
            raise TypeError(f"the class registers itself as {obj.plugin_name!r}")
    except Exception as exc:  # whatever a third-party import raises, it is that plugin's failure only
        _broken[name] = f"allocator plugin {name!r} ({ep.value}) failed to load: {type(exc).__name__}: {exc}"
        raise ConfigError(_broken[name]) from None
    return obj


def make_allocator(config: Mapping[str, Any]) -> Allocator:
    """``{"type": "minpos", ...params}`` to an allocator. Raises ConfigError only: an unknown name, a plugin
    that does not load, an unknown parameter or a bad value."""
    params = dict(config)
    name = params.pop("type", None)
    cls = allocator_class(name)
    try:
        return cls(**params)
    except ConfigError:
        raise
    except (TypeError, ValueError) as exc:  # an allocator's own check beyond its declared parameters
        raise ConfigError(f"allocator {name!r}: {exc}") from None

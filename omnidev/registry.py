"""The plugin registry: Python entry points in five groups.

| group               | entry-point name        | the object it loads                          |
|---------------------|-------------------------|----------------------------------------------|
| ``omnidev.sources`` | URI scheme (``video``)  | a callable ``open(uri_rest, options)``       |
| ``omnidev.unwarpers`` | calibration kind      | an :class:`~omnidev.camera.Unwarper` class |
| ``omnidev.trackers`` | tracker name           | a tracker factory                            |
| ``omnidev.sinks``   | sink name               | a sink factory                               |
| ``omnidev.outputs`` | URI scheme (``v4l2``)   | a callable ``open(rest, options, spec)``     |

First-party plugins register exactly as a vendor's would. A plugin that fails
to import is reported as broken (with its error) and the others keep working;
when two distributions register one name in one group, both are listed as
broken and :func:`get` of that name raises a :class:`PluginError` naming both.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import metadata
from typing import Any

from omnidev.errors import PluginError

GROUPS = (
    "omnidev.sources",
    "omnidev.unwarpers",
    "omnidev.trackers",
    "omnidev.sinks",
    "omnidev.outputs",
)


@dataclass(frozen=True)
class PluginInfo:
    """One registered plugin: where it comes from and whether it loads."""

    group: str
    name: str
    value: str  # "module:attr"
    distribution: str
    version: str
    error: str | None = None  # set when the plugin failed to import

    @property
    def broken(self) -> bool:
        return self.error is not None


def _entry_points(group: str) -> list[tuple[metadata.EntryPoint, str, str]]:
    """(entry point, distribution, version) for a group, one per distribution and name."""
    seen: dict[tuple[str, str], tuple[metadata.EntryPoint, str, str]] = {}
    for dist in metadata.distributions():
        dname = dist.metadata["Name"] or "?"
        for ep in dist.entry_points:
            if ep.group == group:
                seen.setdefault((ep.name, dname), (ep, dname, dist.version))
    return sorted(seen.values(), key=lambda t: (t[0].name, t[1]))


def _load(ep: metadata.EntryPoint) -> tuple[Any, str | None]:
    try:
        return ep.load(), None
    except Exception as exc:  # a broken plugin must not break the others
        return None, f"{type(exc).__name__}: {exc}"


@cache
def _group(group: str) -> tuple[dict[str, PluginInfo], dict[str, Any]]:
    entries = _entry_points(group)
    dists: dict[str, list[str]] = {}
    for ep, dist, _ in entries:
        dists.setdefault(ep.name, []).append(dist)
    infos: dict[str, PluginInfo] = {}
    objects: dict[str, Any] = {}
    for ep, dist, version in entries:
        key = ep.name
        if len(dists[ep.name]) > 1:
            # Neither wins: both are listed as broken, and using the name fails.
            key = f"{ep.name} [{dist}]"
            both = " and ".join(dists[ep.name])
            clash = (
                f"plugin name {ep.name!r} in group {group} is registered by two "
                f"distributions: {both}; uninstall one of them"
            )
            infos[key] = PluginInfo(group, ep.name, ep.value, dist, version, clash)
            continue
        obj, err = _load(ep)
        infos[key] = PluginInfo(group, ep.name, ep.value, dist, version, err)
        if err is None:
            objects[key] = obj
    return infos, objects


def refresh() -> None:
    """Forget what was discovered (after installing or removing a plugin at run time)."""
    _group.cache_clear()


def plugins(group: str) -> list[PluginInfo]:
    """Every plugin of a group, broken ones included, sorted by name."""
    if group not in GROUPS:
        raise PluginError(f"unknown plugin group {group!r}; groups are {', '.join(GROUPS)}")
    return sorted(_group(group)[0].values(), key=lambda p: (p.name, p.distribution))


def get(group: str, name: str) -> Any:
    """The loaded object of plugin ``name`` in ``group``.

    Raises :class:`PluginError` naming the installed plugins when ``name`` is
    unknown, or giving the import error when it is broken.
    """
    infos, objects = _group(group)
    if name in objects:
        return objects[name]
    if name in infos:
        info = infos[name]
        raise PluginError(
            f"plugin {name!r} ({info.distribution} {info.version}) is broken: {info.error}"
        )
    clash = [i for i in infos.values() if i.name == name]
    if clash:
        raise PluginError(str(clash[0].error))
    ok = sorted(objects)
    installed = ", ".join(ok) if ok else "none"
    kind = {
        "omnidev.unwarpers": "camera kind",
        "omnidev.sources": "source scheme",
        "omnidev.trackers": "tracker",
        "omnidev.sinks": "sink",
        "omnidev.outputs": "output scheme",
    }.get(group, "plugin")
    raise PluginError(f"no plugin for {kind} {name!r} in {group}; installed: {installed}")

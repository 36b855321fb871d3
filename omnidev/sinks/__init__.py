"""Pointer sinks (group ``omnidev.sinks``): normalized positions and buttons in, OS events out.

| sink | output | adapter module |
|---|---|---|
| ``uinput`` | a kernel absolute pointer (/dev/uinput) | :mod:`omnidev.sinks.uinput_sink` |
| ``xtest`` | an X server's pointer through XTest | :mod:`omnidev.sinks.xtest_sink` |
| ``hidg`` | a USB HID mouse for another computer (/dev/hidgN) | :mod:`omnidev.sinks.hidg_sink` |
| ``record`` | JSON lines, one per event | :mod:`omnidev.sinks.record` |

A sink plugin's entry point is a callable ``open(options, mapping) -> PointerSink``
where ``options`` is the sink's table from the daemon configuration (strings,
numbers, booleans) and ``mapping`` the :class:`~omnidev.screen.ScreenMapping`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from omnidev import registry
from omnidev.errors import PluginError, SinkError
from omnidev.screen import ScreenMapping
from omnidev.sinks.base import BUTTONS, PointerSink, release_on_signals

GROUP = "omnidev.sinks"

__all__ = ["BUTTONS", "GROUP", "PointerSink", "open_sink", "release_on_signals"]


def open_sink(name: str, options: Mapping[str, Any], mapping: ScreenMapping) -> PointerSink:
    """Open the sink plugin ``name`` with its options."""
    try:
        opener = registry.get(GROUP, name)
    except PluginError as exc:
        raise SinkError(str(exc)) from None
    sink: PointerSink = opener(dict(options), mapping)
    return sink

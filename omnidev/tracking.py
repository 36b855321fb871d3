"""Trackers (group ``omnidev.trackers``): Frames in, :class:`~omnidev.frame.PointerSample` out.

A tracker plugin's entry point is a callable
``open(options, calibration) -> Tracker``: ``options`` is the tracker's table
from the daemon configuration, ``calibration`` the path of its calibration
file or None. A tracker returns None for a frame in which it found nothing;
the daemon then holds the pointer where it was.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from omnidev import registry
from omnidev.errors import PluginError, TrackerError
from omnidev.frame import Frame, PointerSample

GROUP = "omnidev.trackers"


@runtime_checkable
class Tracker(Protocol):
    """Turns frames into pointer samples (normalized target-screen coordinates)."""

    def track(self, frame: Frame) -> PointerSample | None:
        """The pointer for this frame, with ``timestamp_ns`` = the frame's ``timestamp_ns``
        (a camera's capture time, a file's presentation time)."""
        ...

    def reset(self) -> None:
        """Forget state carried between frames (after the source restarted)."""
        ...


def open_tracker(name: str, options: Mapping[str, Any], calibration: Path | None) -> Tracker:
    """Create tracker plugin ``name``."""
    try:
        opener = registry.get(GROUP, name)
    except PluginError as exc:
        raise TrackerError(str(exc)) from None
    tracker: Tracker = opener(dict(options), calibration)
    return tracker

"""Errors that reach a user: each says what is wrong and names the file, row, key or frame.

The CLI prints an :class:`OmnidevError` as one line and exits non-zero; anything
else is a bug and keeps its traceback.
"""

from __future__ import annotations


class OmnidevError(Exception):
    """A user-facing error: bad input, a missing device, an unknown plugin."""


class CalibrationError(OmnidevError):
    """A calibration file or calibration input that cannot be used."""


class SourceError(OmnidevError):
    """A frame source that cannot be opened or stopped delivering."""


class FileSourceError(SourceError):
    """A recorded source (a video file, an image set) that is missing, unreadable,
    truncated or corrupt: final, never retried as an unplugged camera would be."""


class PluginError(OmnidevError):
    """A plugin that is unknown, broken, or registered twice."""


class OutputError(OmnidevError):
    """An output that cannot be written (exists, unwritable directory)."""


class SinkError(OmnidevError):
    """A pointer sink that cannot be opened or stopped accepting events."""


class ConfigError(OmnidevError):
    """A daemon configuration that is invalid; the message names the key."""


class TrackerError(OmnidevError):
    """A tracker that cannot be created or cannot process a frame."""


def naming(path: object, exc: BaseException) -> str:
    """``exc``'s message led by ``path``, unless the message names it already."""
    said = str(exc)
    return said if str(path) in said else f"{path}: {said}"

"""Frame sources: one URI syntax for files, image sets and cameras.

``SCHEME:REST[?key=value&key=value]``:

| URI | source |
|---|---|
| ``video:PATH[?rate=R&loop=1]`` | a video file (``rate``: stand in for a camera, see below) |
| ``images:GLOB[?fps=F]`` | still images (a glob, a folder or one file), sorted by name |
| ``v4l2:/dev/videoN?width=W&height=H&fps=F&fourcc=CCCC`` | a V4L2 capture device |
| ``usb:VID:PID[:SERIAL]`` | the V4L2 node of a USB camera (hex vendor:product) |

A bare path means ``v4l2:`` when it is a device node (``/dev/videoN``),
``images:`` when it is a folder, a glob or an image file, and ``video:`` otherwise.
Schemes are plugins (group ``omnidev.sources``): the entry point is a callable
``open(rest, options) -> Source``.

Two kinds of source, told apart by ``Source.live``:

- *recorded* (``live`` False: a video file, an image set): frames carry the
  file's own timestamps (presentation times, from the start of the file), the
  consumer may take its time (the pipeline waits rather than drop a frame), and
  a missing, truncated or corrupt file raises :class:`~omnidev.errors.FileSourceError`,
  which is final;
- *live* (``live`` True: a camera, or a file paced with ``rate=``): frames carry
  the monotonic time of capture, they come whether or not the consumer is ready
  (the pipeline drops the oldest and counts it), and a camera that stops raises
  :class:`~omnidev.errors.SourceError`, after which the daemon reopens it.
"""

from __future__ import annotations

import glob as _glob
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Protocol, runtime_checkable
from urllib.parse import parse_qsl

from omnidev import registry
from omnidev.errors import PluginError, SourceError
from omnidev.frame import Frame

GROUP = "omnidev.sources"
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm"}


@runtime_checkable
class Source(Protocol):
    """An iterable of :class:`~omnidev.frame.Frame` that must be closed."""

    name: str  # the URI it was opened from
    frame_count: int | None  # total frames when known (files), else None
    fps: float | None
    live: bool  # frames come at the source's pace, stamped on the monotonic clock

    def __iter__(self) -> Iterator[Frame]: ...

    def close(self) -> None: ...

    def __enter__(self) -> Source: ...

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None: ...


class SourceBase:
    """Context-manager plumbing shared by the first-party sources."""

    name: str = ""
    frame_count: int | None = None
    fps: float | None = None
    live: bool = False

    def close(self) -> None:
        """Release the device or file."""

    def __enter__(self) -> SourceBase:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def split_uri(uri: str) -> tuple[str, str, dict[str, str]]:
    """(scheme, rest, options) of a URI; a bare path gets its scheme from what it is.

    >>> split_uri("v4l2:/dev/video0?width=640&fps=30")
    ('v4l2', '/dev/video0', {'width': '640', 'fps': '30'})
    """
    scheme, sep, rest = uri.partition(":")
    if not sep or "/" in scheme or "." in scheme or len(scheme) < 2:
        return _bare(uri), uri, {}
    rest, _, query = rest.partition("?")
    options = dict(parse_qsl(query, keep_blank_values=True)) if query else {}
    return scheme.lower(), rest, options


FILE_SCHEMES = ("video", "images")
"""Schemes whose rest is a path of the file system (relative paths can be resolved)."""


def resolve_uri(uri: str, base: Path) -> str:
    """``uri`` with a relative file path made relative to folder ``base`` instead of the
    current directory: the rule for paths in rig files and daemon configurations (a path
    is relative to the file that names it).

    >>> resolve_uri("video:clips/a.avi?loop=1", Path("/etc/omnidev"))
    'video:/etc/omnidev/clips/a.avi?loop=1'
    >>> resolve_uri("v4l2:/dev/video0", Path("/etc/omnidev"))
    'v4l2:/dev/video0'
    >>> resolve_uri("omni.png", Path("/data"))
    '/data/omni.png'
    """
    scheme, sep, rest = uri.partition(":")
    bare = not sep or "/" in scheme or "." in scheme or len(scheme) < 2
    if bare:
        return uri if not uri or Path(uri).is_absolute() else str(base / uri)
    if scheme.lower() not in FILE_SCHEMES:
        return uri
    path, q, query = rest.partition("?")
    if not path or Path(path).is_absolute():
        return uri
    return f"{scheme}:{base / path}{q}{query}"


def _bare(path: str) -> str:
    """The scheme of a bare path.

    >>> _bare("/dev/video0"), _bare("talk.mp4"), _bare("shots/*.png")
    ('v4l2', 'video', 'images')
    """
    p = Path(path)
    if path.startswith("/dev/video") or p.is_char_device():
        return "v4l2"  # a camera node: live, retried when it goes away (not a missing file)
    if p.is_dir() or _glob.has_magic(path) or p.suffix.lower() in IMAGE_SUFFIXES:
        return "images"
    return "video"


def check_options(uri: str, options: dict[str, str], allowed: set[str]) -> None:
    """Raise :class:`SourceError` for an option the source does not know."""
    for key in options:
        if key not in allowed:
            known = ", ".join(sorted(allowed)) or "none"
            raise SourceError(f"{uri}: unknown option {key!r} (options: {known})")


def open_source(uri: str) -> Source:
    """Open a source by URI or bare path (see the module docstring)."""
    scheme, rest, options = split_uri(uri)
    try:
        opener = registry.get(GROUP, scheme)
    except PluginError as exc:
        raise SourceError(f"{uri}: {exc}") from None
    source: Source = opener(rest, options)
    return source

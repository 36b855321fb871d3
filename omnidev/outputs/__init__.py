"""Frame outputs: where unwarped frames go. One URI syntax for files, pipes and devices.

``SCHEME:REST[?key=value&key=value]``:

| URI | output |
|---|---|
| ``PATH``, ``file:PATH[?codec=&crf=&preset=&q=]`` | an image or a video file, atomically |
| ``-`` or ``y4m:-`` | a YUV4MPEG2 stream on standard output (ffmpeg, GStreamer, mpv) |
| ``y4m:PATH`` | the same into a FIFO (as it comes) or a file (atomically) |
| ``raw:-?format=bgr24`` | bare frames on standard output (``bgr24 rgb24 gray yuv420p``) |
| ``v4l2:/dev/videoN[?format=yuyv]`` | a V4L2 output device (v4l2loopback: a camera to others) |

A bare path means ``file:``, a bare ``-`` means ``y4m:-``. Schemes are plugins
(group ``omnidev.outputs``): the entry point is a callable
``open(rest, options, spec) -> Output`` (see docs/outputs.md).

**Streams.** An output is opened once, with the frame size and rate it will get
(:class:`OutputSpec`), and then takes any number of frames with
:meth:`Output.write`, each a :class:`~omnidev.frame.Frame` whose
``timestamp_ns`` is the capture time (monotonic ns) and ``index`` the source
frame index; a long-running stream (the daemon) keeps it open for as long as
it runs and calls :meth:`Output.close` when it stops, :meth:`Output.abort` when
it fails. Files stamp frames at a constant rate (``spec.fps``) in the order
written; a V4L2 device shows each frame as soon as it is written.

**Layouts.** ``write`` takes ``frame.image`` in the layout ``output.layout``
names, chosen by the output at open time from ``spec.layouts`` (the layouts the
caller can deliver, its preferred first): ``bgr`` (H x W x 3), ``gray`` (H x W),
``yuv420p`` or ``yuvj420p`` (planar 4:2:0 in OpenCV's I420 memory layout,
(H * 3 / 2) x W: the Y plane, then U, then V; BT.601, limited range 16..235 or
full range 0..255). Every output takes ``bgr`` and ``gray``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable
from dataclasses import dataclass
from types import TracebackType
from typing import Literal, Protocol, runtime_checkable

from omnidev import registry
from omnidev.errors import OutputError, PluginError
from omnidev.frame import Frame
from omnidev.sources import split_uri

GROUP = "omnidev.outputs"

Layout = Literal["bgr", "gray", "yuv420p", "yuvj420p"]
LAYOUTS: tuple[Layout, ...] = ("bgr", "gray", "yuv420p", "yuvj420p")


MAX_FPS = 1000.0
"""Highest frame rate an output takes, frames per second (an encoder never returns for an
infinite one)."""


@dataclass(frozen=True)
class OutputSpec:
    """What an output is opened for.

    Attributes:
        size: (width, height) of every frame, px.
        fps: frame rate, frames per second (the source's, or the user's ``--fps``).
        layouts: image layouts the caller can deliver, preferred first (see the
            module docstring); ``gray`` alone for gray frames.
        force: overwrite an existing file.
        live: the frames come from a live source at its own rate (an output
            that feeds a real-time consumer paces non-live frames to ``fps``).
        threads: CPU threads an encoder may use.
    """

    size: tuple[int, int]
    fps: float
    layouts: tuple[Layout, ...] = ("bgr",)
    force: bool = False
    live: bool = False
    threads: int = 1

    def __post_init__(self) -> None:
        w, h = self.size
        if w < 1 or h < 1:
            raise ValueError(f"frame size must be positive, got {w}x{h}")
        if not 0 < self.fps <= MAX_FPS:
            raise ValueError(f"fps must be in (0, {MAX_FPS:g}], got {self.fps}")
        bad = [x for x in self.layouts if x not in LAYOUTS]
        if bad or not self.layouts:
            raise ValueError(f"layouts must be some of {LAYOUTS}, got {self.layouts}")

    @property
    def gray(self) -> bool:
        """True when the frames are gray (H x W)."""
        return self.layouts == ("gray",)


@runtime_checkable
class Output(Protocol):
    """Takes frames of one size until closed; see the module docstring."""

    name: str  # the URI it was opened from, for messages
    layout: Layout  # the layout write() takes, one of spec.layouts (or "bgr"/"gray")
    frames: int  # frames written so far

    def write(self, frame: Frame) -> None:
        """Write one frame; raise :class:`OutputError` naming the output and frame."""
        ...

    def close(self) -> None:
        """Finish: flush, commit a file (rename it into place), release the device."""
        ...

    def abort(self) -> None:
        """Give up: a file output leaves nothing behind; never raises."""
        ...

    def __enter__(self) -> Output: ...

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None: ...


class OutputBase:
    """Context-manager plumbing shared by the first-party outputs.

    Leaving a ``with`` block normally calls :meth:`close`, by an exception
    :meth:`abort`.
    """

    name: str = ""
    layout: Layout = "bgr"
    frames: int = 0

    def close(self) -> None:
        """Finish the output."""

    def abort(self) -> None:
        """Give up; by default the same as :meth:`close`, errors suppressed."""
        with contextlib.suppress(Exception):
            self.close()

    def __enter__(self) -> OutputBase:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        if t is None:
            self.close()
        else:
            self.abort()


def choose_layout(name: str, spec: OutputSpec, accepted: Iterable[Layout]) -> Layout:
    """The first of ``spec.layouts`` that an output accepts (``bgr`` and ``gray`` always are)."""
    ok = set(accepted) | {"bgr", "gray"}
    for layout in spec.layouts:
        if layout in ok:
            return layout
    raise OutputError(f"{name}: takes none of the layouts {', '.join(spec.layouts)}")


def check_output_options(name: str, options: dict[str, str], allowed: set[str]) -> None:
    """Raise :class:`OutputError` for an option the output does not know."""
    for key in options:
        if key not in allowed:
            known = ", ".join(sorted(allowed)) or "none"
            raise OutputError(f"{name}: unknown option {key!r} (options: {known})")


def split_output_uri(uri: str) -> tuple[str, str, dict[str, str]]:
    """(scheme, rest, options) of an output URI; ``-`` is ``y4m:-``, a bare path ``file:``.

    >>> split_output_uri("v4l2:/dev/video10?format=yuyv")
    ('v4l2', '/dev/video10', {'format': 'yuyv'})
    >>> split_output_uri("-")
    ('y4m', '-', {})
    >>> split_output_uri("out/pano.mp4")
    ('file', 'out/pano.mp4', {})
    """
    if uri == "-":
        return "y4m", "-", {}
    scheme, rest, options = split_uri(uri)
    if scheme in ("images", "video"):  # what omnidev.sources calls a bare path
        return "file", uri, {}
    return scheme, rest, options


def open_output(uri: str, spec: OutputSpec) -> Output:
    """Open an output by URI or bare path (see the module docstring)."""
    scheme, rest, options = split_output_uri(str(uri))
    try:
        opener = registry.get(GROUP, scheme)
    except PluginError as exc:
        raise OutputError(f"{uri}: {exc}") from None
    output: Output = opener(rest, options, spec)
    return output


def uses_stdout(uri: str) -> bool:
    """True when the output URI writes to standard output (``-``, ``y4m:-``, ``raw:-``)."""
    scheme, rest, _ = split_output_uri(str(uri))
    return scheme in ("y4m", "raw") and rest == "-"

"""``video:PATH[?rate=R&loop=1]`` — frames of a video file.

A file read at its own pace (no ``rate``) is a *recorded* source: every frame is
delivered (the pipeline waits for the tracker rather than drop one), and each
frame's ``timestamp_ns`` is its presentation time from the container, counted
from the start of the file, so the filter and the dwell click see the video's
own timing however fast it decodes. ``rate`` makes the file stand in for a
camera: frames come at ``rate`` frames per second (``realtime``: at their
presentation times), stamped with the monotonic time of delivery, and a slow
tracker loses the oldest ones, as with a camera. ``loop=1`` starts again at the
end, for ever (timestamps go on increasing: each pass adds the file's length).

A file is complete when its frames reach the length its container states: the
frame count, or for containers that give only a duration (Matroska, WebM), that
duration to within about one frame. A file that stops short (truncated), or a
frame that cannot be decoded, ends the run with a :class:`FileSourceError`
naming the last good frame; a file that is missing or unreadable is one too.
None of these is ever retried as a camera would be.

Decoding sits behind :class:`Decoder` (OpenCV's FFmpeg reader here), so another
library can deliver the same frames and presentation times.
"""

from __future__ import annotations

import logging
import math
import statistics
import time
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple, Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.budget import check_pixels
from omnidev.errors import FileSourceError, OmnidevError, SourceError
from omnidev.frame import Frame
from omnidev.sources import SourceBase, check_options

log = logging.getLogger("omnidev.sources")

MIN_RATE, MAX_RATE = 0.01, 10_000.0  # frames per second: ``rate`` outside is refused


class Decoded(NamedTuple):
    """One frame in presentation order: ``image`` None when it cannot be decoded;
    ``pts_s`` its presentation time, s from the start of the file (None: the
    container has none)."""

    image: NDArray[np.uint8] | None
    pts_s: float | None


class Decoder(Protocol):
    """What :class:`VideoSource` needs of a video decoder."""

    frame_count: int | None  # frames the container states (may come from its duration)
    fps: float | None  # the container's nominal frame rate

    def read(self) -> Decoded | None:
        """The next frame, or None at the end of the data."""
        ...

    def rewind(self) -> None:
        """Start again at the first frame."""
        ...

    def close(self) -> None: ...


class OpenCVDecoder:
    """A video file through ``cv2.VideoCapture`` (its FFmpeg backend for most files).

    Presentation times come from ``CAP_PROP_POS_MSEC`` after each grab, which the
    FFmpeg backend takes from the decoded frame's best-effort timestamp.
    """

    def __init__(self, path: Path, name: str) -> None:
        self._cap = cv2.VideoCapture(str(path))
        if not self._cap.isOpened():
            raise FileSourceError(f"{name}: OpenCV cannot read this file as a video")
        w, h = (
            int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
            int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
        )
        try:
            check_pixels(w, h, 12, f"{name}: decoding {w}x{h} frames")
        except OmnidevError:
            self._cap.release()
            raise
        n = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.frame_count: int | None = n if n > 0 else None
        fps = float(self._cap.get(cv2.CAP_PROP_FPS))
        self.fps: float | None = fps if math.isfinite(fps) and fps > 0 else None

    def read(self) -> Decoded | None:
        if not self._cap.grab():
            return None
        msec = float(self._cap.get(cv2.CAP_PROP_POS_MSEC))
        ok, image = self._cap.retrieve()
        pts = msec / 1000.0 if math.isfinite(msec) else None
        if not ok or image is None or image.size == 0:
            return Decoded(None, pts)
        return Decoded(np.asarray(image, np.uint8), pts)

    def rewind(self) -> None:
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)

    def close(self) -> None:
        self._cap.release()


class VideoSource(SourceBase):
    """A video file (see the module docstring for timestamps, pacing and errors).

    Args:
        path: the file.
        loop: start again at the end, for ever.
        rate: None (the file's own pace: every frame, presentation timestamps),
            ``"realtime"`` (delivered at the presentation times) or frames per
            second; with a rate the source is live.
        decoder: the decoder (default: :class:`OpenCVDecoder` on ``path``).
    """

    def __init__(
        self,
        path: str,
        *,
        loop: bool = False,
        rate: float | str | None = None,
        decoder: Decoder | None = None,
    ) -> None:
        self.path = Path(path)
        self.name = f"video:{path}"
        self.loop = loop
        if decoder is None:
            if not self.path.is_file():
                raise FileSourceError(f"{self.name}: file not found")
            decoder = OpenCVDecoder(self.path, self.name)
        self._dec = decoder
        self.frame_count = None if loop else decoder.frame_count
        self.fps = decoder.fps
        self.rate = rate
        if isinstance(rate, int | float):
            self.fps = float(rate)
        self.live = rate is not None
        self.timestamp_repairs = 0  # frames whose presentation time had to be made up

    def __iter__(self) -> Iterator[Frame]:
        index = 0
        offset_s = 0.0  # presentation time of the current pass's start (loops)
        period_ns = round(1e9 / self.rate) if isinstance(self.rate, int | float) else 0
        next_ns = time.monotonic_ns()
        anchor_ns: int | None = None  # realtime: when presentation time 0 is due
        while True:
            in_file = 0
            first_pts: float | None = None
            last_pts: float | None = None
            spacings: list[float] = []
            while True:
                got = self._dec.read()
                if got is None:
                    break
                if got.image is None:
                    raise FileSourceError(
                        f"{self.name}: frame {index} cannot be decoded (corrupt file?); "
                        f"{_last_good(index)}"
                    )
                pts = self._presentation_time(got.pts_s, last_pts, index)
                if last_pts is not None:
                    spacings.append(pts - last_pts)
                else:
                    first_pts = pts
                last_pts = pts
                t_s = offset_s + pts
                if period_ns:
                    delay = next_ns - time.monotonic_ns()
                    if delay > 0:
                        time.sleep(delay / 1e9)
                    next_ns = max(next_ns + period_ns, time.monotonic_ns())
                elif self.rate == "realtime":
                    if anchor_ns is None:  # the first frame goes now, the others after it
                        anchor_ns = time.monotonic_ns() - round(t_s * 1e9)
                    due = anchor_ns + round(t_s * 1e9)
                    delay = due - time.monotonic_ns()
                    if delay > 0:
                        time.sleep(delay / 1e9)
                    elif delay < -500_000_000:  # decoding fell far behind: start afresh
                        anchor_ns -= delay
                now = time.monotonic_ns()
                stamp = now if self.live else round(t_s * 1e9)
                yield Frame(got.image, stamp, index, now)
                index += 1
                in_file += 1
            self._check_complete(in_file, index, last_pts, spacings)
            if not self.loop or in_file == 0 or last_pts is None or first_pts is None:
                break
            offset_s += last_pts + _frame_spacing(spacings, self._dec.fps)
            self._dec.rewind()

    def _presentation_time(self, pts: float | None, last: float | None, index: int) -> float:
        """The container's presentation time, or one frame after the last when it has
        none usable (missing, or not after the previous frame's)."""
        if pts is not None and (last is None or pts > last):
            return pts
        step = 1.0 / self._dec.fps if self._dec.fps else 1.0 / 30.0
        made = 0.0 if last is None else last + step
        if self.timestamp_repairs == 0:
            log.warning(
                "%s: frame %d has no usable presentation time; timestamps follow the "
                "nominal frame rate (%.3g fps) where the file gives none",
                self.name,
                index,
                1.0 / step,
            )
        self.timestamp_repairs += 1
        return made

    def _check_complete(
        self, in_file: int, index: int, last_pts: float | None, spacings: list[float]
    ) -> None:
        """Raise when the frames stop short of the length the container states."""
        total = self._dec.frame_count
        if total is None or in_file >= total:
            return
        fps = self._dec.fps
        if in_file and last_pts is not None and fps and self.timestamp_repairs == 0:
            # A frame count from a duration (Matroska, variable frame rate) is an
            # estimate: accept frames that reach the stated length within a frame.
            spacing = _frame_spacing(spacings, fps)
            if last_pts + 2.0 * spacing >= total / fps:
                return
        raise FileSourceError(
            f"{self.name}: frame {index} is corrupt or missing (truncated file?): "
            f"read {in_file} of {total} frames, {_last_good(index)}"
        )

    def close(self) -> None:
        self._dec.close()


def _last_good(index: int) -> str:
    return f"last good frame {index - 1}" if index else "no frame decoded"


def _frame_spacing(spacings: list[float], fps: float | None) -> float:
    """The typical time between frames, s: the median spacing seen, else 1 / fps."""
    if spacings:
        return max(statistics.median(spacings), spacings[-1])
    return 1.0 / fps if fps else 0.0


def parse_rate(uri: str, text: str) -> float | str:
    """``rate=`` as frames per second in [MIN_RATE, MAX_RATE], or ``"realtime"``.

    >>> parse_rate("video:a.avi", "realtime"), parse_rate("video:a.avi", "30")
    ('realtime', 30.0)
    """
    if text == "realtime":
        return text
    try:
        rate = float(text)
    except ValueError:
        rate = math.nan
    if not (MIN_RATE <= rate <= MAX_RATE):
        raise SourceError(
            f"{uri}: option rate must be 'realtime' or frames per second from {MIN_RATE:g} "
            f"to {MAX_RATE:g}, got {text!r}"
        )
    return rate


def open_video(rest: str, options: dict[str, str]) -> VideoSource:
    uri = f"video:{rest}"
    check_options(uri, options, {"loop", "rate"})
    loop = options.get("loop", "0").lower()
    if loop not in ("0", "1", "yes", "no", "true", "false"):
        raise SourceError(f"{uri}: option loop must be 0 or 1, got {loop!r}")
    text = options.get("rate")
    rate = parse_rate(uri, text) if text is not None else None
    return VideoSource(rest, loop=loop in ("1", "yes", "true"), rate=rate)

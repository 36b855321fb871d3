"""The data that flows through omnidev: :class:`Frame` and :class:`PointerSample`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, slots=True)
class Frame:
    """One captured or decoded image.

    Attributes:
        image: H x W (gray) or H x W x 3 (BGR) uint8 array.
        timestamp_ns: the frame's own time, ns. A live source (a camera, or a file
            paced with ``rate=``) gives its capture time on the monotonic clock
            (``time.monotonic_ns``); a file read at its own pace gives its
            presentation time from the container, counted from the start of the
            file (not on the monotonic clock). Filters and dwell clicks run on it.
        index: 0-based frame index within its source.
        delivered_ns: monotonic time at which the source handed the frame over
            (decoded it, or received it from the driver); ``None`` when it is
            ``timestamp_ns`` (a live frame made by code that does not set it).
    """

    image: NDArray[np.uint8]
    timestamp_ns: int
    index: int
    delivered_ns: int | None = None

    @property
    def monotonic_ns(self) -> int:
        """When the frame entered omnidev on the monotonic clock, ns (latencies start here)."""
        return self.timestamp_ns if self.delivered_ns is None else self.delivered_ns


@dataclass(frozen=True, slots=True)
class PointerSample:
    """A pointer position from a tracker.

    Attributes:
        x, y: position normalized to [0, 1] x [0, 1] of the target screen
            (0, 0 = top-left corner, x right, y down).
        buttons: names of the buttons held down ("left", "right", "middle").
        confidence: 0 (no idea) .. 1 (certain).
        timestamp_ns: the ``timestamp_ns`` of the frame it came from (see
            :class:`Frame`: capture time of a live frame, presentation time of a
            file's frame).
        frame_index: the ``index`` of that frame, when known (the pipeline sets it).
    """

    x: float
    y: float
    timestamp_ns: int
    confidence: float = 1.0
    buttons: frozenset[str] = field(default_factory=frozenset)
    frame_index: int | None = None

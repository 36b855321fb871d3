"""The data that flows through omnidev: :class:`Frame` and :class:`PointerSample`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, slots=True)
class Frame:
    """One captured image.

    Attributes:
        image: H x W (gray) or H x W x 3 (BGR) uint8 array.
        timestamp_ns: capture time on the monotonic clock (``time.monotonic_ns``), ns.
        index: 0-based frame index within its source.
    """

    image: NDArray[np.uint8]
    timestamp_ns: int
    index: int


@dataclass(frozen=True, slots=True)
class PointerSample:
    """A pointer position from a tracker.

    Attributes:
        x, y: position normalized to [0, 1] x [0, 1] of the target screen
            (0, 0 = top-left corner, x right, y down).
        buttons: names of the buttons held down ("left", "right", "middle").
        confidence: 0 (no idea) .. 1 (certain).
        timestamp_ns: capture time of the frame it came from (monotonic ns).
    """

    x: float
    y: float
    timestamp_ns: int
    confidence: float = 1.0
    buttons: frozenset[str] = field(default_factory=frozenset)

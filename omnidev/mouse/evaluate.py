"""Camera-mouse accuracy against rendered truth, split by how many landmarks were visible.

Pure: cursor samples and per-frame truth in, figures out. Errors are in pixels of
the truth's screen (1920 x 1080 for omnidev.sim.monitor), from the normalized
cursor ``(x, y)`` and the truth's normalized ``screen_xy`` (0..1 spanning pixel
centres 0..W-1, 0..H-1).

Frame classes (by the truth's ``visible`` flags, i.e. whole landmark squares in
the picture):

- ``all4``: four visible; the cursor should be within ~2 px.
- ``predicted``: two or three visible; the missing ones are predicted (sec. 6.2.5).
- ``hold``: one or none visible; the tracker must give no cursor (the pointer
  holds its last position). "Visible" means the whole white square is in the
  picture; a square cut by the image border may leave its disc trackable, so a
  cursor on a hold frame counts as a violation only when fewer than two
  landmark centres are inside the picture (``image_size`` given); otherwise its
  error is counted with the ``predicted`` class.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class ClassFigures:
    """Errors (px) of the frames of one class that gave a cursor, and the rest counted."""

    frames: int = 0
    errors_px: list[float] = field(default_factory=list)
    no_cursor: int = 0

    @property
    def rms_px(self) -> float:
        e = np.asarray(self.errors_px)
        return float(np.sqrt(np.mean(e * e))) if e.size else math.nan

    @property
    def max_px(self) -> float:
        return float(np.max(self.errors_px)) if self.errors_px else math.nan

    def as_dict(self) -> dict[str, Any]:
        return {
            "frames": self.frames,
            "with_cursor": len(self.errors_px),
            "no_cursor": self.no_cursor,
            "rms_px": round(self.rms_px, 3),
            "max_px": round(self.max_px, 3),
        }


@dataclass
class MouseFigures:
    """Per-class figures of one video (see the module docstring)."""

    all4: ClassFigures = field(default_factory=ClassFigures)
    predicted: ClassFigures = field(default_factory=ClassFigures)
    hold: ClassFigures = field(default_factory=ClassFigures)
    no_truth_cursor: int = 0  # cursors on frames with no screen point (no monitor)
    hold_with_discs: int = 0  # hold frames with a cursor from two discs whose squares are cut

    def as_dict(self) -> dict[str, Any]:
        return {
            "all4": self.all4.as_dict(),
            "predicted": self.predicted.as_dict(),
            "hold_frames": self.hold.frames,
            "hold_violations": len(self.hold.errors_px),
            "hold_frames_tracked_on_cut_squares": self.hold_with_discs,
            "false_cursors": self.no_truth_cursor,
        }


def cursor_error_px(
    xy: tuple[float, float], truth_xy: Sequence[float], screen_px: tuple[int, int] = (1920, 1080)
) -> float:
    """Distance (screen px) between a normalized cursor and the truth's normalized point."""
    w, h = screen_px
    return math.hypot((xy[0] - truth_xy[0]) * (w - 1), (xy[1] - truth_xy[1]) * (h - 1))


def _centres_inside(t: Mapping[str, Any], image_size: tuple[int, int]) -> int:
    w, h = image_size
    return sum(
        1
        for uv in t["landmarks_uv"]
        if uv is not None and 0 <= uv[0] <= w - 1 and 0 <= uv[1] <= h - 1
    )


def evaluate(
    cursors: Sequence[tuple[float, float] | None],
    truth: Sequence[Mapping[str, Any]],
    screen_px: tuple[int, int] = (1920, 1080),
    image_size: tuple[int, int] | None = None,
) -> MouseFigures:
    """Figures for one video: ``cursors[i]`` is frame i's normalized cursor or None.

    ``truth[i]`` holds ``visible`` (four bools) and ``screen_xy`` (normalized or
    None), as in omnidev.sim.monitor's truth.json ``per_frame``. A frame with no
    screen point (no monitor) that got a cursor counts in ``no_truth_cursor``.
    """
    if len(cursors) != len(truth):
        raise ValueError(f"{len(cursors)} cursors for {len(truth)} truth frames")
    fig = MouseFigures()
    for c, t in zip(cursors, truth, strict=True):
        nv = sum(bool(v) for v in t["visible"])
        cls = fig.all4 if nv == 4 else fig.predicted if nv >= 2 else fig.hold
        cls.frames += 1
        if (
            cls is fig.hold
            and c is not None
            and image_size is not None
            and _centres_inside(t, image_size) >= 2
            and t["screen_xy"] is not None
        ):
            fig.predicted.errors_px.append(cursor_error_px(c, t["screen_xy"], screen_px))
            fig.hold_with_discs += 1
            continue
        if c is None:
            cls.no_cursor += 1
            continue
        if t["screen_xy"] is None:
            fig.no_truth_cursor += 1
            cls.errors_px.append(math.inf)
            continue
        cls.errors_px.append(cursor_error_px(c, t["screen_xy"], screen_px))
    return fig

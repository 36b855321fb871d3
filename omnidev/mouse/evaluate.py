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


# ------------------------------------------------------------------ randomized videos

ON_SCREEN_CLASSES = ("all4", "predicted")
GROSS_PX = 50.0  # a cursor farther than this from the truth is counted as wrong


def _stats(errors: Sequence[float]) -> dict[str, Any]:
    """RMS, p95 and max (px) of finite errors, with their count."""
    e = np.asarray(errors, dtype=np.float64)
    if not e.size:
        return {"n": 0, "rms_px": None, "p95_px": None, "max_px": None}
    return {
        "n": int(e.size),
        "rms_px": round(float(np.sqrt(np.mean(e * e))), 3),
        "p95_px": round(float(np.percentile(e, 95)), 3),
        "max_px": round(float(e.max()), 3),
    }


def _clamp01(xy: Sequence[float]) -> tuple[float, float]:
    return (min(1.0, max(0.0, float(xy[0]))), min(1.0, max(0.0, float(xy[1]))))


@dataclass
class VideoErrors:
    """Per-frame errors of one randomized video, by class (see :func:`video_errors`)."""

    kind: str
    errors: dict[str, list[float]] = field(default_factory=dict)
    frames: dict[str, int] = field(default_factory=dict)
    cursors: dict[str, int] = field(default_factory=dict)
    false_cursors: int = 0
    hold_violations: int = 0
    gross: int = 0
    want_cursor: int = 0  # on-screen frames with >= 2 landmarks visible
    have_cursor: int = 0  # ... of which gave a cursor

    def summary(self) -> dict[str, Any]:
        """JSON-ready figures of this video."""
        out: dict[str, Any] = {"kind": self.kind}
        for c in ("all4", "predicted", "off_screen"):
            out[c] = {
                "frames": self.frames.get(c, 0),
                "with_cursor": self.cursors.get(c, 0),
                **_stats(self.errors.get(c, [])),
            }
        out["hold_frames"] = self.frames.get("hold", 0)
        out["hold_violations"] = self.hold_violations
        out["false_cursors"] = self.false_cursors
        out["gross_errors"] = self.gross
        out["cursor_rate"] = (
            round(self.have_cursor / self.want_cursor, 4) if self.want_cursor else None
        )
        out["frames_wanting_cursor"] = self.want_cursor
        return out


def video_errors(
    cursors: Sequence[tuple[float, float] | None],
    truth: Sequence[Mapping[str, Any]],
    *,
    kind: str,
    screen_px: tuple[int, int] = (1920, 1080),
) -> VideoErrors:
    """Sort a randomized video's frames into classes and measure each cursor (px).

    ``truth[i]`` as :meth:`omnidev.sim.handheld.HandheldRenderer.truth` gives it.
    Videos of ``kind`` other than "normal" have no monitor: every cursor is false.
    For "normal" videos, by the truth (``visible``: whole white squares in the picture,
    ``on_screen``: the image centre's ray meets the lit area):

    - ``all4``: on screen, four visible; ``predicted``: on screen, two or three visible;
      errors are the cursor's distance from the truth (both unclamped);
    - ``off_screen``: the camera aims past the screen's edge with two or more visible;
      the sinks pin the cursor to the edge, so the error is between the cursor and the
      truth both clamped to the screen;
    - ``hold``: one or none visible: a cursor is a violation unless two landmark
      centres are still inside the picture (a disc of a cut square can be tracked);
      then it counts as ``predicted`` (on screen) or ``off_screen``.

    ``cursor_rate``: frames with a cursor among on-screen frames with two or more
    visible. ``gross_errors``: cursors more than :data:`GROSS_PX` off (any class).
    """
    if len(cursors) != len(truth):
        raise ValueError(f"{len(cursors)} cursors for {len(truth)} truth frames")
    out = VideoErrors(kind)
    w, h = screen_px
    for c, t in zip(cursors, truth, strict=True):
        if kind != "normal" or t["screen_xy"] is None:
            if c is not None:
                out.false_cursors += 1
            continue
        nv = sum(bool(v) for v in t["visible"])
        on = bool(t["on_screen"])
        if nv <= 1:
            cls = "hold"
            if sum(bool(v) for v in t.get("centre_inside", [])) >= 2:
                cls = "predicted" if on else "off_screen"
            elif c is not None:
                out.hold_violations += 1
        elif not on:
            cls = "off_screen"
        else:
            cls = "all4" if nv == 4 else "predicted"
        out.frames[cls] = out.frames.get(cls, 0) + 1
        if on and nv >= 2:
            out.want_cursor += 1
            out.have_cursor += c is not None
        if c is None or cls == "hold":
            continue
        out.cursors[cls] = out.cursors.get(cls, 0) + 1
        if cls == "off_screen":
            a, b = _clamp01(c), _clamp01(t["screen_xy"])
            err = cursor_error_px(a, b, screen_px)
        else:
            err = cursor_error_px(c, t["screen_xy"], screen_px)
        out.errors.setdefault(cls, []).append(err)
        out.gross += err > GROSS_PX
    del w, h
    return out


def pooled_summary(
    videos: Sequence[Mapping[str, Any]], errors: Sequence[VideoErrors]
) -> dict[str, Any]:
    """Pooled figures over videos: ``videos[i]`` holds ``seed`` and ``size`` (w, h),
    ``errors[i]`` its :class:`VideoErrors` (one tracker configuration).

    Cameras 640 px wide or more and 320x240 ones are reported apart; per class the
    pooled RMS / p95 / max over all frames, the share of videos whose all-four RMS is
    within 2 px (4 px at 320x240), the cursor rate, false cursors, hold violations and
    the worst videos (largest all-four and predicted RMS) with their seeds.
    """
    groups: dict[str, list[int]] = {"640+": [], "320x240": [], "other": []}
    for i, v in enumerate(videos):
        wv = int(v["size"][0])
        key = "640+" if wv >= 640 else "320x240" if wv == 320 else "other"
        groups[key].append(i)
    out: dict[str, Any] = {}
    for key, idx in groups.items():
        normal = [i for i in idx if errors[i].kind == "normal"]
        if not idx:
            continue
        g: dict[str, Any] = {"videos": len(idx), "normal_videos": len(normal)}
        bound = 2.0 if key == "640+" else 4.0
        for c in ("all4", "predicted", "off_screen"):
            pooled = [e for i in normal for e in errors[i].errors.get(c, [])]
            g[c] = _stats(pooled)
        per_video = [
            float(np.sqrt(np.mean(np.square(errors[i].errors["all4"]))))
            for i in normal
            if errors[i].errors.get("all4")
        ]
        g["all4_video_rms_bound_px"] = bound
        g["all4_videos_within_bound"] = (
            round(float(np.mean(np.asarray(per_video) <= bound)), 4) if per_video else None
        )
        g["all4_video_rms_p50_p95_max"] = (
            [round(float(np.percentile(per_video, q)), 3) for q in (50, 95, 100)]
            if per_video
            else None
        )
        want = sum(errors[i].want_cursor for i in normal)
        have = sum(errors[i].have_cursor for i in normal)
        g["cursor_rate"] = round(have / want, 4) if want else None
        g["frames_wanting_cursor"] = want
        g["hold_violations"] = sum(errors[i].hold_violations for i in normal)
        g["gross_errors"] = sum(errors[i].gross for i in normal)
        neg = [i for i in idx if errors[i].kind != "normal"]
        g["negative_videos"] = {
            k: sum(1 for i in neg if errors[i].kind == k) for k in ("no-monitor", "lookalikes")
        }
        g["false_cursors"] = {
            k: sum(errors[i].false_cursors for i in neg if errors[i].kind == k)
            for k in ("no-monitor", "lookalikes")
        }
        g["false_cursors_in_normal_videos"] = sum(errors[i].false_cursors for i in normal)

        def worst(cls: str, normal: list[int] = normal) -> list[dict[str, Any]]:
            rows = []
            for i in normal:
                e = errors[i].errors.get(cls)
                if e:
                    rows.append(
                        {
                            "seed": videos[i]["seed"],
                            "size": list(videos[i]["size"]),
                            "rms_px": round(float(np.sqrt(np.mean(np.square(e)))), 3),
                            "max_px": round(float(np.max(e)), 3),
                            "frames": len(e),
                        }
                    )
            return sorted(rows, key=lambda r: -r["rms_px"])[:5]

        g["worst_all4"] = worst("all4")
        g["worst_predicted"] = worst("predicted")
        low_rate = sorted(
            (
                {
                    "seed": videos[i]["seed"],
                    "cursor_rate": round(errors[i].have_cursor / errors[i].want_cursor, 3),
                }
                for i in normal
                if errors[i].want_cursor
            ),
            key=lambda r: r["cursor_rate"],
        )[:5]
        g["worst_cursor_rate"] = low_rate
        g["worst_false"] = [
            {
                "seed": videos[i]["seed"],
                "kind": errors[i].kind,
                "false_cursors": errors[i].false_cursors,
            }
            for i in sorted(neg, key=lambda i: -errors[i].false_cursors)[:5]
            if errors[i].false_cursors
        ]
        out[key] = g
    return out

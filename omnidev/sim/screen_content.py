"""What the screen shows in the laser fixtures, and where the laser spot goes.

- :func:`slide`: presentation content at screen resolution (BGR uint8): text
  slides, photos, charts, bright white pages, dark slides, each with small
  bright red and green details (bullets, icons) that are not a laser spot, and
  an animated element so consecutive frames differ.
- :func:`laser_path`: a recorded-looking hand path of the spot in screen
  pixels: smooth minimum-jerk moves, pauses with hand tremor, jumps, stretches
  with the laser off (at least 12 % of the frames), targets near the border.

Everything is deterministic from the seed. Screen pixels: x right, y down,
centre of the top-left pixel (0, 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

SLIDE_KINDS = ("text", "photo", "chart", "white", "dark")
_WORDS = (
    "camera",
    "screen",
    "laser",
    "calibration",
    "pointer",
    "image",
    "dot",
    "matrix",
    "border",
    "polygon",
    "threshold",
    "template",
    "grid",
    "distortion",
    "barrel",
    "lens",
    "spot",
    "detection",
    "frame",
    "presentation",
    "results",
    "method",
    "accuracy",
    "pixel",
    "cell",
    "region",
)
RED, GREEN = (0, 0, 255), (0, 255, 0)


def _text_lines(img: NDArray[np.uint8], rng: np.random.Generator, colour: tuple[int, ...]) -> None:
    """Bulleted lines of words; bullets are small saturated red/green discs (6-9 px)."""
    h = img.shape[0]
    s = h / 1080
    y = int(300 * s)
    while y < h - 80 * s:
        x0 = int(150 * s)
        bullet = RED if rng.random() < 0.5 else GREEN
        cv2.circle(img, (x0 - int(40 * s), y - int(14 * s)), max(2, int(7 * s)), bullet, -1)
        words = " ".join(rng.choice(_WORDS, int(rng.integers(3, 8))))
        scale = 1.6 * s * float(rng.uniform(0.8, 1.1))
        cv2.putText(
            img,
            words,
            (x0, y),
            cv2.FONT_HERSHEY_SIMPLEX,
            scale,
            colour,
            max(1, int(3 * s)),
            cv2.LINE_AA,
        )
        if rng.random() < 0.3:  # a red or green word underlined
            cv2.line(img, (x0, y + int(10 * s)), (x0 + int(300 * s), y + int(10 * s)), bullet, 3)
        y += int(rng.uniform(80, 120) * s)


@lru_cache(maxsize=16)
def _base_slide(kind: str, width: int, height: int, seed: int) -> NDArray[np.uint8]:
    rng = np.random.default_rng([seed, SLIDE_KINDS.index(kind), 77])
    s = height / 1080
    img = np.full((height, width, 3), 255, np.uint8)
    if kind == "text":
        cv2.rectangle(img, (0, 0), (width, int(180 * s)), (120, 60, 20), -1)
        cv2.putText(
            img,
            "Results",
            (int(80 * s), int(125 * s)),
            cv2.FONT_HERSHEY_DUPLEX,
            3.0 * s,
            (255, 255, 255),
            max(1, int(5 * s)),
            cv2.LINE_AA,
        )
        _text_lines(img, rng, (30, 30, 30))
    elif kind == "photo":
        small = rng.uniform(0, 255, (6, 10, 3)).astype(np.float32)
        photo = cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)
        tex = cv2.resize(
            rng.normal(0, 10, (height // 12, width // 12, 3)).astype(np.float32),
            (width, height),
            interpolation=cv2.INTER_LINEAR,
        )
        photo = photo + tex
        for _ in range(6):  # bright highlights (sky, lamps, snow)
            c = (int(rng.uniform(0, width)), int(rng.uniform(0, height)))
            ax = (int(rng.uniform(40, 220) * s), int(rng.uniform(30, 150) * s))
            cv2.ellipse(photo, c, ax, float(rng.uniform(0, 180)), 0, 360, (255, 255, 255), -1)
        for col in (RED, GREEN):  # saturated small regions (a red flower, a green sign)
            c = (int(rng.uniform(100, width - 100)), int(rng.uniform(100, height - 100)))
            cv2.circle(photo, c, int(rng.uniform(8, 40) * s), col, -1)
        img = np.clip(cv2.GaussianBlur(photo, (0, 0), 1.2), 0, 255).astype(np.uint8)
    elif kind == "chart":
        cv2.putText(
            img,
            "Error by method",
            (int(80 * s), int(120 * s)),
            cv2.FONT_HERSHEY_SIMPLEX,
            2.2 * s,
            (0, 0, 0),
            max(1, int(4 * s)),
            cv2.LINE_AA,
        )
        base = int(950 * s)
        cv2.line(img, (int(120 * s), base), (width - int(120 * s), base), (0, 0, 0), 3)
        for i in range(8):
            col = (RED, GREEN, (200, 80, 0), (0, 140, 255))[i % 4]
            x0 = int((180 + i * 200) * s)
            top = base - int(rng.uniform(150, 650) * s)
            cv2.rectangle(img, (x0, top), (x0 + int(120 * s), base), col, -1)
        cv2.circle(img, (width - int(250 * s), int(300 * s)), int(150 * s), RED, -1)
        cv2.ellipse(
            img, (width - int(250 * s), int(300 * s)), (int(150 * s),) * 2, 0, 0, 130, GREEN, -1
        )
    elif kind == "white":
        cv2.putText(
            img,
            "Questions?",
            (int(700 * s), int(560 * s)),
            cv2.FONT_HERSHEY_SIMPLEX,
            2.0 * s,
            (60, 60, 60),
            max(1, int(3 * s)),
            cv2.LINE_AA,
        )
        for col, x in ((RED, 660), (GREEN, 1190)):
            cv2.circle(img, (int(x * s), int(540 * s)), max(2, int(6 * s)), col, -1)
    elif kind == "dark":
        img[:] = (60, 25, 10)
        _text_lines(img, rng, (255, 255, 255))
        for _ in range(12):  # small bright icons, laser-sized
            c = (int(rng.uniform(40, width - 40)), int(rng.uniform(40, height - 40)))
            col = RED if rng.random() < 0.5 else GREEN
            cv2.circle(img, c, max(2, int(rng.uniform(4, 9) * s)), col, -1)
    else:
        raise ValueError(f"unknown slide kind {kind!r} ({', '.join(SLIDE_KINDS)})")
    out: NDArray[np.uint8] = np.ascontiguousarray(img)
    out.setflags(write=False)
    return out


def slide(kind: str, width: int, height: int, t: float, seed: int = 0) -> NDArray[np.uint8]:
    """Slide ``kind`` at time ``t`` (s): BGR uint8 ``height x width``.

    The animated element: a red ball (radius 40 screen px at 1080 lines,
    display-bright, not saturated on the camera) moving along a loop, and a
    green dot of laser size blinking at 2 Hz.
    """
    img = _base_slide(kind, width, height, seed).copy()
    s = height / 1080
    bx = width * (0.5 + 0.3 * math.sin(0.9 * t + seed))
    by = height * (0.75 + 0.1 * math.sin(1.7 * t))
    cv2.circle(img, (int(bx), int(by)), int(40 * s), (40, 40, 230), -1, cv2.LINE_AA)
    if int(t * 4) % 2 == 0:
        cv2.circle(img, (int(width * 0.92), int(height * 0.08)), max(2, int(6 * s)), GREEN, -1)
    return img


@dataclass(frozen=True)
class PathPoint:
    """The spot in one frame: screen px and relative power."""

    x: float
    y: float
    power: float


def _tremor(rng: np.random.Generator, frames: int, fps: float, amp: float) -> NDArray[np.float64]:
    """Hand tremor (frames, 2) in px: a few sinusoids 3-11 Hz with random phases."""
    t = np.arange(frames) / fps
    out = np.zeros((frames, 2))
    for _ in range(4):
        f = rng.uniform(3.0, 11.0)
        out += amp / 2 * np.sin(2 * np.pi * f * t[:, None] + rng.uniform(0, 2 * np.pi, 2))
    return out


def laser_path(
    frames: int, width: int, height: int, *, fps: float = 30.0, seed: int = 0
) -> list[PathPoint | None]:
    """Where the spot is in each frame (screen px), or None while the laser is off.

    Segments: move (minimum-jerk, 0.25-1.0 s), hold (0.2-0.8 s), jump (the next
    frame elsewhere), off (0.15-0.5 s). A fifth of the targets lie 4-20 px from
    the screen border (the second target always does). At least 12 % of the
    frames (and at least one) have no spot.
    """
    rng = np.random.default_rng([seed, 5150])

    def target(near_border: bool) -> NDArray[np.float64]:
        if near_border:
            d = rng.uniform(4.0, 20.0)
            side = int(rng.integers(4))
            x = rng.uniform(d, width - 1 - d)
            y = rng.uniform(d, height - 1 - d)
            if side == 0:
                return np.array([d, y])
            if side == 1:
                return np.array([width - 1 - d, y])
            if side == 2:
                return np.array([x, d])
            return np.array([x, height - 1 - d])
        return np.array([rng.uniform(30, width - 31), rng.uniform(30, height - 31)])

    pos = target(False)
    out: list[PathPoint | None] = []
    n_targets = 0
    while len(out) < frames:
        kind = rng.choice(["move", "hold", "jump", "off"], p=[0.45, 0.25, 0.1, 0.2])
        if kind in ("move", "jump"):
            n_targets += 1
            q = target(n_targets == 2 or rng.random() < 0.2)
            if kind == "jump":
                pos = q
                continue
            n = max(2, int(rng.uniform(0.25, 1.0) * fps))
            tau = np.arange(1, n + 1) / n
            s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
            for k in range(n):
                p = pos + (q - pos) * s[k]
                out.append(PathPoint(float(p[0]), float(p[1]), 1.0))
            pos = q
        elif kind == "hold":
            for _ in range(max(1, int(rng.uniform(0.2, 0.8) * fps))):
                out.append(PathPoint(float(pos[0]), float(pos[1]), 1.0))
        else:
            out.extend([None] * max(1, int(rng.uniform(0.15, 0.5) * fps)))
            pos = target(rng.random() < 0.2)
    out = out[:frames]
    # at least 12 % off: switch the laser off for short stretches until it is
    need = max(1, math.ceil(0.12 * frames))
    while sum(p is None for p in out) < need:
        k = int(rng.integers(frames))
        for j in range(k, min(frames, k + int(rng.integers(3, 9)))):
            out[j] = None
    trem = _tremor(rng, frames, fps, 1.2)
    power = 1.0 + 0.15 * np.sin(2 * np.pi * 0.7 * np.arange(frames) / fps + rng.uniform(0, 6))
    result: list[PathPoint | None] = []
    for i, p in enumerate(out):
        if p is None:
            result.append(None)
            continue
        x = float(np.clip(p.x + trem[i, 0], 2.0, width - 3.0))
        y = float(np.clip(p.y + trem[i, 1], 2.0, height - 3.0))
        result.append(PathPoint(x, y, float(power[i])))
    return result

"""Textures of the randomized hand-held camera-mouse world (:mod:`omnidev.sim.handheld`).

Everything here is drawn from a ``numpy.random.Generator`` and returned as float32
*linear* radiance in [0, 1] (BGR), so that the renderer can light, expose and
gamma-encode it like a camera:

- :func:`screen_content`: what the monitor shows (emissive): a desktop with windows,
  title bars with dark round buttons, text (black on white and white on dark), a
  full-screen document, a dark theme, a slide, a photo, saturated colour blocks,
  a video region (its pan source returned apart so frames differ), and landmark
  look-alikes (black discs on white squares) on the screen.
- :func:`room_texture`: the wall behind the monitor (reflective): paint, posters,
  picture frames, shelves, a window, and look-alike cards in the room.
- :func:`lookalike`: a black disc on a white square drawn onto a texture.

Texture coordinates: texel (0, 0) is the centre of the top-left texel; ``px_per_m``
texels per metre along both axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.sim.screen_content import SLIDE_KINDS, slide

F32 = NDArray[np.float32]

SCREEN_KINDS = ("desktop", "document", "dark", "slide", "photo", "saturated", "video")
_WORDS = (
    "camera",
    "mouse",
    "window",
    "landmark",
    "the",
    "screen",
    "of",
    "file",
    "edit",
    "view",
    "tracking",
    "and",
    "cursor",
    "frame",
    "report",
    "results",
    "border",
    "disc",
)


def to_linear(bgr_u8: NDArray[np.uint8]) -> F32:
    """sRGB-ish uint8 (gamma 2.2) -> linear float32 in [0, 1]."""
    out: F32 = np.power(bgr_u8.astype(np.float32) / 255.0, np.float32(2.2))
    return out


def lookalike(
    tex: F32,
    centre: tuple[float, float],
    disc_d: float,
    square: float,
    *,
    white: float = 0.85,
    black: float = 0.03,
    angle_deg: float = 0.0,
) -> None:
    """Draw a black disc (diameter ``disc_d`` texels) on a white square (side ``square``
    texels, turned by ``angle_deg``) centred at ``centre`` (texels), in place."""
    sh = 4
    cx, cy = centre
    box = cv2.boxPoints(((cx, cy), (square, square), angle_deg))
    cv2.fillPoly(
        tex, [np.round(box * (1 << sh)).astype(np.int32)], (white,) * 3, cv2.LINE_AA, shift=sh
    )
    cv2.circle(
        tex,
        (round(cx * (1 << sh)), round(cy * (1 << sh))),
        round(disc_d / 2 * (1 << sh)),
        (black,) * 3,
        -1,
        cv2.LINE_AA,
        sh,
    )


def _text(
    img: NDArray[np.uint8],
    rng: np.random.Generator,
    box: tuple[int, int, int, int],
    colour: tuple[int, int, int],
    line_px: float,
) -> None:
    """Lines of words (cap height ~ ``line_px`` / 2) filling ``box`` = (x0, y0, x1, y1)."""
    x0, y0, x1, y1 = box
    scale = max(0.25, line_px / 45.0)
    thick = max(1, round(line_px / 18))
    y = y0 + line_px
    while y < y1 - line_px * 0.3:
        x = x0 + int(rng.uniform(0.0, 0.05) * (x1 - x0))
        if rng.random() < 0.25:  # a bullet: a small dark (or coloured) disc
            col = colour if rng.random() < 0.6 else tuple(int(c) for c in rng.integers(0, 255, 3))
            cv2.circle(img, (x, int(y - line_px / 4)), max(1, int(line_px / 6)), col, -1)
            x += int(line_px * 0.6)
        words = " ".join(rng.choice(_WORDS, int(rng.integers(2, 9))))
        cv2.putText(img, words, (x, int(y)), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thick, 16)
        y += line_px * float(rng.uniform(1.0, 1.6))


def _photo(rng: np.random.Generator, w: int, h: int) -> NDArray[np.uint8]:
    """A smooth photo-like picture with a few highlights and shadows (BGR uint8)."""
    small = rng.uniform(0, 255, (int(rng.integers(3, 8)), int(rng.integers(4, 10)), 3))
    img: F32 = np.asarray(
        cv2.resize(small.astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC), np.float32
    )
    fine = rng.normal(0, 14, (max(2, h // 10), max(2, w // 10), 3)).astype(np.float32)
    img += np.asarray(cv2.resize(fine, (w, h), interpolation=cv2.INTER_LINEAR), np.float32)
    for _ in range(int(rng.integers(2, 7))):
        c = (int(rng.uniform(0, w)), int(rng.uniform(0, h)))
        ax = (max(1, int(rng.uniform(0.03, 0.2) * w)), max(1, int(rng.uniform(0.03, 0.2) * h)))
        col = (255.0,) * 3 if rng.random() < 0.5 else (float(rng.uniform(0, 40)),) * 3
        cv2.ellipse(img, c, ax, float(rng.uniform(0, 180)), 0, 360, col, -1, cv2.LINE_AA)
    out: NDArray[np.uint8] = np.clip(img, 0, 255).astype(np.uint8)
    return out


def _window(
    img: NDArray[np.uint8],
    rng: np.random.Generator,
    box: tuple[int, int, int, int],
    dark_theme: bool,
    unit: float,
) -> None:
    """A window: title bar with round buttons (dark or coloured discs), a body of text,
    a picture or a table."""
    x0, y0, x1, y1 = box
    body = (30, 30, 34) if dark_theme else (250, 250, 250)
    ink = (220, 220, 220) if dark_theme else (20, 20, 20)
    cv2.rectangle(img, (x0, y0), (x1, y1), body, -1)
    bar_h = max(3, int(30 * unit))
    bar = tuple(int(c) for c in rng.integers(40, 90, 3)) if dark_theme else (225, 225, 228)
    if rng.random() < 0.3:
        bar = tuple(int(c) for c in rng.integers(0, 255, 3))
    cv2.rectangle(img, (x0, y0), (x1, y0 + bar_h), bar, -1)
    r = max(1, int(bar_h * 0.3))
    for k in range(3):
        col = (20, 20, 20) if rng.random() < 0.5 else tuple(int(c) for c in rng.integers(0, 255, 3))
        cx = (
            x0 + int(bar_h * (0.6 + 0.9 * k))
            if rng.random() < 0.6
            else x1 - int(bar_h * (0.6 + 0.9 * k))
        )
        cv2.circle(img, (cx, y0 + bar_h // 2), r, col, -1, cv2.LINE_AA)
    cv2.rectangle(img, (x0, y0), (x1, y1), (90, 90, 90), max(1, int(unit)))
    inner = (
        x0 + int(12 * unit),
        y0 + bar_h + int(8 * unit),
        x1 - int(12 * unit),
        y1 - int(6 * unit),
    )
    if inner[2] <= inner[0] + 4 or inner[3] <= inner[1] + 4:
        return
    what = rng.choice(["text", "text", "picture", "table"])
    if what == "text":
        _text(img, rng, inner, ink, float(rng.uniform(18, 40) * unit))
    elif what == "picture":
        w, h = inner[2] - inner[0], inner[3] - inner[1]
        img[inner[1] : inner[3], inner[0] : inner[2]] = _photo(rng, w, h)
    else:
        step = max(4, int(rng.uniform(25, 50) * unit))
        for y in range(inner[1], inner[3], step):
            cv2.line(img, (inner[0], y), (inner[2], y), (128, 128, 128), 1)
        for x in np.linspace(inner[0], inner[2], int(rng.integers(3, 7))):
            cv2.line(img, (int(x), inner[1]), (int(x), inner[3]), (128, 128, 128), 1)


@dataclass(frozen=True)
class ScreenContent:
    """What the screen shows: a static picture and a moving video region.

    ``base``: (h, w, 3) linear float32; ``video_box``: (x0, y0, x1, y1) texels of the
    region that plays video (or None); ``video_source``: a larger linear picture panned
    across that region over time at ``video_speed`` (texels/s, x and y); ``kind``.
    """

    kind: str
    base: F32
    video_box: tuple[int, int, int, int] | None
    video_source: F32 | None
    video_speed: tuple[float, float]
    lookalikes: int


def screen_content(
    rng: np.random.Generator,
    width: int,
    height: int,
    *,
    kind: str,
    lookalike_texels: tuple[float, float] | None = None,
    lookalikes: int = 0,
) -> ScreenContent:
    """Screen content ``kind`` (SCREEN_KINDS) at ``width`` x ``height`` texels.

    ``lookalikes`` black discs on white squares (disc diameter and square side
    ``lookalike_texels``, each scaled by 0.7-1.4) are drawn on top.
    """
    unit = height / 1080.0  # texels per screen pixel of a 1080-line desktop
    img: NDArray[np.uint8]
    video_box: tuple[int, int, int, int] | None = None
    if kind == "desktop" or kind == "dark":
        dark = kind == "dark" or rng.random() < 0.25
        img = (
            _photo(rng, width, height)
            if rng.random() < 0.6
            else np.full((height, width, 3), rng.integers(20, 200, 3).astype(np.uint8), np.uint8)
        )
        bar_h = max(2, int(rng.uniform(30, 48) * unit))
        bar_col = (20, 20, 24) if dark or rng.random() < 0.5 else (235, 235, 235)
        if rng.random() < 0.8:
            y0 = height - bar_h if rng.random() < 0.7 else 0
            cv2.rectangle(img, (0, y0), (width, y0 + bar_h), bar_col, -1)
        for _ in range(int(rng.integers(1, 5))):
            w = int(rng.uniform(0.2, 0.8) * width)
            h = int(rng.uniform(0.2, 0.8) * height)
            x0 = int(rng.uniform(-0.05, 1.0) * (width - w))
            y0 = int(rng.uniform(0.0, 1.0) * (height - h))
            _window(img, rng, (x0, y0, x0 + w, y0 + h), dark, unit)
        if rng.random() < 0.5:  # a window playing a video
            w = int(rng.uniform(0.15, 0.45) * width)
            h = int(w * 9 / 16)
            x0 = int(rng.uniform(0, width - w))
            y0 = int(rng.uniform(0, height - h))
            video_box = (x0, y0, x0 + w, y0 + h)
    elif kind == "document":
        img = np.full((height, width, 3), 250, np.uint8)
        m = int(rng.uniform(0.0, 0.2) * width)
        if m:
            img[:, :m] = img[:, width - m :] = rng.integers(60, 140)
        _text(img, rng, (m + int(40 * unit), int(30 * unit), width - m - int(40 * unit), height),
              (15, 15, 15), float(rng.uniform(20, 45) * unit))  # fmt: skip
    elif kind == "slide":
        k = str(rng.choice(SLIDE_KINDS))
        # omnidev.sim.screen_content's slides need 200 px each way: a smaller texture
        # (a small screen far away) is drawn at 200 px and scaled down
        up = max(1.0, 200 / min(width, height))
        big = (math.ceil(width * up), math.ceil(height * up))
        drawn: NDArray[Any] = slide(k, big[0], big[1], 0.0, int(rng.integers(1 << 30)))
        if up > 1:
            drawn = cv2.resize(drawn, (width, height), interpolation=cv2.INTER_AREA)
        img = np.ascontiguousarray(drawn, np.uint8)
    elif kind == "photo":
        img = _photo(rng, width, height)
    elif kind == "saturated":
        img = np.zeros((height, width, 3), np.uint8)
        cols = [(0, 0, 255), (0, 255, 0), (255, 0, 0), (0, 255, 255), (255, 0, 255),
                (255, 255, 0), (0, 0, 0), (255, 255, 255)]  # fmt: skip
        for _ in range(int(rng.integers(6, 18))):
            x0, y0 = int(rng.uniform(0, width)), int(rng.uniform(0, height))
            w, h = int(rng.uniform(0.1, 0.5) * width), int(rng.uniform(0.1, 0.5) * height)
            cv2.rectangle(img, (x0, y0), (x0 + w, y0 + h), cols[int(rng.integers(len(cols)))], -1)
    elif kind == "video":
        img = np.zeros((height, width, 3), np.uint8)
        video_box = (0, 0, width, height)
    else:
        raise ValueError(f"unknown screen content {kind!r} ({', '.join(SCREEN_KINDS)})")
    base = to_linear(img)
    if lookalikes and lookalike_texels is not None:
        dt, st = lookalike_texels
        for _ in range(lookalikes):
            sc = float(rng.uniform(0.7, 1.4))
            c = (float(rng.uniform(0.05, 0.95) * width), float(rng.uniform(0.05, 0.95) * height))
            lookalike(base, c, dt * sc, st * sc, white=0.9, black=0.01,
                      angle_deg=float(rng.uniform(-10, 10)))  # fmt: skip
    src: F32 | None = None
    speed = (0.0, 0.0)
    if video_box is not None:
        w, h = video_box[2] - video_box[0], video_box[3] - video_box[1]
        src = to_linear(_photo(rng, 3 * w, 3 * h))
        ang = rng.uniform(0, 2 * math.pi)
        v = float(rng.uniform(0.1, 0.6)) * w
        speed = (v * math.cos(ang), v * math.sin(ang))
    return ScreenContent(kind, base, video_box, src, speed, lookalikes)


def video_frame(content: ScreenContent, t: float) -> F32 | None:
    """The video region's picture at time ``t`` (s), or None when there is none: a crop
    panned across ``video_source`` (bouncing at its ends), brightness flickering."""
    if content.video_box is None or content.video_source is None:
        return None
    x0, y0, x1, y1 = content.video_box
    w, h = x1 - x0, y1 - y0
    sh, sw = content.video_source.shape[:2]

    def bounce(p: float, span: int) -> int:
        if span <= 0:
            return 0
        q = p % (2 * span)
        return int(q if q <= span else 2 * span - q)

    ox = bounce(content.video_speed[0] * t + sw / 3, sw - w)
    oy = bounce(content.video_speed[1] * t + sh / 3, sh - h)
    crop = content.video_source[oy : oy + h, ox : ox + w]
    out: F32 = crop * np.float32(0.85 + 0.15 * math.sin(3.1 * t))
    return out


def room_texture(
    rng: np.random.Generator,
    width: int,
    height: int,
    px_per_m: float,
    *,
    lookalike_m: tuple[float, float],
    lookalikes: int,
    lookalike_rect: tuple[float, float, float, float] | None = None,
) -> F32:
    """The wall (reflectance, linear BGR float32 (height, width, 3)) at ``px_per_m``.

    Paint with a low-frequency variation, posters and framed pictures (with text),
    shelves, a window, and ``lookalikes`` black-disc-on-white-square cards (disc
    and square sizes ``lookalike_m`` in m, each scaled 0.7-1.5). When
    ``lookalike_rect`` = (x0, y0, x1, y1) texels is given, four of the cards sit on
    that rectangle's corners (a group shaped like a layout of landmarks).
    """
    paint = rng.uniform(0.25, 0.8) * rng.uniform(0.8, 1.0, 3)
    low = rng.normal(0, 1, (6, 8, 3)).astype(np.float32)
    tex = cv2.resize(low, (width, height), interpolation=cv2.INTER_CUBIC) * 0.04 + paint.astype(
        np.float32
    )
    grain = rng.normal(0, 0.015, (max(2, height // 3), max(2, width // 3), 3)).astype(np.float32)
    tex += cv2.resize(grain, (width, height), interpolation=cv2.INTER_LINEAR)
    m = px_per_m
    for _ in range(int(rng.integers(3, 9))):  # posters and framed pictures
        w, h = rng.uniform(0.2, 0.9) * m, rng.uniform(0.2, 0.7) * m
        lo, hi = (0.25, 0.75) if rng.random() < 0.6 else (-0.1, 1.0)  # near the monitor
        x0, y0 = rng.uniform(lo, hi) * width - w / 2, rng.uniform(lo, hi) * height - h / 2
        p0 = (int(x0), int(y0))
        p1 = (int(x0 + w), int(y0 + h))
        if rng.random() < 0.5:
            cv2.rectangle(tex, p0, p1, (float(rng.uniform(0.02, 0.5)),) * 3, -1)
            f = int(max(2, rng.uniform(0.01, 0.04) * m))
            q0, q1 = (p0[0] + f, p0[1] + f), (p1[0] - f, p1[1] - f)
        else:
            q0, q1 = p0, p1
        if q1[0] - q0[0] > 8 and q1[1] - q0[1] > 8:
            sub = _photo(rng, q1[0] - q0[0], q1[1] - q0[1])
            if rng.random() < 0.4:
                sub[:] = 235
                _text(sub, rng, (4, 4, sub.shape[1] - 4, sub.shape[0]), (20, 20, 20),
                      float(rng.uniform(0.02, 0.06) * m))  # fmt: skip
            ys, xs = max(0, q0[1]), max(0, q0[0])
            ye, xe = min(height, q1[1]), min(width, q1[0])
            if ye > ys and xe > xs:
                tex[ys:ye, xs:xe] = 0.8 * to_linear(
                    sub[ys - q0[1] : ye - q0[1], xs - q0[0] : xe - q0[0]]
                )
    if rng.random() < 0.5:  # a shelf: a dark band with objects on it
        y = int(rng.uniform(0.1, 0.9) * height)
        cv2.rectangle(tex, (0, y), (width, y + int(0.03 * m)), (0.05, 0.05, 0.06), -1)
        for _ in range(int(rng.integers(2, 8))):
            x = int(rng.uniform(0, width))
            bw, bh = int(rng.uniform(0.03, 0.2) * m), int(rng.uniform(0.05, 0.3) * m)
            col = tuple(float(c) for c in rng.uniform(0.02, 0.8, 3))
            cv2.rectangle(tex, (x, y - bh), (x + bw, y), col, -1)
    if rng.random() < 0.3:  # a bright window
        x0, y0 = int(rng.uniform(0, 0.8) * width), int(rng.uniform(0, 0.6) * height)
        cv2.rectangle(tex, (x0, y0), (x0 + int(0.8 * m), y0 + int(1.0 * m)), (1.0,) * 3, -1)
        cv2.rectangle(tex, (x0, y0), (x0 + int(0.8 * m), y0 + int(1.0 * m)), (0.1,) * 3,
                      max(1, int(0.03 * m)))  # fmt: skip
    d, s = lookalike_m[0] * m, lookalike_m[1] * m
    placed = 0
    if lookalike_rect is not None:
        x0, y0, x1, y1 = lookalike_rect
        for c in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
            lookalike(tex, c, d, s, angle_deg=float(rng.uniform(-5, 5)))
            placed += 1
    for _ in range(max(0, lookalikes - placed)):
        k = float(rng.uniform(0.7, 1.5))
        c = (float(rng.uniform(0, width)), float(rng.uniform(0, height)))
        lookalike(tex, c, d * k, s * k, angle_deg=float(rng.uniform(-20, 20)))
    out: F32 = np.clip(tex, 0.0, 1.0)
    return out

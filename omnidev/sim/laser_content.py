"""What the screen shows in the randomized laser scenes: slides and desktops full of
things that look like a laser spot.

:class:`LaserSlide` draws one slide of a class (:data:`SLIDE_CLASSES`):

- ``dark``: a dark background (black, navy, dark grey) with white, grey and
  coloured text;
- ``white``: a white or light-grey page with black, grey and red text;
- ``saturated``: a fully saturated background (red, yellow, green, blue,
  magenta, cyan, orange; the laser's own colour included) with white and black
  text.

Every slide also holds, at seeded places and sizes, the look-alikes a laser
detector must not take for the spot: saturated red, yellow, white and green
patches and discs from laser size (3 screen px) up to 80 px, red (or green) text
in the laser's colour, desktop windows (white body, title bar, a red close
button of laser size, a yellow highlight bar), and optionally a video window whose
content moves every frame (bright discs of the laser's colour, yellow and white
moving over a changing texture) plus a small bright blob drifting across the slide.

Content is display values (BGR uint8) at screen resolution; the renderer turns them
into light through the display's gamma. Deterministic from the seed. Screen pixels:
x right, y down, centre of the top-left pixel (0, 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

SLIDE_CLASSES = ("dark", "white", "saturated")
_SATURATED = {  # BGR display values
    "red": (0, 0, 255),
    "yellow": (0, 255, 255),
    "green": (0, 255, 0),
    "blue": (255, 0, 0),
    "magenta": (255, 0, 255),
    "cyan": (255, 255, 0),
    "orange": (0, 140, 255),
}
_WHITE = (255, 255, 255)
_LASER_BGR = {"red": (0, 0, 255), "green": (0, 255, 0)}
_WORDS = [
    "laser",
    "pointer",
    "screen",
    "camera",
    "results",
    "method",
    "pixel",
    "error",
    "slide",
    "frame",
    "window",
    "detection",
    "spot",
    "colour",
    "channel",
    "exposure",
    "bloom",
    "compression",
    "calibration",
    "border",
]
_FONTS = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_TRIPLEX)


@dataclass
class _Mover:
    """A disc moving in a box: centre (x0, y0) + amplitude * sin(2 pi f t + phase)."""

    x0: float
    y0: float
    ax: float
    ay: float
    fx: float
    fy: float
    px: float
    py: float
    radius: float
    colour: tuple[int, int, int]

    def at(self, t: float) -> tuple[int, int]:
        return (
            round(self.x0 + self.ax * math.sin(2 * math.pi * self.fx * t + self.px)),
            round(self.y0 + self.ay * math.sin(2 * math.pi * self.fy * t + self.py)),
        )


@dataclass
class LaserSlide:
    """One slide: a static picture plus the parts that move (see the module docstring).

    Args:
        slide_class: one of :data:`SLIDE_CLASSES`.
        width, height: screen resolution, px.
        laser: the laser's colour ("red" or "green"): look-alikes of that colour.
        seed: everything drawn from it.
        video: whether the slide holds a video window (content changing every frame).
    """

    slide_class: str
    width: int
    height: int
    laser: str = "red"
    seed: int = 0
    video: bool = False
    base: NDArray[np.uint8] = field(init=False, repr=False)
    video_rect: tuple[int, int, int, int] | None = field(init=False, default=None)
    _movers: list[_Mover] = field(init=False, default_factory=list, repr=False)
    _drifter: _Mover | None = field(init=False, default=None, repr=False)
    _video_tex: NDArray[np.uint8] | None = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        if self.slide_class not in SLIDE_CLASSES:
            raise ValueError(f"slide class {self.slide_class!r}: one of {', '.join(SLIDE_CLASSES)}")
        if self.laser not in _LASER_BGR:
            raise ValueError(f"laser colour {self.laser!r}: 'red' or 'green'")
        rng = np.random.default_rng([self.seed, 4711, SLIDE_CLASSES.index(self.slide_class)])
        self.base = self._draw_base(rng)
        if self.video:
            self._setup_video(rng)
        self._setup_drifter(rng)

    # -- static content --------------------------------------------------------
    def _draw_base(self, rng: np.random.Generator) -> NDArray[np.uint8]:
        W, H = self.width, self.height
        s = H / 1080
        laser_bgr = _LASER_BGR[self.laser]
        if self.slide_class == "dark":
            bg = [(0, 0, 0), (60, 25, 10), (40, 40, 40), (30, 10, 30)][int(rng.integers(4))]
            ink = [_WHITE, (200, 200, 200), (0, 220, 255)]
        elif self.slide_class == "white":
            bg = [_WHITE, (235, 235, 235), (245, 250, 255)][int(rng.integers(3))]
            ink = [(0, 0, 0), (60, 60, 60), (120, 60, 20)]
        else:
            names = list(_SATURATED)
            # the laser's own colour as the background on a third of these slides
            name = self.laser if rng.random() < 0.33 else names[int(rng.integers(len(names)))]
            bg = _SATURATED[name]
            ink = [_WHITE, (0, 0, 0)]
        img = np.empty((H, W, 3), np.uint8)
        img[:] = bg
        # a title and lines of text, some in the laser's colour
        y = int(rng.uniform(90, 160) * s)
        cv2.putText(
            img, "Laser results", (int(80 * s), y), _FONTS[1], 2.6 * s,
            ink[0], max(1, int(5 * s)), cv2.LINE_AA,
        )  # fmt: skip
        y += int(rng.uniform(90, 130) * s)
        while y < H - 60 * s:
            colour = laser_bgr if rng.random() < 0.3 else ink[int(rng.integers(len(ink)))]
            words = " ".join(rng.choice(_WORDS, int(rng.integers(3, 9))))
            scale = float(rng.uniform(0.6, 1.8)) * s
            cv2.putText(
                img, words, (int(rng.uniform(60, 300) * s), y), _FONTS[int(rng.integers(3))],
                scale, colour, max(1, int(rng.uniform(1, 4) * s)), cv2.LINE_AA,
            )  # fmt: skip
            y += int(rng.uniform(45, 110) * s)
        # desktop windows: white body, title bar, red close button, yellow highlight
        for _ in range(int(rng.integers(0, 3))):
            w = int(rng.uniform(0.2, 0.45) * W)
            h = int(rng.uniform(0.2, 0.45) * H)
            x0, y0 = int(rng.uniform(0, W - w)), int(rng.uniform(0, H - h))
            cv2.rectangle(img, (x0, y0), (x0 + w, y0 + h), (250, 250, 250), -1)
            tb = max(6, int(28 * s))
            cv2.rectangle(img, (x0, y0), (x0 + w, y0 + tb), (150, 90, 40), -1)
            cv2.circle(img, (x0 + w - tb // 2, y0 + tb // 2), max(2, tb // 3), (40, 40, 235), -1)
            cv2.rectangle(
                img, (x0 + w // 8, y0 + h // 2), (x0 + w // 2, y0 + h // 2 + tb // 2),
                (0, 255, 255), -1,
            )  # fmt: skip
            for k in range(3):
                cv2.putText(
                    img, " ".join(rng.choice(_WORDS, 3)),
                    (x0 + int(10 * s), y0 + tb + int((30 + 30 * k) * s)), _FONTS[0], 0.8 * s,
                    (0, 0, 0) if k else laser_bgr, max(1, int(2 * s)), cv2.LINE_AA,
                )  # fmt: skip
        # saturated patches and discs: the laser's colour, yellow, white, the other laser
        palette = [laser_bgr, laser_bgr, (0, 255, 255), _WHITE, (0, 255, 0), (0, 0, 255)]
        for _ in range(int(rng.integers(8, 20))):
            colour = palette[int(rng.integers(len(palette)))]
            size = float(np.exp(rng.uniform(math.log(3), math.log(80)))) * s
            c = (int(rng.uniform(0, W)), int(rng.uniform(0, H)))
            if rng.random() < 0.5:
                cv2.circle(img, c, max(1, int(size / 2)), colour, -1, cv2.LINE_AA)
            else:
                a = max(1, int(size * rng.uniform(0.5, 2.0)))
                b = max(1, int(size))
                cv2.rectangle(img, c, (c[0] + a, c[1] + b), colour, -1)
        return img

    def _setup_video(self, rng: np.random.Generator) -> None:
        W, H = self.width, self.height
        w, h = int(rng.uniform(0.22, 0.4) * W), int(rng.uniform(0.22, 0.4) * H)
        x0, y0 = int(rng.uniform(0, W - w)), int(rng.uniform(0, H - h))
        self.video_rect = (x0, y0, w, h)
        small = rng.uniform(0, 255, (9, 14, 3)).astype(np.float32)
        self._video_tex = np.clip(
            cv2.resize(small, (2 * w, h), interpolation=cv2.INTER_CUBIC), 0, 255
        ).astype(np.uint8)
        laser_bgr = _LASER_BGR[self.laser]
        for k in range(int(rng.integers(3, 7))):
            colour = (laser_bgr, (0, 255, 255), _WHITE)[k % 3]
            self._movers.append(
                _Mover(
                    w / 2,
                    h / 2,
                    w * rng.uniform(0.2, 0.45),
                    h * rng.uniform(0.2, 0.45),
                    rng.uniform(0.2, 1.2),
                    rng.uniform(0.2, 1.2),
                    rng.uniform(0, 6.3),
                    rng.uniform(0, 6.3),
                    float(np.exp(rng.uniform(math.log(2), math.log(30)))),
                    colour,
                )
            )

    def _setup_drifter(self, rng: np.random.Generator) -> None:
        W, H = self.width, self.height
        if rng.random() < 0.5:
            colour = (_LASER_BGR[self.laser], (0, 255, 255), _WHITE)[int(rng.integers(3))]
            self._drifter = _Mover(
                W / 2, H / 2, W * 0.4, H * 0.4, rng.uniform(0.05, 0.3), rng.uniform(0.05, 0.3),
                rng.uniform(0, 6.3), rng.uniform(0, 6.3), rng.uniform(2, 8) * H / 1080, colour,
            )  # fmt: skip

    # -- per frame -------------------------------------------------------------
    @property
    def animated(self) -> bool:
        """Whether the content changes from frame to frame."""
        return self.video_rect is not None or self._drifter is not None

    def changed_boxes(self, t: float) -> list[tuple[int, int, int, int]]:
        """Screen boxes (x0, y0, x1, y1), exclusive ends, where :meth:`frame` may differ
        from :attr:`base` at time ``t``."""
        out: list[tuple[int, int, int, int]] = []
        if self.video_rect is not None:
            x0, y0, w, h = self.video_rect
            out.append((x0, y0, x0 + w, y0 + h))
        if self._drifter is not None:
            x, y = self._drifter.at(t)
            r = round(self._drifter.radius) + 2
            out.append(
                (
                    max(0, x - r),
                    max(0, y - r),
                    min(self.width, x + r + 1),
                    min(self.height, y + r + 1),
                )
            )
        return out

    def frame(self, t: float) -> NDArray[np.uint8]:
        """The slide at time ``t`` (s): BGR uint8 ``height x width``."""
        if not self.animated:
            return self.base
        img = self.base.copy()
        if self.video_rect is not None and self._video_tex is not None:
            x0, y0, w, h = self.video_rect
            shift = int(t * 40) % w
            tex = self._video_tex[:, shift : shift + w].astype(np.float32)
            flicker = 0.85 + 0.15 * math.sin(2 * math.pi * 0.7 * t)
            view = np.clip(tex * flicker, 0, 255).astype(np.uint8)
            for m in self._movers:
                cv2.circle(view, m.at(t), max(1, round(m.radius)), m.colour, -1, cv2.LINE_AA)
            img[y0 : y0 + h, x0 : x0 + w] = view
        if self._drifter is not None:
            d = self._drifter
            cv2.circle(img, d.at(t), max(1, round(d.radius)), d.colour, -1, cv2.LINE_AA)
        return img

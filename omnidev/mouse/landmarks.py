"""Camera-mouse landmarks (dissertation sec. 6.2): a black circle at the center of a white square.

:class:`LandmarkLayout` describes where the four landmarks sit on the monitor's frame:
the screen's size in mm and, per corner, the landmark center's offset from that screen
corner, in the monitor plane (mm, x right, y down). :func:`draw_landmark` and
:func:`draw_landmark_sheet` return the printable images (uint8, 255 = white) at a given
DPI; writing them to PNG/PDF is the CLI's business.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import ConfigError

CORNERS = ("tl", "tr", "br", "bl")
"""Corner names in the order used everywhere in :mod:`omnidev.mouse`."""

MM_PER_INCH = 25.4
_PREFIX = "camera-mouse landmarks"


@dataclass(frozen=True)
class LandmarkLayout:
    """The four landmarks on a monitor's frame and the screen they surround.

    Attributes:
        screen_width_mm, screen_height_mm: the visible screen area (mm).
        offsets_mm: per corner (TL, TR, BR, BL) the landmark center minus the screen corner,
            in the monitor plane (mm, x right, y down). Landmarks outside the screen have
            e.g. TL offset (-dx, -dy) and BR offset (+dx, +dy).
        circle_diameter_mm: diameter of the black circle (mm).
        square_side_mm: side of the white square around it (mm).

    Example:
        >>> layout = LandmarkLayout.symmetric(520.0, 292.5, margin_mm=(30.0, 30.0))
        >>> round(layout.aspect_ratio, 4)
        1.7778
        >>> layout.landmark_centers_mm()[2].tolist()
        [550.0, 322.5]
    """

    screen_width_mm: float
    screen_height_mm: float
    offsets_mm: tuple[tuple[float, float], ...]
    circle_diameter_mm: float = 20.0
    square_side_mm: float = 30.0

    def __post_init__(self) -> None:
        _positive("screen_width_mm", self.screen_width_mm)
        _positive("screen_height_mm", self.screen_height_mm)
        _positive("circle_diameter_mm", self.circle_diameter_mm)
        _positive("square_side_mm", self.square_side_mm)
        if self.circle_diameter_mm >= self.square_side_mm:
            raise ConfigError(
                f"{_PREFIX}: circle_diameter_mm ({self.circle_diameter_mm}) must be smaller "
                f"than square_side_mm ({self.square_side_mm})"
            )
        if len(self.offsets_mm) != 4:
            raise ConfigError(f"{_PREFIX}: offsets_mm needs 4 corners {CORNERS}")
        for name, off in zip(CORNERS, self.offsets_mm, strict=True):
            if len(off) != 2 or not all(math.isfinite(float(v)) for v in off):
                raise ConfigError(f"{_PREFIX}: offsets_mm.{name} must be two finite numbers (mm)")
        c = self.landmark_centers_mm()
        # The landmark quadrilateral must be convex with the corners in clockwise order
        # (y down): every cross product of consecutive edges positive.
        for i in range(4):
            e1 = c[(i + 1) % 4] - c[i]
            e2 = c[(i + 2) % 4] - c[(i + 1) % 4]
            if e1[0] * e2[1] - e1[1] * e2[0] <= 0:
                raise ConfigError(
                    f"{_PREFIX}: offsets_mm.{CORNERS[(i + 1) % 4]} makes the landmark "
                    "quadrilateral non-convex or out of TL, TR, BR, BL order"
                )

    @classmethod
    def symmetric(
        cls,
        screen_width_mm: float,
        screen_height_mm: float,
        *,
        margin_mm: tuple[float, float],
        circle_diameter_mm: float = 20.0,
        square_side_mm: float = 30.0,
    ) -> LandmarkLayout:
        """Landmarks ``margin_mm`` = (x, y) mm outside each screen corner."""
        mx, my = margin_mm
        return cls(
            screen_width_mm,
            screen_height_mm,
            ((-mx, -my), (mx, -my), (mx, my), (-mx, my)),
            circle_diameter_mm,
            square_side_mm,
        )

    @property
    def aspect_ratio(self) -> float:
        """Screen width over height."""
        return self.screen_width_mm / self.screen_height_mm

    def screen_corners_mm(self) -> NDArray[np.float64]:
        """(4, 2) screen corners TL, TR, BR, BL in the monitor plane (mm)."""
        w, h = self.screen_width_mm, self.screen_height_mm
        return np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])

    def landmark_centers_mm(self) -> NDArray[np.float64]:
        """(4, 2) landmark centers TL, TR, BR, BL in the monitor plane (mm)."""
        return self.screen_corners_mm() + np.asarray(self.offsets_mm, dtype=np.float64)

    def landmark_aspect_ratio(self) -> float:
        """Width over height of the landmark quadrilateral, as R of sec. 6.2.1 step 4c."""
        c = self.landmark_centers_mm()
        d = np.linalg.norm(c - np.roll(c, -1, axis=0), axis=1)  # |C1C2|, |C2C3|, |C3C4|, |C4C1|
        return float((d[0] + d[2]) / (d[1] + d[3]))

    def to_dict(self) -> dict[str, Any]:
        """A plain dict (TOML/JSON-ready) that :meth:`from_dict` reads back."""
        return {
            "screen_width_mm": self.screen_width_mm,
            "screen_height_mm": self.screen_height_mm,
            "circle_diameter_mm": self.circle_diameter_mm,
            "square_side_mm": self.square_side_mm,
            "offsets_mm": {
                n: [float(o[0]), float(o[1])] for n, o in zip(CORNERS, self.offsets_mm, strict=True)
            },
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LandmarkLayout:
        """Read :meth:`to_dict`'s form; a :class:`ConfigError` names the bad or missing key."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{_PREFIX}: expected a table, got {type(data).__name__}")
        known = {
            "screen_width_mm",
            "screen_height_mm",
            "circle_diameter_mm",
            "square_side_mm",
            "offsets_mm",
        }
        for key in data:
            if key not in known:
                raise ConfigError(f"{_PREFIX}: unknown key {key!r} (known: {sorted(known)})")
        for key in ("screen_width_mm", "screen_height_mm", "offsets_mm"):
            if key not in data:
                raise ConfigError(f"{_PREFIX}: missing key {key!r}")
        offsets = data["offsets_mm"]
        if not isinstance(offsets, Mapping):
            raise ConfigError(f"{_PREFIX}: offsets_mm must be a table with keys {CORNERS}")
        for key in offsets:
            if key not in CORNERS:
                raise ConfigError(f"{_PREFIX}: unknown key 'offsets_mm.{key}' (known: {CORNERS})")
        parsed: list[tuple[float, float]] = []
        for name in CORNERS:
            if name not in offsets:
                raise ConfigError(f"{_PREFIX}: missing key 'offsets_mm.{name}'")
            v = offsets[name]
            if isinstance(v, str | bytes) or not hasattr(v, "__len__") or len(v) != 2:
                raise ConfigError(f"{_PREFIX}: offsets_mm.{name} must be [x, y] in mm, got {v!r}")
            parsed.append(
                (_number(f"offsets_mm.{name}[0]", v[0]), _number(f"offsets_mm.{name}[1]", v[1]))
            )
        kwargs: dict[str, float] = {}
        for key in ("circle_diameter_mm", "square_side_mm"):
            if key in data:
                kwargs[key] = _number(key, data[key])
        return cls(
            _number("screen_width_mm", data["screen_width_mm"]),
            _number("screen_height_mm", data["screen_height_mm"]),
            tuple(parsed),
            **kwargs,
        )


def _number(key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{_PREFIX}: {key} must be a number (mm), got {value!r}")
    if not math.isfinite(float(value)):
        raise ConfigError(f"{_PREFIX}: {key} must be finite, got {value!r}")
    return float(value)


def _positive(key: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise ConfigError(f"{_PREFIX}: {key} must be a positive number (mm), got {value!r}")


def mm_to_px(mm: float, dpi: float) -> float:
    """Length in printer pixels of ``mm`` millimetres at ``dpi`` dots per inch."""
    return mm * dpi / MM_PER_INCH


def draw_landmark(
    *, circle_diameter_mm: float, square_side_mm: float, dpi: float = 300.0, supersample: int = 4
) -> NDArray[np.uint8]:
    """One landmark: a white square ``square_side_mm`` wide with a centered black circle.

    Returns an (n, n) uint8 image (255 white, 0 black), n = round(square side at ``dpi``);
    circle edge pixels are grey in proportion to their covered area (``supersample``^2
    samples per pixel), so the printed circle has its true size to a fraction of a dot.

    Example:
        >>> img = draw_landmark(circle_diameter_mm=20.0, square_side_mm=30.0, dpi=254)
        >>> img.shape, int(img[150, 150]), int(img[0, 0])
        ((300, 300), 0, 255)
    """
    _positive("circle_diameter_mm", circle_diameter_mm)
    _positive("square_side_mm", square_side_mm)
    if circle_diameter_mm >= square_side_mm:
        raise ConfigError(f"{_PREFIX}: circle_diameter_mm must be smaller than square_side_mm")
    n = max(1, round(mm_to_px(square_side_mm, dpi)))
    r = mm_to_px(circle_diameter_mm, dpi) / 2.0
    s = int(supersample)
    # Sample positions inside each pixel, pixel centers at integer + 0.5 from the edge.
    sub = (np.arange(n * s, dtype=np.float64) + 0.5) / s - n / 2.0
    inside = (sub[:, None] ** 2 + sub[None, :] ** 2) <= r * r
    cover = inside.reshape(n, s, n, s).mean(axis=(1, 3))
    return np.asarray(np.round(255.0 * (1.0 - cover)), dtype=np.uint8)


def draw_landmark_sheet(
    layout: LandmarkLayout,
    *,
    dpi: float = 300.0,
    paper_mm: tuple[float, float] = (210.0, 297.0),
) -> NDArray[np.uint8]:
    """A printable page (portrait ``paper_mm`` = (width, height), uint8, 255 white) with the
    four landmarks of ``layout`` in a 2x2 grid, each labelled with its corner and outlined
    by a thin grey cut line, plus a 100 mm scale bar to check the print's true size.

    Raises ConfigError when the four landmarks do not fit on the paper.
    """
    pw, ph = (round(mm_to_px(v, dpi)) for v in paper_mm)
    side = mm_to_px(layout.square_side_mm, dpi)
    margin = mm_to_px(15.0, dpi)
    need = 2 * side + 3 * margin
    if need > pw or need + mm_to_px(30.0, dpi) > ph:
        raise ConfigError(
            f"{_PREFIX}: square_side_mm {layout.square_side_mm} does not fit four landmarks "
            f"on a {paper_mm[0]}x{paper_mm[1]} mm page"
        )
    page = np.full((ph, pw), 255, np.uint8)
    tile = draw_landmark(
        circle_diameter_mm=layout.circle_diameter_mm,
        square_side_mm=layout.square_side_mm,
        dpi=dpi,
    )
    n = tile.shape[0]
    font_scale = max(0.5, dpi / 150.0)
    thick = max(1, round(dpi / 150.0))
    for k, name in enumerate(CORNERS):
        col, row = (0, 1, 1, 0)[k], (0, 0, 1, 1)[k]
        x0 = round(margin + col * (side + margin))
        y0 = round(margin + row * (side + margin) + mm_to_px(10.0, dpi))
        page[y0 : y0 + n, x0 : x0 + n] = tile
        cv2.rectangle(page, (x0 - 1, y0 - 1), (x0 + n, y0 + n), 160, 1)
        cv2.putText(
            page,
            name.upper(),
            (x0, y0 - round(mm_to_px(2.0, dpi))),
            cv2.FONT_HERSHEY_SIMPLEX,
            font_scale,
            0,
            thick,
            cv2.LINE_AA,
        )
    # 100 mm scale bar along the bottom.
    yb = ph - round(mm_to_px(15.0, dpi))
    xb = round(margin)
    cv2.line(page, (xb, yb), (xb + round(mm_to_px(100.0, dpi)), yb), 0, thick)
    return page

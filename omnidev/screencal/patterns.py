"""The three calibration patterns of dissertation sec. 5.2 (Fig. 5.1), for any screen size.

Fig. 5.1: (a) a white rectangle, (b) a black rectangle, (c) "a matrix of white
dots on a black rectangular shape". The dissertation does not give the dot
layout in numbers. Any rows x columns and margins are accepted
(:func:`dot_grid`); the default layout fixes it so that the N x N dots and the screen
border cut the screen into (N + 1) x (N + 1) equal cells (sec. 5.2.3: the N x N
dots plus the extended dot centres on the border make an (N + 2) x (N + 2)
grid with (N + 1) x (N + 1) basic regions inside the screen):

- spacing ``W / (N + 1)`` across and ``H / (N + 1)`` down; the margin from
  the screen's edge to the outer dots equals the spacing;
- dot radius ``0.2 * min(W, H) / (N + 1)`` unless given (21.6 px on a
  1920 x 1080 screen with N = 9), large enough to stay several camera pixels
  wide when the screen fills a 640 x 480 picture.

Coordinates are screen pixels (x right, y down) with the centre of the
top-left pixel at (0, 0); the screen's lit area spans [-0.5, W - 0.5] x
[-0.5, H - 0.5]. Dots are antialiased (their pixel values are the covered
fraction of each pixel, from 8 x 8 sub-samples), so each dot's grey-value
centroid is its centre.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

Polarity = Literal["white", "black"]
_AA = 8  # sub-samples per pixel side for the dots' coverage


def _check_size(width: int, height: int) -> None:
    if width < 16 or height < 16:
        raise ValueError(f"screen size {width}x{height}: at least 16x16 px")


def white_pattern(width: int, height: int) -> NDArray[np.uint8]:
    """The white-rectangle pattern (Fig. 5.1a): ``height x width``, all 255."""
    _check_size(width, height)
    return np.full((height, width), 255, np.uint8)


def black_pattern(width: int, height: int) -> NDArray[np.uint8]:
    """The black-rectangle pattern (Fig. 5.1b): ``height x width``, all 0."""
    _check_size(width, height)
    return np.zeros((height, width), np.uint8)


@dataclass(frozen=True)
class DotGrid:
    """Where the dots of :func:`dot_pattern` are, in screen pixels: the dot layout.

    ``rows`` x ``cols`` dots; ``centers`` is (rows*cols, 2) float (x, y),
    row-major from the top-left dot: index ``row * cols + col``.
    ``spacing_px`` is (sx, sy) between neighbouring dots; ``margin_px`` (mx, my)
    from the screen's edge (x = -0.5, y = -0.5) to the outer dots' centres.
    ``polarity`` is the dots' colour: ``"white"`` on black (the dissertation's)
    or ``"black"`` on white. ``n`` is ``rows`` for a square grid.
    """

    rows: int
    centers: NDArray[np.float64]
    radius_px: float
    spacing_px: tuple[float, float] = (0.0, 0.0)
    polarity: Polarity = "white"
    screen_px: tuple[int, int] = (0, 0)
    cols: int = 0
    margin_px: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if self.cols == 0:
            object.__setattr__(self, "cols", self.rows)

    @property
    def n(self) -> int:
        """Dots per row and column of a square grid (ValueError for rows != cols)."""
        if self.rows != self.cols:
            raise ValueError(f"a {self.rows} x {self.cols} dot grid has no single n")
        return self.rows

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return self.rows, self.cols

    @property
    def count(self) -> int:
        """rows * cols."""
        return self.rows * self.cols

    def grid(self) -> NDArray[np.float64]:
        """The centres as (rows, cols, 2): ``grid()[row, col] = (x, y)``."""
        out: NDArray[np.float64] = self.centers.reshape(self.rows, self.cols, 2)
        return out

    def describe(self) -> str:
        """``9 x 9 dots, margin 192.0 x 108.0 px, radius 21.6 px`` (rows x columns)."""
        mx, my = self.margin_px
        return (
            f"{self.rows} x {self.cols} dots, margin {mx:.1f} x {my:.1f} px, "
            f"radius {self.radius_px:.1f} px"
        )

    def to_dict(self) -> dict[str, object]:
        """The layout as written to layout.json (see :func:`layout_from_dict`)."""
        return {
            "kind": "screen-dot-layout",
            "screen": list(self.screen_px),
            "rows": self.rows,
            "cols": self.cols,
            "margin_px": list(self.margin_px),
            "radius_px": self.radius_px,
            "polarity": self.polarity,
            "conventions": "screen px, centre of the top-left pixel = (0, 0); margin from the "
            "screen edge (-0.5) to the outer dot centres",
        }


def layout_from_dict(d: Mapping[str, Any], where: str = "layout") -> DotGrid:
    """The DotGrid a :meth:`DotGrid.to_dict` document describes; errors name the key."""
    try:
        w, h = (int(v) for v in d["screen"])
        rows, cols = int(d["rows"]), int(d["cols"])
        mx, my = (float(v) for v in d["margin_px"])
        radius = float(d["radius_px"])
        polarity = str(d.get("polarity", "white"))
    except KeyError as exc:
        raise ValueError(f"{where}: missing key {exc.args[0]!r}") from None
    except (TypeError, ValueError):
        raise ValueError(
            f"{where}: screen, rows, cols, margin_px, radius_px must be numbers"
        ) from None
    if polarity not in ("white", "black"):
        raise ValueError(f"{where}: polarity {polarity!r}: 'white' or 'black'")
    g = dot_grid(w, h, rows=rows, cols=cols, margin_px=(mx, my), radius_px=radius)
    return replace(g, polarity=polarity)  # type: ignore[arg-type]


def dot_grid(
    width: int,
    height: int,
    n: int = 9,
    radius_px: float | None = None,
    *,
    rows: int | None = None,
    cols: int | None = None,
    margin: float | tuple[float, float] | None = None,
    margin_px: tuple[float, float] | None = None,
) -> DotGrid:
    """The dot layout of :func:`dot_pattern` without drawing it.

    ``rows`` x ``cols`` dots (default ``n`` x ``n``). The outer dots' centres
    sit ``margin`` (a fraction of the screen's width and height, one number or
    (x, y)) or ``margin_px`` (screen px) from the screen's edge; by default
    one dot spacing (the dissertation-style layout: the dots and the border
    cut the screen into (cols + 1) x (rows + 1) equal cells). Radius default:
    ``0.2 * min(spacing)``.

    Example:
        >>> g = dot_grid(1920, 1080, 9)
        >>> g.centers[0].tolist(), g.centers[-1].tolist(), round(g.radius_px, 2)
        ([191.5, 107.5], [1727.5, 971.5], 21.6)
        >>> g = dot_grid(1920, 1080, rows=7, cols=7, margin=0.05)
        >>> g.centers[0].tolist(), g.shape
        ([95.5, 53.5], (7, 7))
    """
    _check_size(width, height)
    rows = n if rows is None else int(rows)
    cols = n if cols is None else int(cols)
    if rows < 2 or cols < 2:
        raise ValueError(f"dot matrix {rows} x {cols}: at least 2 x 2 dots")
    if margin_px is not None:
        mx, my = float(margin_px[0]), float(margin_px[1])
    elif margin is not None:
        fx, fy = (margin, margin) if isinstance(margin, int | float) else margin
        if not (0.0 <= fx < 0.5 and 0.0 <= fy < 0.5):
            raise ValueError(f"dot margin {fx:g}, {fy:g}: fractions of the screen in [0, 0.5)")
        mx, my = fx * width, fy * height
    else:
        mx, my = width / (cols + 1), height / (rows + 1)
    sx, sy = (width - 2 * mx) / (cols - 1), (height - 2 * my) / (rows - 1)
    if sx <= 0 or sy <= 0:
        raise ValueError(f"dot margin {mx:g} x {my:g} px leaves no room on {width}x{height}")
    r = 0.2 * min(sx, sy) if radius_px is None else float(radius_px)
    if not 0.5 <= r < 0.5 * min(sx, sy):
        raise ValueError(
            f"dot radius {r:g} px: must be >= 0.5 and less than half the spacing "
            f"({0.5 * min(sx, sy):g} px for {rows} x {cols} dots on {width}x{height})"
        )
    if r > min(mx, my) + 0.5:
        raise ValueError(f"dot radius {r:g} px: the outer dots would cross the screen's edge")
    xs = mx + sx * np.arange(cols) - 0.5
    ys = my + sy * np.arange(rows) - 0.5
    xx, yy = np.meshgrid(xs, ys)
    centers = np.stack([xx.ravel(), yy.ravel()], axis=1).astype(np.float64)
    return DotGrid(rows, centers, r, (sx, sy), "white", (width, height), cols, (mx, my))


def disc_coverage(
    x: float, y: float, radius: float, shape: tuple[int, int]
) -> tuple[slice, slice, NDArray[np.float64]]:
    """The fraction (0..1) of each pixel covered by a disc, in its bounding window.

    Args:
        x, y: disc centre, pixels (centre of the top-left pixel = (0, 0)).
        radius: pixels.
        shape: (H, W) of the image the window is clipped to.

    Returns:
        (rows, cols, coverage): the window's slices and its coverage (h, w),
        from 8 x 8 sub-samples per pixel.
    """
    h, w = shape
    r0, r1 = max(int(np.floor(y - radius)) - 1, 0), min(int(np.ceil(y + radius)) + 2, h)
    c0, c1 = max(int(np.floor(x - radius)) - 1, 0), min(int(np.ceil(x + radius)) + 2, w)
    off = (np.arange(_AA) + 0.5) / _AA - 0.5
    ys = (np.arange(r0, r1)[:, None] + off[None, :]).ravel() - y
    xs = (np.arange(c0, c1)[:, None] + off[None, :]).ravel() - x
    inside = (ys[:, None] ** 2 + xs[None, :] ** 2) <= radius * radius
    cov = inside.reshape(r1 - r0, _AA, c1 - c0, _AA).mean(axis=(1, 3))
    return slice(r0, r1), slice(c0, c1), cov


def dot_pattern(
    width: int,
    height: int,
    n: int = 9,
    radius_px: float | None = None,
    *,
    polarity: Polarity = "white",
    layout: DotGrid | None = None,
) -> tuple[NDArray[np.uint8], DotGrid]:
    """The dot-matrix pattern (Fig. 5.1c) and where its dots are.

    Args:
        width, height: screen size, pixels.
        n: dots per row and per column (when no ``layout``).
        radius_px: dot radius in screen pixels; default ``0.2 * min(spacing)``.
        polarity: ``"white"`` dots on black (the dissertation's, default) or
            ``"black"`` dots on white.
        layout: any :func:`dot_grid` layout (rows x columns, margins, radius);
            its polarity is replaced by ``polarity``.

    Returns:
        (image, grid): ``height x width`` uint8, antialiased; the dot layout.

    Example:
        >>> img, g = dot_pattern(1920, 1080)
        >>> img.shape, int(img[108, 192]), int(img[0, 0]), g.n
        ((1080, 1920), 255, 0, 9)
    """
    if polarity not in ("white", "black"):
        raise ValueError(f"polarity {polarity!r}: 'white' or 'black'")
    g = dot_grid(width, height, n, radius_px) if layout is None else layout
    if g.screen_px != (width, height):
        raise ValueError(f"dot layout for {g.screen_px}, screen is {(width, height)}")
    g = replace(g, polarity=polarity)
    cov = np.zeros((height, width), np.float64)
    for x, y in g.centers:
        rows, cols, c = disc_coverage(float(x), float(y), g.radius_px, (height, width))
        cov[rows, cols] = np.maximum(cov[rows, cols], c)
    if polarity == "black":
        cov = 1.0 - cov
    img: NDArray[np.uint8] = np.round(cov * 255.0).astype(np.uint8)
    return img, g

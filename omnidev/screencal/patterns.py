"""The three calibration patterns of dissertation sec. 5.2 (Fig. 5.1), for any screen size.

Fig. 5.1: (a) a white rectangle, (b) a black rectangle, (c) "a matrix of white
dots on a black rectangular shape". The dissertation does not give the dot
layout in numbers; this module fixes it so that the N x N dots and the screen
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

from dataclasses import dataclass
from typing import Literal

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
    """Where the dots of :func:`dot_pattern` are, in screen pixels.

    ``centers`` is (n*n, 2) float (x, y), row-major from the top-left dot:
    index ``row * n + col``. ``spacing_px`` is (sx, sy) between neighbouring
    dots (also the margin from the screen edge to the outer dots). ``polarity``
    is the dots' colour: ``"white"`` on black (the dissertation's) or
    ``"black"`` on white.
    """

    n: int
    centers: NDArray[np.float64]
    radius_px: float
    spacing_px: tuple[float, float] = (0.0, 0.0)
    polarity: Polarity = "white"
    screen_px: tuple[int, int] = (0, 0)

    def grid(self) -> NDArray[np.float64]:
        """The centres as (n, n, 2): ``grid()[row, col] = (x, y)``."""
        out: NDArray[np.float64] = self.centers.reshape(self.n, self.n, 2)
        return out


def dot_grid(width: int, height: int, n: int = 9, radius_px: float | None = None) -> DotGrid:
    """The dot layout of :func:`dot_pattern` without drawing it.

    Example:
        >>> g = dot_grid(1920, 1080, 9)
        >>> g.centers[0].tolist(), g.centers[-1].tolist(), round(g.radius_px, 2)
        ([191.5, 107.5], [1727.5, 971.5], 21.6)
    """
    _check_size(width, height)
    if n < 2:
        raise ValueError(f"dot matrix n = {n}: at least 2 x 2 dots")
    sx, sy = width / (n + 1), height / (n + 1)
    r = 0.2 * min(sx, sy) if radius_px is None else float(radius_px)
    if not 0.5 <= r < 0.5 * min(sx, sy):
        raise ValueError(
            f"dot radius {r:g} px: must be >= 0.5 and less than half the spacing "
            f"({0.5 * min(sx, sy):g} px for {n} x {n} dots on {width}x{height})"
        )
    xs = sx * np.arange(1, n + 1) - 0.5
    ys = sy * np.arange(1, n + 1) - 0.5
    xx, yy = np.meshgrid(xs, ys)
    centers = np.stack([xx.ravel(), yy.ravel()], axis=1).astype(np.float64)
    return DotGrid(n, centers, r, (sx, sy), "white", (width, height))


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
) -> tuple[NDArray[np.uint8], DotGrid]:
    """The dot-matrix pattern (Fig. 5.1c) and where its dots are.

    Args:
        width, height: screen size, pixels.
        n: dots per row and per column.
        radius_px: dot radius in screen pixels; default ``0.2 * min(spacing)``.
        polarity: ``"white"`` dots on black (the dissertation's, default) or
            ``"black"`` dots on white.

    Returns:
        (image, grid): ``height x width`` uint8, antialiased; the dot layout.

    Example:
        >>> img, g = dot_pattern(1920, 1080)
        >>> img.shape, int(img[108, 192]), int(img[0, 0]), g.n
        ((1080, 1920), 255, 0, 9)
    """
    if polarity not in ("white", "black"):
        raise ValueError(f"polarity {polarity!r}: 'white' or 'black'")
    g = dot_grid(width, height, n, radius_px)
    g = DotGrid(g.n, g.centers, g.radius_px, g.spacing_px, polarity, g.screen_px)
    cov = np.zeros((height, width), np.float64)
    for x, y in g.centers:
        rows, cols, c = disc_coverage(float(x), float(y), g.radius_px, (height, width))
        cov[rows, cols] = np.maximum(cov[rows, cols], c)
    if polarity == "black":
        cov = 1.0 - cov
    img: NDArray[np.uint8] = np.round(cov * 255.0).astype(np.uint8)
    return img, g

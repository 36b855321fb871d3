"""Extended dot centres and the (N+2) x (N+2) landmark grid (sec. 5.2.2c, 5.2.3).

The extended dot centre of a dot row (column) is where the line through its first
two dots, extended outwards, meets the border polygon (Fig. 5.11); the polygon's
corner vertices P0, P2, P4, P6 close the grid's corners. Image points are image
pixels (u right, v down), screen points screen pixels (x right, y down), both with
the top-left pixel centre at (0, 0); the screen's edge is at -0.5 and W - 0.5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.screencal.features import BorderPolygon

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LandmarkGrid:
    """The (N+2) x (N+2) landmark grid: ``image[i, j]`` (image px) and ``screen[i, j]``
    (screen px) of row i, column j; row 0 / N+1 and column 0 / N+1 are the extended
    dot centres on the screen border, the corners the polygon's corner vertices."""

    image: FloatArray
    screen: FloatArray


def ray_polygon(origin: FloatArray, direction: FloatArray, border: BorderPolygon) -> FloatArray:
    """The first point where the ray origin + t * direction (t > 0) crosses a polygon side."""
    best_t = np.inf
    for i in range(8):
        a, b = border.side(i)
        e = b - a
        m = np.array([[direction[0], -e[0]], [direction[1], -e[1]]])
        det = float(np.linalg.det(m))
        if abs(det) < 1e-12:
            continue
        t, s = np.linalg.solve(m, a - origin)
        if t > 1e-9 and -1e-9 <= s <= 1 + 1e-9 and t < best_t:
            best_t = float(t)
    if not np.isfinite(best_t):
        raise CalibrationError("screen border polygon not closed around the dots")
    return np.asarray(origin + best_t * direction, np.float64)


def landmark_grid(
    dots_image: FloatArray,
    dots_screen: FloatArray,
    border: BorderPolygon,
    screen_size: tuple[int, int],
) -> LandmarkGrid:
    """Build the (R+2) x (C+2) grid from (R, C, 2) dot centres (no NaN) and the border.

    Left/right extensions use each row's first/last two dots, top/bottom each column's
    (Fig. 5.11); their screen coordinates lie on the screen edge (x = -0.5 or W - 0.5,
    y = -0.5 or H - 0.5) at the row's (column's) dot coordinate.
    """
    rows, cols = dots_image.shape[:2]
    sw, sh = screen_size
    img = np.full((rows + 2, cols + 2, 2), np.nan)
    scr = np.full((rows + 2, cols + 2, 2), np.nan)
    img[1:-1, 1:-1] = dots_image
    scr[1:-1, 1:-1] = dots_screen
    for k in range(rows):
        row = dots_image[k]
        img[k + 1, 0] = ray_polygon(row[0], row[0] - row[1], border)
        img[k + 1, -1] = ray_polygon(row[-1], row[-1] - row[-2], border)
        scr[k + 1, 0] = (-0.5, dots_screen[k, 0, 1])
        scr[k + 1, -1] = (sw - 0.5, dots_screen[k, -1, 1])
    for k in range(cols):
        col = dots_image[:, k]
        img[0, k + 1] = ray_polygon(col[0], col[0] - col[1], border)
        img[-1, k + 1] = ray_polygon(col[-1], col[-1] - col[-2], border)
        scr[0, k + 1] = (dots_screen[0, k, 0], -0.5)
        scr[-1, k + 1] = (dots_screen[-1, k, 0], sh - 0.5)
    v = border.vertices
    img[0, 0], img[0, -1], img[-1, -1], img[-1, 0] = v[0], v[2], v[4], v[6]
    scr[0, 0], scr[0, -1] = (-0.5, -0.5), (sw - 0.5, -0.5)
    scr[-1, -1], scr[-1, 0] = (sw - 0.5, sh - 0.5), (-0.5, sh - 0.5)
    return LandmarkGrid(img, scr)

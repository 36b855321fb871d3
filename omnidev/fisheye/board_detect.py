"""Chessboard corners in strongly distorted images (fisheye and catadioptric omni-images).

:func:`detect_chessboard` tries, in order, until one finds the whole board and the grid passes
:func:`grid_problem`:

1. ``sb``: ``cv2.findChessboardCornersSB`` (``NORMALIZE_IMAGE | EXHAUSTIVE | ACCURACY``);
2. ``classic``: ``cv2.findChessboardCorners`` (adaptive threshold, quads linked into a grid);
3. ``grow``: :func:`omnidev.fisheye.board_grow.grow_grid`, a grid grown from saddle points
   (X-junctions of the board's edges) by local prediction, which needs no straight rows:
   from a seed cell, every next corner is predicted from its grid neighbours (linear or
   quadratic extrapolation along a row or column, or the parallelogram of a cell) and taken
   when a saddle point lies within a third of the local spacing and its edge lines agree;
4. ``classic-x2`` and ``sb-x2``: OpenCV's detectors on the image upsampled twice (bicubic):
   near a mirror's rim the squares shrink to a few pixels, below what they resolve (the
   slowest, so last).

Each detector's pattern size is tried both ways round (``COLSxROWS`` and ``ROWSxCOLS``). A grid
found the other way round is transposed back to the pattern's order (row by row, ``cols``
corners per row): the labelling is then the board's mirror image, which is the same planar
point set turned over, so calibration and pose fitting are unaffected.

Every corner is then refined in the original image by ``cv2.cornerSubPix`` in a window fitted
to its own squares (half-size 0.4 of the shortest distance to its grid neighbours, 2 to 7 px):
in an omni-image the squares of one board differ in size by 3 times and more, and one window
for all is either too small for the large squares or spans several of the small ones.

A board partly hidden (by the camera's own reflection, a hand) is not found: its corners
cannot be labelled without the whole grid. Pixels: (u, v) = (column, row), (0, 0) the centre of
the top-left pixel.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Image = NDArray[np.uint8]

METHODS = ("sb", "classic", "grow", "classic-x2", "sb-x2")
SB_FLAGS = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
MAX_BEND = 0.8  # second difference along a row or column / the local spacing
MIN_SPACING_PX = 2.0


@dataclass(frozen=True)
class BoardCorners:
    """A chessboard found in an image.

    Attributes:
        uv: (rows * cols, 2) refined corner pixels, row by row, ``cols`` per row.
        method: the detector that found it (one of :data:`METHODS`).
        raw_uv: the same corners before the refinement.
    """

    uv: FloatArray
    method: str
    raw_uv: FloatArray


def grid_problem(grid: FloatArray, image_size: tuple[int, int]) -> str | None:
    """Why a (rows, cols, 2) corner grid is not a plausible board image, or None.

    Checks: every corner inside the image; neighbouring corners at least
    :data:`MIN_SPACING_PX` apart; the second difference along every row and column below
    :data:`MAX_BEND` of the local spacing (a smooth image of straight board lines, however
    distorted); the grid's cells all of one orientation (no fold, no corner swapped).
    """
    w, h = image_size
    if not np.all(np.isfinite(grid)):
        return "corners not finite"
    u, v = grid[..., 0], grid[..., 1]
    if u.min() < -0.5 or v.min() < -0.5 or u.max() > w - 0.5 or v.max() > h - 0.5:
        return "a corner outside the image"
    du = np.diff(grid, axis=1)
    dv = np.diff(grid, axis=0)
    su = np.linalg.norm(du, axis=-1)
    sv = np.linalg.norm(dv, axis=-1)
    if min(su.min(), sv.min()) < MIN_SPACING_PX:
        return "corners closer than 2 px"
    if grid.shape[1] >= 3:
        bend = np.linalg.norm(np.diff(grid, 2, axis=1), axis=-1)
        if np.any(bend > MAX_BEND * np.minimum(su[:, 1:], su[:, :-1])):
            return "a row bends too sharply"
    if grid.shape[0] >= 3:
        bend = np.linalg.norm(np.diff(grid, 2, axis=0), axis=-1)
        if np.any(bend > MAX_BEND * np.minimum(sv[1:], sv[:-1])):
            return "a column bends too sharply"
    a = du[:-1]  # cell edges along the row
    b = dv[:, :-1]  # cell edges down the column
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    if not (np.all(cross > 0) or np.all(cross < 0)):
        return "the grid folds"
    return None


def _spacing(grid: FloatArray) -> FloatArray:
    """(rows, cols) shortest distance from each corner to its grid neighbours, px."""
    rows, cols = grid.shape[:2]
    out = np.full((rows, cols), np.inf)
    du = np.linalg.norm(np.diff(grid, axis=1), axis=-1)
    dv = np.linalg.norm(np.diff(grid, axis=0), axis=-1)
    out[:, 1:] = np.minimum(out[:, 1:], du)
    out[:, :-1] = np.minimum(out[:, :-1], du)
    out[1:] = np.minimum(out[1:], dv)
    out[:-1] = np.minimum(out[:-1], dv)
    return out


def refine_corners(grey: Image, grid: FloatArray) -> FloatArray:
    """(rows, cols, 2) corners refined by ``cv2.cornerSubPix``, each in its own window.

    Half-size ``clip(floor(0.4 * spacing), 2, 7)`` px with ``spacing`` the distance to the
    nearest grid neighbour. A refinement that moves a corner by more than a quarter of its
    spacing (it slid to another junction) is not taken.
    """
    sp = _spacing(grid)
    half = np.clip(np.floor(0.4 * sp), 2, 7).astype(int)
    flat = grid.reshape(-1, 2).copy()
    hs = half.ravel()
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
    for k in np.unique(hs):
        sel = np.flatnonzero(hs == k)
        pts = flat[sel].reshape(-1, 1, 2).astype(np.float32)
        out = cv2.cornerSubPix(grey, pts, (int(k), int(k)), (-1, -1), crit)
        flat[sel] = np.asarray(out, np.float64).reshape(-1, 2)
    moved = np.linalg.norm(flat - grid.reshape(-1, 2), axis=1)
    keep = moved <= 0.25 * sp.ravel()
    flat[~keep] = grid.reshape(-1, 2)[~keep]
    return flat.reshape(grid.shape)


def _as_grid(corners: FloatArray, size: tuple[int, int], inner: tuple[int, int]) -> FloatArray:
    """Corners found with pattern size ``size`` as a (rows, cols, 2) grid of ``inner``."""
    c, r = size
    grid = np.asarray(corners, np.float64).reshape(r, c, 2)
    if (c, r) != inner:
        grid = grid.transpose(1, 0, 2)
    return grid


def _opencv(grey: Image, inner: tuple[int, int], method: str) -> FloatArray | None:
    scale = 2.0 if method.endswith("-x2") else 1.0
    img = grey
    if scale != 1.0:
        img = np.asarray(
            cv2.resize(grey, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC), np.uint8
        )
    cols, rows = inner
    sizes = [(cols, rows)] if cols == rows else [(cols, rows), (rows, cols)]
    for size in sizes:
        if method.startswith("sb"):
            ok, corners = cv2.findChessboardCornersSB(img, size, flags=SB_FLAGS)
        else:
            ok, corners = cv2.findChessboardCorners(img, size, flags=CLASSIC_FLAGS)
        if ok and corners is not None:
            # pixel centres: (u + 0.5) * scale - 0.5 in the upsampled image
            uv = (np.asarray(corners, np.float64).reshape(-1, 2) + 0.5) / scale - 0.5
            return _as_grid(uv, size, inner)
    return None


def detect_chessboard(
    grey: Image, inner: tuple[int, int], *, methods: Sequence[str] = METHODS
) -> BoardCorners | None:
    """The chessboard with ``inner = (cols, rows)`` inner corners in a (H, W) uint8 image.

    The detectors of ``methods`` are tried in order (module docstring); the first whole grid
    that passes :func:`grid_problem` is refined (:func:`refine_corners`) and returned. None
    when none finds it.
    """
    img = np.asarray(grey, np.uint8)
    if img.ndim != 2:
        raise ValueError(f"detect_chessboard needs a (H, W) grey image, not {img.shape}")
    size = (int(img.shape[1]), int(img.shape[0]))
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ValueError(f"unknown detector {unknown[0]!r}: choose from {', '.join(METHODS)}")
    for method in methods:
        if method == "grow":
            from omnidev.fisheye.board_grow import grow_grid

            grid = grow_grid(img, inner)
        else:
            grid = _opencv(img, inner, method)
        if grid is None or grid_problem(grid, size) is not None:
            continue
        refined = refine_corners(img, grid)
        if grid_problem(refined, size) is not None:
            continue
        return BoardCorners(refined.reshape(-1, 2), method, grid.reshape(-1, 2))
    return None

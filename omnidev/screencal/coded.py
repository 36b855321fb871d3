"""A coded calibration pattern beside the dissertation's dots: a ChArUco board on the screen.

Every chessboard corner of a ChArUco board is identified by the ArUco markers in
its squares (OpenCV's ``cv2.aruco.CharucoDetector``), so occlusion, a cut-off
part or an unusual layout cannot shift the grid's indices: a corner is either
found with its identity or not found. The corners' screen positions are exact
(the board is drawn with an integer square size), so they take the place of the
dots in :class:`~omnidev.screencal.calibration.ScreenFeatures` and every
image -> screen method fits to them unchanged.

Screen px (x right, y down, centre of the top-left pixel (0, 0)): the board
fills ``cols x rows`` squares of ``square_px`` px, centred on the screen; inner
corner (r, c), r = 1..rows-1, c = 1..cols-1, sits at
``(ox + c square_px - 0.5, oy + r square_px - 0.5)`` and has ChArUco id
``(r - 1)(cols - 1) + (c - 1)``.

Example:
    >>> img, lay = charuco_pattern(1920, 1080)
    >>> img.shape, lay.lattice.shape, lay.lattice.centers[0].tolist()
    ((1080, 1920), (8, 15), [189.5, 154.5])
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.screencal.dots import DotDetection
from omnidev.screencal.patterns import DotGrid

FloatArray = NDArray[np.float64]
DICTIONARY = cv2.aruco.DICT_5X5_250
MARKER_FRACTION = 0.7  # marker side over square side


@dataclass(frozen=True)
class CodedLayout:
    """A ChArUco board on the screen: ``cols x rows`` squares of ``square_px`` at offset
    (``ox``, ``oy``) screen px; ``lattice``: its inner corners as a (rows-1) x (cols-1)
    :class:`DotGrid` (row-major by ChArUco id)."""

    screen_px: tuple[int, int]
    cols: int
    rows: int
    square_px: int
    ox: int
    oy: int
    lattice: DotGrid

    def board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV board object (units: screen px)."""
        d = cv2.aruco.getPredefinedDictionary(DICTIONARY)
        sq = float(self.square_px)
        return cv2.aruco.CharucoBoard((self.cols, self.rows), sq, sq * MARKER_FRACTION, d)


def charuco_layout(
    width: int, height: int, *, cols: int = 16, rows: int = 9, margin: float = 0.04
) -> CodedLayout:
    """The board's place on a ``width x height`` screen: the largest integer square size
    leaving ``margin`` (fraction of the screen) on every side, centred so both offsets
    are integers and the corner lattice is symmetric."""
    if cols < 3 or rows < 3:
        raise ValueError(f"ChArUco board {cols} x {rows} squares: at least 3 x 3")
    if (cols * rows) // 2 > 250:
        raise ValueError(f"ChArUco board {cols} x {rows}: more markers than the dictionary has")
    sq = int(min(width * (1 - 2 * margin) / cols, height * (1 - 2 * margin) / rows))
    while sq > 4 and ((width - cols * sq) % 2 or (height - rows * sq) % 2):
        sq -= 1
    if sq < 8:
        raise ValueError(f"ChArUco board {cols} x {rows} on {width}x{height}: squares too small")
    ox, oy = (width - cols * sq) // 2, (height - rows * sq) // 2
    xs = ox + sq * np.arange(1, cols) - 0.5
    ys = oy + sq * np.arange(1, rows) - 0.5
    gx, gy = np.meshgrid(xs, ys)
    centers = np.stack([gx.ravel(), gy.ravel()], axis=1).astype(np.float64)
    lattice = DotGrid(
        rows - 1,
        centers,
        0.25 * sq,
        (float(sq), float(sq)),
        "black",
        (width, height),
        cols - 1,
        (float(ox + sq), float(oy + sq)),
    )
    return CodedLayout((width, height), cols, rows, sq, ox, oy, lattice)


def charuco_pattern(
    width: int, height: int, *, cols: int = 16, rows: int = 9, margin: float = 0.04
) -> tuple[NDArray[np.uint8], CodedLayout]:
    """The ChArUco board on a white screen (``height x width`` uint8) and its layout."""
    lay = charuco_layout(width, height, cols=cols, rows=rows, margin=margin)
    sq = lay.square_px
    img = lay.board().generateImage((cols * sq, rows * sq), marginSize=0, borderBits=1)
    out = np.full((height, width), 255, np.uint8)
    out[lay.oy : lay.oy + rows * sq, lay.ox : lay.ox + cols * sq] = img
    return out, lay


def find_charuco(gray: NDArray[np.uint8], layout: CodedLayout) -> DotDetection:
    """The board's inner corners in a grey image (image px, NaN where not found), as a
    DotDetection over the corner lattice (row-major by id)."""
    det = cv2.aruco.CharucoDetector(layout.board())
    corners, ids, _, marker_ids = det.detectBoard(np.ascontiguousarray(gray))
    r, c = layout.rows - 1, layout.cols - 1
    centers = np.full((r * c, 2), np.nan)
    if ids is not None and len(ids):
        k = np.asarray(ids, np.int64).ravel()
        ok = (k >= 0) & (k < r * c)
        centers[k[ok]] = np.asarray(corners, np.float64).reshape(-1, 2)[ok]
    found = np.isfinite(centers[:, 0])
    markers = 0 if marker_ids is None else len(marker_ids)
    if found.sum() < 12:
        raise CalibrationError(
            f"coded pattern: found {int(found.sum())} of the {r * c} ChArUco corners "
            f"({markers} markers): is the screen showing the board, and sharp enough?"
        )
    return DotDetection(
        rows=r,
        centers=centers,
        found=found,
        radius=np.where(found, 0.0, np.nan),
        pitch=(float(layout.square_px), float(layout.square_px)),
        cross=np.full((5, 2), np.nan),
        cols=c,
        blobs=markers,
    )

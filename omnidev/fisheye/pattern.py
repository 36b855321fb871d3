"""Calibration patterns: a chessboard or a ChArUco board, their corners in the board frame.

Board frame (both kinds): origin at the top-left outer corner of the squares area, x along a
row of squares (to the right on the printout), y down the printout, z = 0 on the board; lengths
in mm. Inner corner ``(i, j)`` (column i, row j, 0-based) lies at ``((i + 1) * square,
(j + 1) * square, 0)``; corners are numbered row by row, ``id = j * cols_inner + i``, which is
both the order of ``cv2.findChessboardCornersSB`` (up to the board's symmetry) and ChArUco's
corner ids.

``COLSxROWS`` on the command line counts *inner corners* for a chessboard (OpenCV's
``patternSize``: a board of 10 x 7 squares is ``chessboard:9x6,SQUARE``) and *squares* for a
ChArUco board (as ``cv2.aruco.CharucoBoard``: ``charuco:10x7,SQUARE,MARKER[,DICT]``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError

FloatArray = NDArray[np.float64]

DEFAULT_DICTIONARY = "DICT_5X5_100"

MAX_SQUARES = 200
"""Most squares (ChArUco) or inner corners (chessboard) along one side of a pattern."""

SIZE_RANGE_MM = (1e-3, 1e6)
"""Smallest and largest square or marker size accepted (mm): a micron to a kilometre. OpenCV
stores them as 32-bit floats, where 5e-324 becomes 0 and fails an assertion."""


@dataclass(frozen=True)
class Pattern:
    """A planar calibration target.

    Attributes:
        kind: ``"chessboard"`` or ``"charuco"``.
        cols, rows: chessboard: inner corners per row / per column (OpenCV ``patternSize``);
            ChArUco: squares per row / per column.
        square_mm: side of one square, mm.
        marker_mm: ChArUco marker side, mm (unused for a chessboard).
        dictionary: ChArUco ArUco dictionary name, a ``cv2.aruco.DICT_*`` name.
    """

    kind: Literal["chessboard", "charuco"]
    cols: int
    rows: int
    square_mm: float
    marker_mm: float = 0.0
    dictionary: str = DEFAULT_DICTIONARY

    @property
    def squares(self) -> tuple[int, int]:
        """Squares per row and per column."""
        if self.kind == "chessboard":
            return self.cols + 1, self.rows + 1
        return self.cols, self.rows

    @property
    def inner(self) -> tuple[int, int]:
        """Inner corners per row and per column."""
        sx, sy = self.squares
        return sx - 1, sy - 1

    @property
    def n_corners(self) -> int:
        cx, cy = self.inner
        return cx * cy

    def object_points(self) -> FloatArray:
        """(N, 3) inner corners in the board frame, mm, in id order (row by row)."""
        cx, cy = self.inner
        jj, ii = np.mgrid[0:cy, 0:cx]
        s = self.square_mm
        return np.stack([(ii.ravel() + 1) * s, (jj.ravel() + 1) * s, np.zeros(cx * cy)], -1).astype(
            np.float64
        )

    def size_mm(self) -> tuple[float, float]:
        """Width and height of the squares area, mm."""
        sx, sy = self.squares
        return sx * self.square_mm, sy * self.square_mm

    def charuco_board(self) -> Any:
        """The ``cv2.aruco.CharucoBoard`` (lengths in mm)."""
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(self.squares, float(self.square_mm), float(self.marker_mm), d)

    def describe(self) -> str:
        if self.kind == "chessboard":
            return f"chessboard:{self.cols}x{self.rows},{self.square_mm:g}"
        return (
            f"charuco:{self.cols}x{self.rows},{self.square_mm:g},{self.marker_mm:g},"
            f"{self.dictionary}"
        )


_SPEC = re.compile(
    r"^(chessboard|charuco):(\d{1,9})x(\d{1,9}),([^,]+)(?:,([^,]+))?(?:,([A-Za-z0-9_]+))?$"
)


def parse_pattern(text: str) -> Pattern:
    """``chessboard:COLSxROWS,SQUARE_MM`` or ``charuco:COLSxROWS,SQUARE_MM,MARKER_MM[,DICT]``.

    >>> parse_pattern("chessboard:9x6,25").n_corners
    54
    >>> parse_pattern("charuco:8x6,30,22").inner
    (7, 5)
    """
    m = _SPEC.match(text.strip())
    if m is None:
        raise CalibrationError(
            f"--pattern {text!r}: expected chessboard:COLSxROWS,SQUARE_MM or "
            "charuco:COLSxROWS,SQUARE_MM,MARKER_MM[,DICT]"
        )
    kind, cols, rows, square, marker, dictionary = m.groups()
    try:
        square_mm = float(square)
        marker_mm = float(marker) if marker is not None else 0.0
    except ValueError:
        raise CalibrationError(
            f"--pattern {text!r}: square and marker sizes are numbers (mm)"
        ) from None
    if square_mm <= 0:
        raise CalibrationError(f"--pattern {text!r}: the square size must be > 0 mm")
    lo, hi = SIZE_RANGE_MM
    sizes = [square_mm, marker_mm] if marker is not None and marker_mm > 0 else [square_mm]
    if not all(lo <= x <= hi for x in sizes):
        raise CalibrationError(
            f"--pattern {text!r}: square and marker sizes must be {lo:g} .. {hi:g} mm"
        )
    if int(cols) > MAX_SQUARES or int(rows) > MAX_SQUARES:
        raise CalibrationError(f"--pattern {text!r}: at most {MAX_SQUARES} along a side")
    if kind == "chessboard":
        if marker is not None:
            raise CalibrationError(f"--pattern {text!r}: a chessboard takes COLSxROWS,SQUARE_MM")
        if int(cols) < 2 or int(rows) < 2:
            raise CalibrationError(f"--pattern {text!r}: at least 2x2 inner corners")
        return Pattern("chessboard", int(cols), int(rows), square_mm)
    if marker is None or not 0 < marker_mm < square_mm:
        raise CalibrationError(
            f"--pattern {text!r}: a ChArUco board needs a marker size between 0 and the square size"
        )
    if int(cols) < 3 or int(rows) < 3:
        raise CalibrationError(f"--pattern {text!r}: at least 3x3 squares")
    name = (dictionary or DEFAULT_DICTIONARY).upper()
    if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise CalibrationError(f"--pattern {text!r}: unknown ArUco dictionary {dictionary!r}")
    return Pattern("charuco", int(cols), int(rows), square_mm, marker_mm, name)

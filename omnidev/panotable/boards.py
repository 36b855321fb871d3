"""Landmarks from ChArUco boards at measured places: hundreds of pairs without surveying points.

A *board rig* (TOML) lists the boards seen in the omni-images. Each board is a
ChArUco board (:mod:`omnidev.fisheye.pattern`) whose markers carry their own
ids (``first_marker``: boards in one image must not share marker ids), and its
place in the world is given by three measured points of the board, in the
landmarks' unit (any, e.g. metres), Z up:

- ``origin``: the top-left outer corner of the squares area (the board frame's
  origin: x along a row of squares to the right, y down the printout);
- ``x_end``: the top-right outer corner (the end of the board's x axis);
- ``y_end``: the bottom-left outer corner (the end of its y axis).

Every detected ChArUco corner then has a world point, ``origin +
(x ex + y ey) * scale`` with ex, ey the measured axes (ey made orthogonal to ex)
and ``scale`` the measured length over the printed one; the two measured sides
must agree with the printed board within ``tolerance`` (else the measurement
or the pattern is wrong). A mirror reverses the image: boards are looked for
in the image and in its mirror image, and the one with more corners is kept.

Rig file::

    [[board]]
    image = "shot1.png"                  # optional: only in this image
    pattern = "charuco:8x6,80,60,DICT_4X4_250"
    first_marker = 0
    origin = [1.50, -0.32, 0.95]
    x_end  = [1.50,  0.32, 0.95]
    y_end  = [1.50, -0.32, 0.47]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.fisheye.pattern import Pattern, parse_pattern
from omnidev.inputfile import read_toml

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PlacedBoard:
    """A ChArUco board and where it is: world = origin + (x ex + y ey) scale (x, y in mm)."""

    name: str
    pattern: Pattern
    first_marker: int
    origin: FloatArray  # (3,) world
    ex: FloatArray  # (3,) unit, the board's x axis in the world
    ey: FloatArray  # (3,) unit, orthogonal to ex
    scale: float  # world units per mm
    image: str | None = None

    @classmethod
    def from_points(
        cls,
        name: str,
        pattern: Pattern,
        first_marker: int,
        origin: FloatArray,
        x_end: FloatArray,
        y_end: FloatArray,
        *,
        image: str | None = None,
        tolerance: float = 0.03,
    ) -> PlacedBoard:
        """From three measured corners; CalibrationError when they disagree with the board."""
        if pattern.kind != "charuco":
            raise CalibrationError(f"{name}: board pattern must be a ChArUco board (charuco:...)")
        o = np.asarray(origin, np.float64)
        vx = np.asarray(x_end, np.float64) - o
        vy = np.asarray(y_end, np.float64) - o
        wmm, hmm = pattern.size_mm()
        lx, ly = float(np.linalg.norm(vx)), float(np.linalg.norm(vy))
        if lx == 0 or ly == 0:
            raise CalibrationError(f"{name}: x_end and y_end must differ from origin")
        sx, sy = lx / wmm, ly / hmm
        if not (0 < sx < math.inf and 0 < sy < math.inf):
            raise CalibrationError(
                f"{name}: the measured sides {lx:g} and {ly:g} cannot be a "
                f"{wmm:g} x {hmm:g} mm board: re-measure, or check the pattern"
            )
        if abs(sx / sy - 1) > tolerance:
            raise CalibrationError(
                f"{name}: the measured sides are {lx:g} and {ly:g} but the board is "
                f"{wmm:g} x {hmm:g} mm (scales differ by {abs(sx / sy - 1):.1%}): "
                "re-measure, or check the pattern"
            )
        ex = vx / lx
        ey = vy - (vy @ ex) * ex
        ny = float(np.linalg.norm(ey))
        angle = math.degrees(math.acos(np.clip((vx @ vy) / (lx * ly), -1, 1)))
        if abs(angle - 90) > 3:
            raise CalibrationError(
                f"{name}: the measured sides are {angle:.1f} degrees apart, not 90: re-measure"
            )
        return cls(name, pattern, first_marker, o, ex, ey / ny, 0.5 * (sx + sy), image)

    def world(self, board_mm: FloatArray) -> FloatArray:
        """(n, 3) world points of (n, 2|3) board-frame points in mm."""
        b = np.asarray(board_mm, np.float64)
        return np.asarray(
            self.origin + (b[:, :1] * self.ex + b[:, 1:2] * self.ey) * self.scale, np.float64
        )

    def charuco(self) -> Any:
        p = self.pattern
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, p.dictionary))
        n = (p.squares[0] * p.squares[1]) // 2
        first, last = self.first_marker, self.first_marker + n - 1
        if last >= d.bytesList.shape[0]:
            raise CalibrationError(
                f"{self.name}: markers {first}..{last} exceed {p.dictionary}'s "
                f"{d.bytesList.shape[0]} ids"
            )
        ids = np.arange(first, last + 1, dtype=np.int32)
        try:
            return cv2.aruco.CharucoBoard(p.squares, float(p.square_mm), float(p.marker_mm), d, ids)
        except (cv2.error, SystemError):  # OpenCV's own checks of what parse_pattern let by
            raise CalibrationError(
                f"{self.name}: OpenCV refuses the board {p.describe()}"
            ) from None


MAX_COORDINATE = 1e9
"""Largest |coordinate| of a measured board corner (any unit)."""


def _vec3(board: dict[str, Any], key: str, where: str) -> FloatArray:
    v = board.get(key)
    if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, int | float) for x in v)):
        raise CalibrationError(f"{where}: {key} must be [X, Y, Z] (numbers)")
    if not all(math.isfinite(x) and abs(x) <= MAX_COORDINATE for x in v):
        raise CalibrationError(f"{where}: {key} must be finite numbers within +-{MAX_COORDINATE:g}")
    return np.array(v, np.float64)


def read_rig(path: Path) -> list[PlacedBoard]:
    """Read a board rig TOML file; errors name the file and the board."""
    path = Path(path)
    data = read_toml(path, "board rig file", error=CalibrationError)
    boards = data.get("board")
    if not isinstance(boards, list) or not boards:
        raise CalibrationError(f"{path}: no [[board]] tables")
    out = []
    for i, b in enumerate(boards, start=1):
        where = f"{path} board {i}"
        if not isinstance(b, dict):
            raise CalibrationError(f"{where}: must be a [[board]] table")
        unknown = sorted(set(b) - {"image", "pattern", "first_marker", "origin", "x_end", "y_end"})
        if unknown:
            raise CalibrationError(f"{where}: unknown key {unknown[0]!r}")
        if "pattern" not in b:
            raise CalibrationError(f"{where}: missing pattern")
        try:
            pattern = parse_pattern(str(b["pattern"]))
        except CalibrationError as exc:
            raise CalibrationError(f"{where}: {exc}") from None
        first = b.get("first_marker", 0)
        if not isinstance(first, int) or first < 0:
            raise CalibrationError(f"{where}: first_marker must be an integer >= 0")
        image = b.get("image")
        if image is not None and not isinstance(image, str):
            raise CalibrationError(f"{where}: image must be a file name")
        out.append(
            PlacedBoard.from_points(
                where,
                pattern,
                first,
                _vec3(b, "origin", where),
                _vec3(b, "x_end", where),
                _vec3(b, "y_end", where),
                image=image,
            )
        )
    return out


@dataclass(frozen=True)
class BoardCorners:
    """Detected corners of one board in one image: pixels, world points, corner ids."""

    board: str
    uv: FloatArray  # (n, 2)
    xyz: FloatArray  # (n, 3)
    ids: NDArray[np.intp]
    mirrored: bool


def _detect(gray: NDArray[np.uint8], board: PlacedBoard) -> tuple[FloatArray, NDArray[np.intp]]:
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
    params.adaptiveThreshWinSizeMax = 53
    params.minMarkerPerimeterRate = 0.01
    charuco = cv2.aruco.CharucoParameters()
    charuco.minMarkers = 1
    det = cv2.aruco.CharucoDetector(board.charuco(), charuco, params)
    corners, ids, _, _ = det.detectBoard(gray)
    if ids is None or len(ids) == 0:
        return np.zeros((0, 2)), np.zeros(0, np.intp)
    return np.asarray(corners, np.float64).reshape(-1, 2), np.asarray(ids, np.intp).ravel()


def detect_board(image: NDArray[np.uint8], board: PlacedBoard) -> BoardCorners:
    """The board's ChArUco corners in ``image`` (or in its mirror image), with world points."""
    gray = np.asarray(
        image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), np.uint8
    )
    w = gray.shape[1]
    uv, ids = _detect(gray, board)
    uv_m, ids_m = _detect(np.ascontiguousarray(gray[:, ::-1]), board)
    mirrored = len(ids_m) > len(ids)
    if mirrored:
        uv, ids = uv_m.copy(), ids_m
        uv[:, 0] = (w - 1) - uv[:, 0]
    obj = board.pattern.object_points()
    return BoardCorners(board.name, uv, board.world(obj[ids]), ids, mirrored)


def landmarks_from_boards(
    images: dict[str, NDArray[np.uint8]], boards: list[PlacedBoard], *, min_corners: int = 4
) -> list[tuple[str, BoardCorners]]:
    """Every board in every image it is meant for (``board.image`` or all): (image name, corners).

    Boards with fewer than ``min_corners`` corners in an image are left out.
    """
    out = []
    for name, img in images.items():
        for b in boards:
            if b.image is not None and Path(b.image).name != Path(name).name:
                continue
            c = detect_board(img, b)
            if len(c.ids) >= min_corners:
                out.append((name, c))
    return out

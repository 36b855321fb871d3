"""ChArUco boards placed in a :class:`~omnidev.sim.scene.RoomScene`, with exact corner truth.

A board (:class:`omnidev.panotable.boards.PlacedBoard`, world frame = the
room's camera frame shifted by ``mirror_center_world``) is a textured
rectangle: the printout ``cv2.aruco.CharucoBoard.generateImage`` draws at
``px_per_mm``, with a white quiet zone of ``margin_mm`` around the squares. A
ray that meets a board before the room's walls takes the board's grey
(bilinear); elsewhere the room shades it. The truth of a corner is its world
point (exact) projected by the camera (exact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.fisheye.pattern import parse_pattern
from omnidev.panotable.boards import PlacedBoard
from omnidev.sim.scene import RoomScene

FloatArray = NDArray[np.float64]

WHITE = 225.0
BLACK = 25.0


@dataclass(frozen=True)
class BoardScene:
    """A room with boards in it (camera frame, metres; boards in world = camera + offset)."""

    room: RoomScene
    boards: tuple[PlacedBoard, ...]
    px_per_mm: float = 2.0
    margin_mm: float = 20.0
    _tex: list[NDArray[np.float32]] = field(default_factory=list, repr=False, compare=False)

    def __post_init__(self) -> None:
        for b in self.boards:
            wmm, hmm = b.pattern.size_mm()
            m = round(self.margin_mm * self.px_per_mm)
            size = (
                round(wmm * self.px_per_mm) + 2 * m,
                round(hmm * self.px_per_mm) + 2 * m,
            )
            img = b.charuco().generateImage(size, marginSize=m, borderBits=1)
            tex = BLACK + (WHITE - BLACK) * (np.asarray(img, np.float32) / 255.0)
            self._tex.append(tex.astype(np.float32))

    @property
    def mirror_center_world(self) -> tuple[float, float, float]:
        return self.room.mirror_center_world

    def intersect(
        self, origins: FloatArray, dirs: FloatArray
    ) -> tuple[FloatArray, NDArray[np.intp]]:
        return self.room.intersect(origins, dirs)

    def shade(self, origins: FloatArray, dirs: FloatArray, t: float = 0.0) -> FloatArray:
        out = self.room.shade(origins, dirs, t)
        origins = np.broadcast_to(np.asarray(origins, np.float64), dirs.shape)
        dist, _ = self.room.intersect(origins, dirs)
        off = np.asarray(self.room.mirror_center_world, np.float64)
        for b, tex in zip(self.boards, self._tex, strict=True):
            n = np.cross(b.ex, b.ey)
            o = b.origin - off
            den = dirs @ n
            with np.errstate(divide="ignore", invalid="ignore"):
                tb = ((o - origins) @ n) / den
            p = origins + tb[:, None] * dirs - o
            x = (p @ b.ex) / b.scale  # mm on the board
            y = (p @ b.ey) / b.scale
            m = self.margin_mm
            wmm, hmm = b.pattern.size_mm()
            hit = (
                np.isfinite(tb)
                & (tb > 0)
                & (tb < dist)
                & (x >= -m)
                & (x <= wmm + m)
                & (y >= -m)
                & (y <= hmm + m)
            )
            if not np.any(hit):
                continue
            col = ((x[hit] + m) * self.px_per_mm - 0.5).astype(np.float32)
            row = ((y[hit] + m) * self.px_per_mm - 0.5).astype(np.float32)
            out[hit] = _bilinear(tex, col, row)[:, None]
        return out


def _bilinear(
    tex: NDArray[np.float32], col: NDArray[np.float32], row: NDArray[np.float32]
) -> FloatArray:
    """Bilinear samples of ``tex`` at (col, row); remap takes < 32767 rows, so 1024 per row."""
    n = col.size
    width = 1024
    rows = -(-n // width)
    c = np.zeros(rows * width, np.float32)
    r = np.zeros(rows * width, np.float32)
    c[:n], r[:n] = col, row
    g = cv2.remap(
        tex,
        c.reshape(rows, width),
        r.reshape(rows, width),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return np.asarray(g, np.float64).ravel()[:n]


def boards_around(
    scene: RoomScene,
    n: int = 4,
    *,
    pattern: str = "charuco:8x6,80,60,DICT_4X4_250",
    distance: float = 1.3,
    height: float = -0.35,
    seed: int = 0,
) -> tuple[PlacedBoard, ...]:
    """``n`` vertical boards facing the viewpoint at ``distance`` m, spread over the azimuths,
    centred ``height`` m from the viewpoint (negative: below), turned and tilted a little."""
    rng = np.random.default_rng(seed)
    pat = parse_pattern(pattern)
    wmm, hmm = pat.size_mm()
    markers = (pat.squares[0] * pat.squares[1]) // 2
    off = np.asarray(scene.mirror_center_world, np.float64)
    out = []
    a0 = rng.uniform(0, 2 * math.pi)
    for i in range(n):
        az = a0 + 2 * math.pi * i / n + rng.uniform(-0.2, 0.2)
        yaw = rng.uniform(-0.3, 0.3)
        lean = rng.uniform(-0.25, 0.25)
        d = distance * rng.uniform(0.85, 1.15)
        fwd = np.array([math.cos(az), math.sin(az), 0.0])  # from the viewpoint to the board
        right = np.array([math.sin(az), -math.cos(az), 0.0])  # as seen from the viewpoint
        ex = math.cos(yaw) * right + math.sin(yaw) * fwd
        down = np.array([0.0, 0.0, -1.0])
        ey = math.cos(lean) * down + math.sin(lean) * fwd
        ey = ey - (ey @ ex) * ex
        ey /= np.linalg.norm(ey)
        center = fwd * d + np.array([0.0, 0.0, height + rng.uniform(-0.2, 0.2)])
        s = 1e-3  # world metres per mm
        origin = center - (wmm / 2 * ex + hmm / 2 * ey) * s + off
        out.append(
            PlacedBoard.from_points(
                f"board {i + 1}",
                pat,
                i * markers,
                origin,
                origin + ex * wmm * s,
                origin + ey * hmm * s,
            )
        )
    return tuple(out)

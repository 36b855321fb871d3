"""Threshold distribution map, local binarization and the screen border polygon (sec. 5.2.1-5.2.2a).

All positions are image pixels ``(u, v)``: u to the right, v down, the centre of the
top-left pixel at (0, 0). Images are H x W uint8 (grey) or H x W x 3 uint8 (BGR,
converted to grey by :func:`to_gray`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError

FloatArray = NDArray[np.float64]
U8 = NDArray[np.uint8]

MIN_CONTRAST = 20  # grey levels; eq. 5.1's "effective pixel" test w - b > 20
SCAN_LEN = 6  # pixels along an edge in one scan window (the 2 x 6 windows of Fig. 5.6)


def to_gray(image: NDArray[np.uint8]) -> U8:
    """An H x W uint8 grey image from grey or BGR ``image``."""
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise CalibrationError(f"images must be uint8, got {img.dtype}")
    if img.ndim == 3 and img.shape[2] == 3:
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), np.uint8)
    if img.ndim == 3 and img.shape[2] == 1:
        return np.ascontiguousarray(img[:, :, 0])
    if img.ndim != 2:
        raise CalibrationError(f"expected an H x W or H x W x 3 image, got shape {img.shape}")
    return img


def threshold_map(
    white: NDArray[np.uint8], black: NDArray[np.uint8], *, min_contrast: int = MIN_CONTRAST
) -> U8:
    """The threshold distribution map (TDM) t of eq. 5.1, H x W uint8.

    ``t = b + (w - b) / 2`` where ``w - b > min_contrast`` (the screen), else 255
    (outside the screen: no pixel of the dot image can exceed it).
    """
    w = to_gray(white).astype(np.int16)
    b = to_gray(black).astype(np.int16)
    if w.shape != b.shape:
        raise CalibrationError(f"white image is {w.shape[::-1]}, black image is {b.shape[::-1]}")
    t = np.full(w.shape, 255, np.uint8)
    on = (w - b) > min_contrast
    t[on] = (b[on] + (w[on] - b[on]) // 2).astype(np.uint8)
    return t


def binarize(dots: NDArray[np.uint8], tdm: U8) -> U8:
    """The binary dot-matrix image d' of eq. 5.2: 255 where ``d > t``, else 0 (H x W uint8)."""
    d = to_gray(dots)
    if d.shape != tdm.shape:
        raise CalibrationError(f"dot image is {d.shape[::-1]}, white/black are {tdm.shape[::-1]}")
    return np.where(d > tdm, 255, 0).astype(np.uint8)


@dataclass(frozen=True)
class BorderPolygon:
    """The eight-sided screen border of Fig. 5.5 in image pixels.

    ``vertices`` is (8, 2): P0 top-left corner, P1 on the top side, P2 top-right,
    P3 right side, P4 bottom-right, P5 bottom side, P6 bottom-left, P7 left side.
    Side L_i joins P_i and P_(i+1 mod 8).
    """

    vertices: FloatArray

    def side(self, i: int) -> FloatArray:
        """Side L_i as a (2, 2) array of its two end points."""
        return np.stack([self.vertices[i % 8], self.vertices[(i + 1) % 8]])

    def mask(self, size: tuple[int, int]) -> NDArray[np.bool_]:
        """H x W bool: image pixels (centres) inside the polygon; ``size`` = (W, H)."""
        w, h = size
        m = np.zeros((h, w), np.uint8)
        shift = 4
        pts = np.round(self.vertices * (1 << shift)).astype(np.int32)
        cv2.fillPoly(m, [pts], (1,), lineType=cv2.LINE_8, shift=shift)
        return m.astype(bool)

    def contains(self, uv: FloatArray) -> NDArray[np.bool_]:
        """Whether each point of (N, 2) ``uv`` lies inside the polygon."""
        contour = self.vertices.astype(np.float32).reshape(-1, 1, 2)
        return np.array(
            [cv2.pointPolygonTest(contour, (float(u), float(v)), False) >= 0 for u, v in uv],
            bool,
        )


def _edge_maps(tdm: U8) -> tuple[FloatArray, FloatArray]:
    """Edge values |G1 - G2| of the 2 x 6 scan windows (Fig. 5.6b) at every position.

    ``horiz[y, x]``: upper six pixels (row y, columns x-3..x+2) against the lower six
    (row y+1): a horizontal edge between rows y and y+1. ``vert[y, x]``: the 6 x 2
    window, left six (column x, rows y-3..y+2) against the right six (column x+1).
    """
    t = tdm.astype(np.float64)
    row_mean = cv2.blur(
        t, (SCAN_LEN, 1), anchor=(SCAN_LEN // 2, 0), borderType=cv2.BORDER_REPLICATE
    )
    col_mean = cv2.blur(
        t, (1, SCAN_LEN), anchor=(0, SCAN_LEN // 2), borderType=cv2.BORDER_REPLICATE
    )
    horiz = np.zeros_like(t)
    horiz[:-1] = np.abs(row_mean[:-1] - row_mean[1:])
    vert = np.zeros_like(t)
    vert[:, :-1] = np.abs(col_mean[:, :-1] - col_mean[:, 1:])
    return horiz, vert


def _screen_centre(tdm: U8) -> tuple[int, int]:
    """The TDM centre used as the start of the scans: the image centre if it lies on
    the screen (t < 255), else the centroid of the screen pixels."""
    h, w = tdm.shape
    cx, cy = (w - 1) // 2, (h - 1) // 2
    if tdm[cy, cx] < 255:
        return cx, cy
    ys, xs = np.nonzero(tdm < 255)
    if len(xs) < 0.01 * w * h:
        raise CalibrationError(
            "screen not found: white and black images differ by more than "
            f"{MIN_CONTRAST} grey levels in {len(xs)} pixels only"
        )
    return round(float(xs.mean())), round(float(ys.mean()))


def _vertex_energy(
    cand: FloatArray, a: FloatArray, emap: FloatArray, samples: int, *, axis: int
) -> NDArray[np.float64]:
    """Edge energy of the candidate sides cand -> a: the summed edge values of scan
    windows tiling each side (one per SCAN_LEN pixels of its length), estimated from
    ``samples`` evenly spaced windows.

    ``axis`` is the coordinate (0: u, 1: v) across which ``emap`` measures edges; its
    index k holds the edge at k + 0.5.
    """
    h, w = emap.shape
    s = (np.arange(samples) + 0.5) / samples
    pts = cand[:, None, :] + (a[None, None, :] - cand[:, None, :]) * s[None, :, None]
    fx = np.floor if axis == 0 else np.round
    fy = np.floor if axis == 1 else np.round
    x = np.clip(fx(pts[..., 0]).astype(np.int64), 0, w - 1)
    y = np.clip(fy(pts[..., 1]).astype(np.int64), 0, h - 1)
    length = np.hypot(*(a[None, :] - cand).T)
    return np.asarray(emap[y, x].mean(axis=1) * length / SCAN_LEN, np.float64)


def find_border(tdm: U8, *, samples: int = 48, step: int = 3) -> BorderPolygon:
    """The eight-sided screen border polygon (sec. 5.2.2a, Figs. 5.5-5.7) from the TDM.

    P1/P5 (P3/P7): the maximum of the 2 x 6 (6 x 2) scan-window edge value |G1 - G2|
    along the vertical (horizontal) line through the TDM centre, above and below
    (right and left of) it. Each corner P0, P2, P4, P6: the pixel of the rectangular
    search window (centre (x3, y1), size 2|x3 - x1| x 2|y3 - y1| for P2) with the
    largest edge energy, the sum of the edge values of the scan windows placed along
    the two candidate sides to its neighbouring mid-side vertices (Fig. 5.7b; the
    windows tile each side, so a short degenerate side does not win). ``step`` > 1
    searches every step-th pixel first, then every pixel within +-step of the best
    (``step=1``: one exhaustive pass, the dissertation's, ~10x slower).
    Edges lie between pixel rows/columns, so vertex coordinates end in .5 there.
    """
    h, w = tdm.shape
    cx, cy = _screen_centre(tdm)
    horiz, vert = _edge_maps(tdm)
    col = horiz[:, cx]
    row = vert[cy, :]
    if cy < 1 or cx < 1 or cy >= h - 1 or cx >= w - 1:
        raise CalibrationError("screen not found: its centre lies on the image border")
    y1 = int(np.argmax(col[:cy])) + 0.5
    y5 = cy + int(np.argmax(col[cy : h - 1])) + 0.5
    x7 = int(np.argmax(row[:cx])) + 0.5
    x3 = cx + int(np.argmax(row[cx : w - 1])) + 0.5
    for name, val in (("top", col[int(y1)]), ("bottom", col[int(y5)])):
        if val < MIN_CONTRAST / 2:
            raise CalibrationError(f"screen not found: no {name} border edge in the TDM")
    for name, val in (("left", row[int(x7)]), ("right", row[int(x3)])):
        if val < MIN_CONTRAST / 2:
            raise CalibrationError(f"screen not found: no {name} border edge in the TDM")
    p1 = np.array([cx, y1])
    p3 = np.array([x3, cy])
    p5 = np.array([cx, y5])
    p7 = np.array([x7, cy])
    mids = {1: p1, 3: p3, 5: p5, 7: p7}
    verts: dict[int, FloatArray] = dict(mids)
    # corner k sits between mids k-1 and k+1; the side to a top/bottom mid is mostly
    # horizontal (2 x 6 windows), the side to a left/right mid mostly vertical (6 x 2).
    for k in (0, 2, 4, 6):
        a = mids[(k - 1) % 8]
        b = mids[(k + 1) % 8]
        horiz_mid, vert_mid = (a, b) if (k - 1) % 8 in (1, 5) else (b, a)
        pcx, pcy = vert_mid[0], horiz_mid[1]
        half_w = abs(vert_mid[0] - horiz_mid[0])
        half_h = abs(vert_mid[1] - horiz_mid[1])
        x_lo, x_hi = max(0, int(pcx - half_w)), min(w - 2, int(pcx + half_w))
        y_lo, y_hi = max(0, int(pcy - half_h)), min(h - 2, int(pcy + half_h))

        def best(
            xs: NDArray[np.int64],
            ys: NDArray[np.int64],
            hm: FloatArray = horiz_mid,
            vm: FloatArray = vert_mid,
        ) -> FloatArray:
            gx, gy = np.meshgrid(xs + 0.5, ys + 0.5)
            cand = np.stack([gx.ravel(), gy.ravel()], axis=1)
            energy = _vertex_energy(cand, hm, horiz, samples, axis=1)
            energy += _vertex_energy(cand, vm, vert, samples, axis=0)
            return np.asarray(cand[int(np.argmax(energy))], np.float64)

        v = best(np.arange(x_lo, x_hi + 1, step), np.arange(y_lo, y_hi + 1, step))
        if step > 1:
            bx, by = int(v[0]), int(v[1])
            v = best(
                np.arange(max(x_lo, bx - step), min(x_hi, bx + step) + 1),
                np.arange(max(y_lo, by - step), min(y_hi, by + step) + 1),
            )
        verts[k] = v
    return BorderPolygon(np.stack([verts[i] for i in range(8)]).astype(np.float64))

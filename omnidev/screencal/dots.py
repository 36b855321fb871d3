"""Dot centres of the dot-matrix image (sec. 5.2.2b).

(b.1) connected components of the binary image d' (eq. 5.2) filtered by area,
width/height ratio and fill; (b.2) the five-dot cross C0..C4 near the screen centre
and the rough cross-matrix pattern (CMP) with the spacings W_g, H_g of eq. 5.3;
(b.3) fine positions by deformable template matching (DTM): a circle of centre
(x, y) and radius r with eight scan windows around it, the position and radius of
maximum edge energy in the search range. Beside the dissertation's integer DTM
position, ``subpixel=True`` (default) refines each centre by the centroid of the
dot's normalised brightness ``(d - b) / (w - b)`` in a window around it shaped like
the dot's blob (``w - b`` floored near the screen's edge, see :func:`_centroid`).

Positions are image pixels (u right, v down, top-left pixel centre at (0, 0)).
Dot indices are row-major from the top-left of the screen, as in
:class:`omnidev.screencal.patterns.DotGrid`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.screencal.features import (
    MIN_CONTRAST,
    BorderPolygon,
    at_exposure,
    binarize,
    to_gray,
)

FloatArray = NDArray[np.float64]

WINDOW_SCALE = 1.25  # the centroid window's semi-axes over the dot's (plus 2 px)
# The eight scan-window directions of the circular template (Fig. 5.10b).
_DIRS = [(math.cos(a), math.sin(a)) for a in np.arange(8) * math.pi / 4]


@dataclass(frozen=True)
class DotDetection:
    """Dot centres found in a dot-matrix image.

    centers: (rows*cols, 2) image px, row-major like the pattern's DotGrid; NaN
    where a dot was not found. found: (rows*cols,) bool. radius: (rows*cols,) DTM
    radius in image px (NaN if not found). pitch: (W_g, H_g) of eq. 5.3 in image
    px. cross: (5, 2) the five-dot cross C0..C4 (C1 left, C2 right, C3 up, C4
    down). blobs: dot-like blobs inside the screen border (found or not).
    """

    rows: int
    centers: FloatArray
    found: NDArray[np.bool_]
    radius: FloatArray
    pitch: tuple[float, float]
    cross: FloatArray
    cols: int = 0
    blobs: int = 0
    blob_uv: FloatArray | None = None  # (blobs, 2) image px of the dot-like blobs

    def __post_init__(self) -> None:
        if self.cols == 0:
            object.__setattr__(self, "cols", self.rows)

    @property
    def n(self) -> int:
        """Dots per row of a square grid (rows)."""
        return self.rows

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return self.rows, self.cols

    @property
    def count(self) -> int:
        """Number of dots found."""
        return int(self.found.sum())


@dataclass(frozen=True)
class _Blobs:
    centroid: FloatArray  # (m, 2)
    area: FloatArray  # (m,)
    elong: FloatArray  # (m,) major over minor axis of the equal-moment ellipse
    axis: FloatArray  # (m, 2) unit vector along the major axis


def _components(
    binary: NDArray[np.uint8], border: BorderPolygon, expected: int | None = None
) -> _Blobs:
    """(b.1) Connected components that look like dots: inside the border, fill >= 0.45,
    width/height within 1:2.5, area within 1/4..4 x the typical dot's area.

    The typical area is the median over the ``expected`` largest blobs (the layout's
    dot count; all blobs when None): where the screen's contrast is low, noise over
    the threshold map makes hundreds of specks, and their median would refuse every
    dot as too large."""
    count, labels, stats, cents = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if count <= 1:
        return _Blobs(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros((0, 2)))
    st = stats[1:].astype(np.float64)
    c = np.asarray(cents[1:], np.float64)
    area = st[:, cv2.CC_STAT_AREA]
    elong, axis = _elongation(np.asarray(labels, np.int32), count, c, area)
    bw, bh = st[:, cv2.CC_STAT_WIDTH], st[:, cv2.CC_STAT_HEIGHT]
    ok = (area >= 5) & (bw / bh <= 2.5) & (bh / bw <= 2.5) & (area / (bw * bh) >= 0.45)
    c, area, elong, axis = c[ok], area[ok], elong[ok], axis[ok]
    if len(c):
        inside = border.contains(c)
        c, area, elong, axis = c[inside], area[inside], elong[inside], axis[inside]
    if len(c):
        top = np.sort(area)[::-1][: expected or len(area)]
        med = float(np.median(top))
        ok = (area >= med / 4) & (area <= med * 4)
        c, area, elong, axis = c[ok], area[ok], elong[ok], axis[ok]
    return _Blobs(c, area, elong, axis)


def _elongation(
    labels: NDArray[np.int32], count: int, centroid: FloatArray, area: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Each labelled component's equal-moment ellipse (from its pixels' covariance, each
    pixel a unit square): the major over the minor axis ((count - 1,)) and the major
    axis's direction ((count - 1, 2) unit vectors, image u right, v down)."""
    v, u = np.nonzero(labels)
    lab = labels[v, u] - 1
    n = count - 1
    du = u - centroid[lab, 0]
    dv = v - centroid[lab, 1]
    a = np.maximum(area, 1.0)
    suu = np.bincount(lab, du * du, n) / a
    svv = np.bincount(lab, dv * dv, n) / a
    suv = np.bincount(lab, du * dv, n) / a
    half = np.sqrt(0.25 * (suu - svv) ** 2 + suv**2)
    big, small = 0.5 * (suu + svv) + half, 0.5 * (suu + svv) - half
    theta = 0.5 * np.arctan2(2.0 * suv, suu - svv)
    axis = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    return np.sqrt((big + 1.0 / 12.0) / np.maximum(small + 1.0 / 12.0, 1e-6)), axis


def _nearest_in_cone(c: FloatArray, pts: FloatArray, direction: tuple[float, float]) -> int:
    """Index of the point nearest to c within 45 degrees of ``direction``; -1 if none."""
    d = pts - c
    dist = np.hypot(d[:, 0], d[:, 1])
    along = d @ np.asarray(direction)
    ok = (dist > 0) & (along > dist * math.cos(math.pi / 4))
    if not ok.any():
        return -1
    idx = np.flatnonzero(ok)
    return int(idx[np.argmin(dist[idx])])


def _edge_maps(gray: NDArray[np.uint8]) -> list[NDArray[np.float32]]:
    """Edge value |G_in - G_out| of the template's scan window k at every pixel: six
    pixels along the circle on the inner side against six on the outer side."""
    g = gray.astype(np.float32)
    maps = []
    for dx, dy in _DIRS:
        ux, uy = round(dx), round(dy)
        tx, ty = -uy, ux  # tangent
        k = np.zeros((11, 11), np.float32)
        for t in range(-3, 3):
            k[5 + t * ty, 5 + t * tx] -= 1 / 6
            k[5 + t * ty + uy, 5 + t * tx + ux] += 1 / 6
        maps.append(np.abs(cv2.filter2D(g, cv2.CV_32F, k, borderType=cv2.BORDER_REPLICATE)))
    return maps


def _dtm(
    maps: list[NDArray[np.float32]],
    start: tuple[int, int],
    half: tuple[int, int],
    radii: FloatArray,
) -> tuple[int, int, float, float]:
    """(b.3) Deformable template matching: the centre (x, y) in the search range
    start +- half and the radius in ``radii`` with the largest edge energy (sum of
    the eight scan windows' edge values). Returns x, y, r, energy."""
    h, w = maps[0].shape
    x0, y0 = start
    hx, hy = half
    best = (x0, y0, float(radii[0]), -1.0)
    xs = np.arange(x0 - hx, x0 + hx + 1)
    ys = np.arange(y0 - hy, y0 + hy + 1)
    for r in radii:
        energy = np.zeros((len(ys), len(xs)), np.float32)
        for (dx, dy), emap in zip(_DIRS, maps, strict=True):
            ox, oy = round(float(r) * dx), round(float(r) * dy)
            yy = np.clip(ys + oy, 0, h - 1)
            xx = np.clip(xs + ox, 0, w - 1)
            energy += emap[np.ix_(yy, xx)]
        k = int(np.argmax(energy))
        e = float(energy.flat[k])
        if e > best[3]:
            iy, ix = divmod(k, len(xs))
            best = (int(xs[ix]), int(ys[iy]), float(r), e)
    return best


EDGE_FLOOR = 0.8  # of the disc's screen level: below it w - b is taken as the edge's blur


def _centroid(
    norm: NDArray[np.float32],
    x: float,
    y: float,
    radius: float,
    stretch: tuple[float, float, float] | None = None,
) -> tuple[float, float] | None:
    """Centroid of the normalised brightness in the disc of ``radius`` around (x, y), or
    with ``stretch`` = (ux, uy, long) the ellipse reaching ``long`` along the unit vector
    (ux, uy) and ``radius`` across it.

    ``norm`` is :func:`_normalised`'s (H, W, 2) pair: the dot image's rise over the
    black one, ``d - b``, and the screen's, ``w - b``. The rise is divided by ``w - b``
    pixel by pixel (vignetting and uneven light cancel), but never by less than
    ``EDGE_FLOOR`` of the disc's level (the 90th percentile of ``w - b`` in it): near the
    screen's edge ``w - b`` falls in the blur while the dot's halo does not, and the
    bare ratio there pulled the outer dots' centroids up to 0.7 px toward the edge.
    Pixels off the screen (``w - b`` <= MIN_CONTRAST) weigh 0.
    """
    h, w = norm.shape[:2]
    r = math.ceil(radius if stretch is None else max(radius, stretch[2]))
    xi, yi = round(x), round(y)
    if xi - r < 0 or yi - r < 0 or xi + r >= w or yi + r >= h:
        return None
    patch = norm[yi - r : yi + r + 1, xi - r : xi + r + 1].astype(np.float64)
    gy, gx = np.mgrid[-r : r + 1, -r : r + 1]
    dx, dy = gx + xi - x, gy + yi - y
    if stretch is None:
        disc = dx**2 + dy**2 <= radius**2
    else:
        ux, uy, long = stretch
        along, across = dx * ux + dy * uy, dy * ux - dx * uy
        disc = (along / long) ** 2 + (across / radius) ** 2 <= 1.0
    lift, screen = patch[..., 0], patch[..., 1]
    on = disc & (screen > MIN_CONTRAST)
    if not on.any():
        return None
    level = max(float(np.percentile(screen[on], 90)), 1.0)
    floor = max(EDGE_FLOOR * level, 1.0)
    wgt = np.where(on, np.clip(lift / np.maximum(screen, floor), 0.0, 1.0), 0.0)
    s = float(wgt.sum())
    if s <= 0:
        return None
    return xi + float((wgt * gx).sum()) / s, yi + float((wgt * gy).sum()) / s


def _affine_guess(centers: FloatArray, i: int, j: int, rough: FloatArray) -> FloatArray:
    """Where dot (i, j) should be from an affine fit (grid index -> image px) to the six
    found dots nearest to it in the grid; ``rough`` if fewer than three are found."""
    rows, cols = centers.shape[:2]
    gi, gj = np.mgrid[0:rows, 0:cols]
    ok = np.isfinite(centers[..., 0])
    if ok.sum() < 3:
        return rough
    d = np.hypot(gi[ok] - i, gj[ok] - j)
    near = np.argsort(d, kind="stable")[:6]
    a = np.c_[gj[ok][near], gi[ok][near], np.ones(len(near))]
    if np.linalg.matrix_rank(a) < 3:
        return rough
    coef, *_ = np.linalg.lstsq(a, centers[ok][near], rcond=None)
    return np.asarray(np.array([j, i, 1.0]) @ coef, np.float64)


def _refine(
    maps: list[NDArray[np.float32]],
    norm: NDArray[np.float32],
    blobs: _Blobs,
    k: int,
    pitch: tuple[float, float],
    subpixel: bool,
) -> tuple[tuple[float, float], float]:
    """(b.3) DTM position and radius of blob k, then (``subpixel``) the centroid of the
    normalised brightness in a window around it (an ellipse shaped like the blob), iterated
    to a fixed point."""
    wg, hg = pitch
    pts = blobs.centroid
    r_cc = math.sqrt(blobs.area[k] / math.pi)
    radii = np.arange(max(1.5, 0.7 * r_cc), 1.3 * r_cc + 1.0, 0.5)
    half = (max(2, int(wg / 4)), max(2, int(hg / 4)))
    start = (round(float(pts[k, 0])), round(float(pts[k, 1])))
    half = (min(half[0], int(r_cc) + 2), min(half[1], int(r_cc) + 2))
    x, y, r, _ = _dtm(maps, start, half, radii)
    pos: tuple[float, float] = (float(x), float(y))
    if subpixel:
        # the window holds the whole dot: a projected dot under a steep view is an
        # ellipse longer than the template's circle, and a window cutting it moves the
        # centroid off the full ellipse's, which the perspective correction assumes; so
        # the window is an ellipse shaped like the blob, of the template's mean radius
        q = math.sqrt(float(blobs.elong[k]))  # semi-axes r q and r / q
        ax = blobs.axis[k]
        radius = WINDOW_SCALE * r / q + 2.0
        stretch = (float(ax[0]), float(ax[1]), WINDOW_SCALE * r * q + 2.0)
        for _ in range(10):
            c = _centroid(norm, pos[0], pos[1], radius, stretch)
            if c is None:
                break
            moved = math.hypot(c[0] - pos[0], c[1] - pos[1])
            pos = c
            if moved < 1e-3:
                break
    return pos, r


def _normalised(
    gray: NDArray[np.uint8],
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    black_gain: float = 1.0,
    scaled: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
) -> NDArray[np.float32]:
    """(H, W, 2): the dot image's rise over the black image and the white image's
    (grey levels), for :func:`_centroid`. The white image's is taken with the black
    image at the white image's exposure (``black_gain``,
    :func:`~omnidev.screencal.features.exposure_gain`): where auto-exposure made the
    black capture the brighter (a projector's dim corner), ``w - b`` fell to zero and
    the dots' pixels there weighed nothing (scene 54076 of issue 12: a dot 3 image px
    off). With ``scaled``, the white and black images at the dot capture's exposure
    (:func:`dot_exposure`), both rises are taken at that exposure."""
    if scaled is not None:
        w_d, b_d = scaled
        return np.stack([gray.astype(np.float32) - b_d, w_d - b_d], axis=-1)
    w_img = to_gray(white).astype(np.float32)
    b = to_gray(black)
    b_img = b.astype(np.float32)
    return np.stack([gray.astype(np.float32) - b_img, w_img - at_exposure(b, black_gain)], axis=-1)


def dot_exposure(
    white: NDArray[np.uint8], black: NDArray[np.uint8], black_gain: float, dot_gain: float
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """The white and black images as they would read at the dot capture's exposure
    (float32 grey levels, clipped at 255 as the dot capture is): ``black_gain`` is the
    white capture's exposure over the black one's, ``dot_gain`` the dot capture's
    (:func:`~omnidev.screencal.features.exposure_gain` of each against the black
    image). An auto-exposure camera sets the dot capture between the other two."""
    b_d = np.minimum(at_exposure(to_gray(black), dot_gain), 255.0)
    w_d = np.minimum(at_exposure(to_gray(white), dot_gain / black_gain), 255.0)
    return w_d, b_d


def dot_threshold(
    w_d: NDArray[np.float32], b_d: NDArray[np.float32], tdm: NDArray[np.uint8]
) -> NDArray[np.uint8]:
    """Eq. 5.1's threshold map at the dot capture's exposure: ``b + (w - b) / 2`` of the
    white and black images scaled to it (:func:`dot_exposure`) where ``tdm`` is below
    255, 255 elsewhere."""
    inside = tdm < 255
    t = np.full(tdm.shape, 255, np.uint8)
    mid = b_d[inside] + np.maximum(w_d[inside] - b_d[inside], 0.0) / 2
    t[inside] = np.clip(np.floor(mid), 0, 254).astype(np.uint8)
    return t


def _corner_homography(border: BorderPolygon, screen_size: tuple[int, int]) -> FloatArray:
    """Screen px -> image px through the border polygon's corner vertices."""
    sw, sh = screen_size
    corners_img = border.vertices[[0, 2, 4, 6]].astype(np.float32)
    corners_scr = np.array(
        [[-0.5, -0.5], [sw - 0.5, -0.5], [sw - 0.5, sh - 0.5], [-0.5, sh - 0.5]], np.float32
    )
    return np.asarray(cv2.getPerspectiveTransform(corners_scr, corners_img), np.float64)


def _grow_lattice(
    rect: FloatArray, step: tuple[float, float], start: int, gate: float = 0.3
) -> dict[tuple[int, int], int]:
    """Relative lattice indices (i, j) -> blob index, grown neighbour by neighbour from
    blob ``start`` over the blobs' positions ``rect`` (the corner-homography-rectified
    frame, where the lattice is roughly axis-aligned with spacing ``step`` (x, y)).

    Each neighbour of an indexed blob is predicted by extending the nearest known step
    in that direction (the lattice's local, distorted spacing), or by the nominal step
    where none is known yet; it takes the nearest blob within ``gate`` of that step's
    length, if the blob is not indexed yet. Where no step is known and no blob lies
    within the gate of the nominal step (a strong barrel lens magnifies the middle of
    the picture against the corners' homography, up to 1.4 x at k1 = -0.34 with a
    334 px focal length at 640x480), the step is the one to the nearest blob along the
    direction 0.6 to 1.6 nominal steps away and off it by less than ``gate`` of that
    (two steps over a missing dot are longer; a diagonal neighbour is off the line).
    """
    sx, sy = step
    index: dict[tuple[int, int], int] = {(0, 0): start}
    used = {start}
    queue = [(0, 0)]
    dirs = ((0, 1), (0, -1), (1, 0), (-1, 0))
    while queue:
        queue.sort(key=lambda ij: abs(ij[0]) + abs(ij[1]))  # the most central first
        i, j = queue.pop(0)
        p = rect[index[(i, j)]]
        for di, dj in dirs:
            nxt = (i + di, j + dj)
            if nxt in index:
                continue
            # the step along (di, dj) nearest in the lattice to (i, j)
            best: FloatArray | None = None
            best_d = math.inf
            for (a, b), k in index.items():
                prev = index.get((a - di, b - dj))
                if prev is None:
                    continue
                dd = abs(a - i) + abs(b - j)
                if dd < best_d:
                    best_d, best = dd, rect[k] - rect[prev]
                    if dd == 0:
                        break
            if best is None:
                best = _first_step(rect - p, np.array([dj * sx, di * sy]), gate)
            pred = p + best
            d = np.hypot(*(rect - pred).T)
            k = int(np.argmin(d))
            if d[k] < gate * float(np.hypot(*best)) and k not in used:
                index[nxt] = k
                used.add(k)
                queue.append(nxt)
    return index


def _first_step(rel: FloatArray, nominal: FloatArray, gate: float) -> FloatArray:
    """The first step from a blob along the lattice direction of ``nominal`` (x, y),
    ``rel`` the blobs' offsets from it (:func:`_grow_lattice`): the nominal step where a
    blob lies within ``gate`` of it, else the offset of the nearest blob along the
    direction 0.6-1.6 nominal steps away and off it by less than ``gate`` of that, else
    the nominal step."""
    length = float(np.hypot(*nominal))
    if float(np.hypot(*(rel - nominal).T).min()) < gate * length:
        return nominal
    unit = nominal / length
    along = rel @ unit
    across = np.abs(rel @ np.array([unit[1], -unit[0]]))
    ok = (along >= 0.6 * length) & (along <= 1.6 * length) & (across < gate * along)
    if not ok.any():
        return nominal
    return np.asarray(rel[np.flatnonzero(ok)[np.argmin(along[ok])]], np.float64)


def _assign_by_growth(
    pts: FloatArray,
    border: BorderPolygon,
    screen_dots: FloatArray,
    rows: int,
    cols: int,
    screen_size: tuple[int, int],
) -> NDArray[np.int64] | None:
    """Blob index for each dot (-1: none) by growing the lattice from the blob nearest
    the screen centre (:func:`_grow_lattice`) in the frame rectified by the border's
    corner homography; the grown lattice's offset in the layout is the one that puts
    its blobs nearest their dots in that frame. None if the growth or the offset is
    not clear (fewer than 8 blobs grown, or, where the grown lattice does not span every
    row and column, no offset within 0.6 dot spacings)."""
    h = _corner_homography(border, screen_size)
    rect = np.asarray(
        cv2.perspectiveTransform(pts.reshape(-1, 1, 2).astype(np.float64), np.linalg.inv(h)),
        np.float64,
    ).reshape(-1, 2)
    sx = float(screen_dots[1, 0] - screen_dots[0, 0]) if cols > 1 else float(screen_size[0])
    sy = float(screen_dots[cols, 1] - screen_dots[0, 1]) if rows > 1 else float(screen_size[1])
    centre = np.array([screen_size[0] / 2 - 0.5, screen_size[1] / 2 - 0.5])
    start = int(np.argmin(np.hypot(*(rect - centre).T)))
    index = _grow_lattice(rect, (sx, sy), start)
    if len(index) < 8:
        return None
    ij = np.array(list(index.keys()))
    blob = np.array(list(index.values()))
    lo, hi = ij.min(axis=0), ij.max(axis=0)
    if hi[0] - lo[0] >= rows or hi[1] - lo[1] >= cols:
        return None  # more rows or columns than the layout has
    grid = screen_dots.reshape(rows, cols, 2)
    best: tuple[float, int, int] = (math.inf, 0, 0)
    for oi in range(-lo[0], rows - hi[0]):
        for oj in range(-lo[1], cols - hi[1]):
            err = np.hypot(*(rect[blob] - grid[ij[:, 0] + oi, ij[:, 1] + oj]).T)
            med = float(np.median(err))
            if med < best[0]:
                best = (med, oi, oj)
    med, oi, oj = best
    unique = hi[0] - lo[0] == rows - 1 and hi[1] - lo[1] == cols - 1
    if not (unique or med < 0.6 * min(sx, sy)):
        return None
    assign = np.full(rows * cols, -1, np.int64)
    assign[(ij[:, 0] + oi) * cols + ij[:, 1] + oj] = blob
    return assign


def _assign_by_model(
    pts: FloatArray,
    border: BorderPolygon,
    screen_dots: FloatArray,
    rows: int,
    cols: int,
    screen_size: tuple[int, int],
    image_size: tuple[int, int],
) -> tuple[NDArray[np.int64], FloatArray]:
    """Blob index for each dot (-1: none) and the predicted image positions (rows*cols, 2).

    Round 0 predicts through the homography of the border's corners; rounds 1-3
    through a radial model (:class:`omnidev.screencal.transform.RadialMap`, inverted)
    fitted to the dots matched in the previous round. A dot takes the nearest blob
    within a third of the predicted distance to its nearest neighbouring dot, if that
    blob has no nearer dot.
    """
    from omnidev.screencal.transform import RadialMap, invert

    h = _corner_homography(border, screen_size)
    pred = cv2.perspectiveTransform(screen_dots.reshape(-1, 1, 2).astype(np.float64), h)
    pred = np.asarray(pred, np.float64).reshape(-1, 2)
    sx = (screen_dots[1, 0] - screen_dots[0, 0]) if cols > 1 else 1.0
    sy = (screen_dots[cols, 1] - screen_dots[0, 1]) if rows > 1 else 1.0
    lattice = np.array([screen_dots[0, 0], screen_dots[0, 1], sx, sy])
    grown = _assign_by_growth(pts, border, screen_dots, rows, cols, screen_size)
    for rnd in range(4):
        if rnd == 0 and grown is not None:
            assign = grown
            found = assign >= 0
            model = RadialMap.fit(
                pts[assign[found]],
                screen_dots[found],
                image_size,
                lattice,
                (rows, cols),
                found,
                correct=False,
            )
            new = invert(model, screen_dots, pred)
            if np.isfinite(new).all():
                pred = new
                continue
        g = pred.reshape(rows, cols, 2)
        dx = np.full((rows, cols), np.inf)
        dy = np.full((rows, cols), np.inf)
        if cols > 1:
            step = np.hypot(*(g[:, 1:] - g[:, :-1]).transpose(2, 0, 1))
            dx[:, :-1] = np.minimum(dx[:, :-1], step)
            dx[:, 1:] = np.minimum(dx[:, 1:], step)
        if rows > 1:
            step = np.hypot(*(g[1:] - g[:-1]).transpose(2, 0, 1))
            dy[:-1] = np.minimum(dy[:-1], step)
            dy[1:] = np.minimum(dy[1:], step)
        gate = np.minimum(dx, dy).ravel() / 3.0
        d = np.hypot(pts[None, :, 0] - pred[:, None, 0], pts[None, :, 1] - pred[:, None, 1])
        best = np.argmin(d, axis=1)
        ok = d[np.arange(len(pred)), best] < gate
        mutual = np.argmin(d, axis=0)[best] == np.arange(len(pred))
        assign = np.where(ok & mutual, best, -1)
        found = assign >= 0
        if rnd == 3 or found.sum() < 8:
            break
        model = RadialMap.fit(
            pts[assign[found]],
            screen_dots[found],
            image_size,
            lattice,
            (rows, cols),
            found,
            correct=False,
        )
        new = invert(model, screen_dots, pred)
        if not np.isfinite(new).all():
            break
        pred = new
    return assign, pred


def _find_by_model(
    gray: NDArray[np.uint8],
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    blobs: _Blobs,
    border: BorderPolygon,
    rows: int,
    cols: int,
    screen_dots: FloatArray,
    screen_size: tuple[int, int],
    subpixel: bool,
    black_gain: float,
    scaled: tuple[NDArray[np.float32], NDArray[np.float32]] | None,
) -> DotDetection:
    pts = blobs.centroid
    image_size = (gray.shape[1], gray.shape[0])
    assign, pred = _assign_by_model(pts, border, screen_dots, rows, cols, screen_size, image_size)
    g = pred.reshape(rows, cols, 2)
    wg = float(np.nanmedian(np.hypot(*(g[:, 1:] - g[:, :-1]).reshape(-1, 2).T))) if cols > 1 else 8
    hg = float(np.nanmedian(np.hypot(*(g[1:] - g[:-1]).reshape(-1, 2).T))) if rows > 1 else 8
    wg = wg if math.isfinite(wg) else 8.0
    hg = hg if math.isfinite(hg) else 8.0
    norm = _normalised(gray, white, black, black_gain, scaled)
    maps = _edge_maps(gray)
    centers = np.full((rows * cols, 2), np.nan)
    radius = np.full(rows * cols, np.nan)
    for i in np.flatnonzero(assign >= 0):
        pos, r = _refine(maps, norm, blobs, int(assign[i]), (wg, hg), subpixel)
        centers[i] = pos
        radius[i] = r
    found = np.isfinite(centers[:, 0])
    c = (rows // 2) * cols + cols // 2
    cross_idx = [c, c - 1, c + 1, c - cols, c + cols]
    cross = np.array([centers[k] if 0 <= k < rows * cols else (np.nan, np.nan) for k in cross_idx])
    return DotDetection(
        rows=rows,
        centers=centers,
        found=found,
        radius=radius,
        pitch=(wg, hg),
        cross=cross,
        cols=cols,
        blobs=len(pts),
        blob_uv=pts,
    )


def find_dots(
    dots: NDArray[np.uint8],
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    tdm: NDArray[np.uint8],
    border: BorderPolygon,
    n: int | tuple[int, int],
    screen_dots: FloatArray,
    screen_size: tuple[int, int],
    *,
    subpixel: bool = True,
    index: str = "model",
    black_gain: float = 1.0,
    dot_gain: float | None = None,
) -> DotDetection:
    """Find the dot centres (sec. 5.2.2b) in image pixels.

    ``index`` says how each blob gets its grid index: ``model`` (default) predicts
    every dot through a model of the screen -> image map (first the border
    corners' homography, then the radial model fitted to the dots matched so far,
    three rounds) and takes the blob nearest each prediction within a third of the
    local spacing, so a short row spacing or a missing dot cannot shift the grid;
    ``walk`` is the dissertation's walk out from the five-dot cross C0 described
    below.

    ``n``: dots per row and column, or (rows, cols). ``screen_dots``
    (rows*cols, 2) are the dots' screen pixels (the pattern's DotGrid) and
    ``screen_size`` (W, H); they give the grid index of the centre dot C0 (through
    the homography of the border polygon's corners), so the grid is indexed right
    even when whole rows or columns are occluded. Walking out from C0 ring by ring,
    each rough CMP cross (eq. 5.3 spacing, moved by its found neighbours' offsets)
    takes the component nearest to it within the search range; the DTM then fixes
    the centre. Missing dots are NaN in ``centers``. ``black_gain``: the white
    capture's exposure over the black one's (:func:`_normalised`); ``dot_gain``: the
    dot capture's over the black one's, or None (eq. 5.2 on the images as captured):
    the dot image is then thresholded, and its dots weighed, against the white and
    black images at its own exposure (:func:`dot_threshold`).
    """
    rows, cols = (n, n) if isinstance(n, int) else (int(n[0]), int(n[1]))
    if index not in ("model", "walk"):
        raise CalibrationError(f"unknown dot indexing {index!r}: 'model' or 'walk'")
    gray = to_gray(dots)
    scaled = None if dot_gain is None else dot_exposure(white, black, black_gain, dot_gain)
    if scaled is not None:
        tdm = dot_threshold(*scaled, tdm)
    binary = binarize(gray, tdm)
    blobs = _components(binary, border, rows * cols)
    if len(blobs.area) < 5:
        raise CalibrationError(
            f"dots not found: {len(blobs.area)} dot-like blobs in the dot image "
            "(is it the dot-matrix image, and is the screen showing it?)"
        )
    if index == "model":
        return _find_by_model(
            gray,
            white,
            black,
            blobs,
            border,
            rows,
            cols,
            screen_dots,
            screen_size,
            subpixel,
            black_gain,
            scaled,
        )
    centre = border.vertices[[1, 3, 5, 7]].mean(axis=0)
    pts = blobs.centroid
    # C0: the blob nearest the screen centre that has its four cross neighbours
    nb = [-1]
    c0 = pts[0]
    for i0 in np.argsort(np.hypot(*(pts - centre).T))[:12]:
        c0 = pts[int(i0)]
        nb = [_nearest_in_cone(c0, pts, d) for d in ((-1, 0), (1, 0), (0, -1), (0, 1))]
        if min(nb) >= 0:
            break
    if min(nb) < 0:
        raise CalibrationError(
            f"dots not found: {len(pts)} dot-like blobs but no five-dot cross near the screen "
            "centre (dots occluded?)"
        )
    c1, c2, c3, c4 = (pts[k] for k in nb)
    wg = (float(np.hypot(*(c1 - c0))) + float(np.hypot(*(c2 - c0)))) / 2  # eq. 5.3
    hg = (float(np.hypot(*(c3 - c0))) + float(np.hypot(*(c4 - c0)))) / 2
    # grid index of C0: its screen position through the corner homography
    sw, sh = screen_size
    corners_img = border.vertices[[0, 2, 4, 6]].astype(np.float32)
    corners_scr = np.array(
        [[-0.5, -0.5], [sw - 0.5, -0.5], [sw - 0.5, sh - 0.5], [-0.5, sh - 0.5]], np.float32
    )
    hmat = cv2.getPerspectiveTransform(corners_img, corners_scr)
    s0 = cv2.perspectiveTransform(c0.reshape(1, 1, 2).astype(np.float64), hmat)[0, 0]
    k0 = int(np.argmin(np.hypot(*(screen_dots - s0).T)))
    r0, q0 = divmod(k0, cols)

    norm = _normalised(gray, white, black, black_gain, scaled)
    maps = _edge_maps(gray)

    centers = np.full((rows, cols, 2), np.nan)
    radius = np.full((rows, cols), np.nan)
    used = np.zeros(len(pts), bool)
    order = sorted(
        ((i, j) for i in range(rows) for j in range(cols)),
        key=lambda ij: (max(abs(ij[0] - r0), abs(ij[1] - q0)), abs(ij[0] - r0) + abs(ij[1] - q0)),
    )
    for i, j in order:
        rough = c0 + np.array([(j - q0) * wg, (i - r0) * hg])  # rough CMP cross
        # move the cross by its found neighbours towards C0 (linear extrapolation)
        si, sj = int(np.sign(r0 - i)), int(np.sign(q0 - j))
        guesses = []
        for di, dj in ((si, 0), (0, sj), (si, sj)):
            if di == 0 and dj == 0:
                continue
            a = centers[i + di, j + dj]
            b = (
                centers[i + 2 * di, j + 2 * dj]
                if 0 <= i + 2 * di < rows and 0 <= j + 2 * dj < cols
                else np.full(2, np.nan)
            )
            if np.isfinite(a).all():
                step = (a - b) if np.isfinite(b).all() else np.array([-dj * wg, -di * hg])
                guesses.append(a + step)
        pred = np.mean(guesses, axis=0) if guesses else _affine_guess(centers, i, j, rough)
        d = pts - pred
        inside = (np.abs(d[:, 0]) < wg / 2) & (np.abs(d[:, 1]) < hg / 2) & ~used
        if not inside.any():
            continue
        cand = np.flatnonzero(inside)
        k = int(cand[np.argmin(np.hypot(*d[cand].T))])
        used[k] = True
        pos, r = _refine(maps, norm, blobs, k, (wg, hg), subpixel)
        centers[i, j] = pos
        radius[i, j] = r
    found = np.isfinite(centers[..., 0]).ravel()
    return DotDetection(
        rows=rows,
        centers=centers.reshape(-1, 2),
        found=found,
        radius=radius.ravel(),
        pitch=(wg, hg),
        cross=np.stack([c0, c1, c2, c3, c4]),
        cols=cols,
        blobs=len(pts),
        blob_uv=pts,
    )

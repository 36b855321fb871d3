"""Threshold distribution map, local binarization and the screen border polygon (sec. 5.2.1-5.2.2a).

All positions are image pixels ``(u, v)``: u to the right, v down, the centre of the
top-left pixel at (0, 0). Images are H x W uint8 (grey) or H x W x 3 uint8 (BGR,
converted to grey by :func:`to_gray`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
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


# ---------------------------------------------------------------- border from white - black


@dataclass(frozen=True)
class ScreenRegion:
    """The screen as the white-minus-black difference shows it.

    ``mask``: H x W bool, the screen's pixels (the largest region where the white
    image is brighter than the black one by more than half the screen's typical
    difference, holes filled). ``contrast``: that typical difference (grey
    levels, median over the mask). ``touches``: image sides ("left", "top",
    ...) the region touches (the screen is cut by the picture's edge).
    ``black_gain``: the white capture's exposure over the black one's
    (:func:`exposure_gain`), by which the black capture was scaled.
    """

    mask: NDArray[np.bool_]
    contrast: float
    touches: tuple[str, ...]
    black_gain: float = 1.0


def _largest(
    binary: NDArray[np.uint8], prefer: NDArray[np.bool_] | None = None
) -> NDArray[np.bool_]:
    """The largest 4-connected region of ``binary`` (the one overlapping ``prefer`` most,
    when given)."""
    count, labels, stats_, _ = cv2.connectedComponentsWithStats(binary, connectivity=4)
    if count <= 1:
        return np.zeros(binary.shape, bool)
    if prefer is not None and prefer.any():
        hits = np.bincount(labels[prefer], minlength=count)
        hits[0] = 0
        k = int(np.argmax(hits))
        if hits[k] > 0:
            return np.asarray(labels == k)
    k = 1 + int(np.argmax(stats_[1:, cv2.CC_STAT_AREA]))
    return np.asarray(labels == k)


def screen_region(white: NDArray[np.uint8], black: NDArray[np.uint8]) -> ScreenRegion:
    """The screen region from the white-minus-black difference.

    Only the screen changes between the two patterns by a large positive amount:
    the room may change (auto-exposure makes it brighter in the black image, a
    window or the screen's spill light may change it), so the threshold is half
    of the screen's own typical difference, found by Otsu's method on the
    positive differences, gives the screen's core (the largest region above it);
    then, in linear light, a pixel is screen where the difference exceeds half of
    the screen's own level nearby (a Gaussian-weighted mean over the core), grown
    from the core twice. A wall point next to the screen cannot join it unless the
    wall itself changed by half as much as the screen did. The linear difference is
    taken with the black image at the white image's exposure (:func:`exposure_gain`);
    pixels at or above ``CLIPPED`` in the black image are not screen.
    """
    wg, bg = to_gray(white), to_gray(black)
    w, b = wg.astype(np.int16), bg.astype(np.int16)
    if w.shape != b.shape:
        raise CalibrationError(f"white image is {w.shape[::-1]}, black image is {b.shape[::-1]}")
    d = w - b
    pos = np.clip(d, 0, 255).astype(np.uint8)
    brighter = int(np.count_nonzero(pos > MIN_CONTRAST))
    darker = int(np.count_nonzero(d < -2 * MIN_CONTRAST))
    if brighter < 0.005 * d.size and darker >= 0.005 * d.size:
        raise CalibrationError(
            "the black image is brighter than the white image: are --white and --black swapped?"
        )
    if brighter < 0.005 * d.size:
        raise CalibrationError(
            "screen not found: the white image is brighter than the black one by more than "
            f"{MIN_CONTRAST} grey levels in {brighter} pixels only (is the screen showing the "
            "patterns, and are --white and --black the right way round?)"
        )
    otsu, _ = cv2.threshold(pos, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    first = pos > max(float(otsu), MIN_CONTRAST)
    contrast = float(np.median(d[first])) if first.any() else 0.0
    if contrast < MIN_CONTRAST:
        raise CalibrationError(
            f"screen not found: white minus black is only {contrast:.0f} grey levels on the "
            f"screen (at least {MIN_CONTRAST}: more display brightness, less room light)"
        )
    # the screen: where the difference, in linear light, exceeds half of the screen's
    # own level nearby (the level varies over the screen: hot spot, viewing angle)
    lin = (np.arange(256) / 255.0) ** 2.2
    core = _largest(first.astype(np.uint8))
    gain = exposure_gain(wg, bg, core)
    dl = (lin[wg] - gain * lin[bg]).astype(np.float32)
    dl[bg >= CLIPPED] = 0.0  # clipped in the black image: how much brighter it was is unknown
    sigma = 0.04 * float(np.hypot(*d.shape))
    for _ in range(2):
        c32 = core.astype(np.float32)
        num = cv2.GaussianBlur(dl * c32, (0, 0), sigma)
        den = cv2.GaussianBlur(c32, (0, 0), sigma)
        level = np.where(den > 1e-3, num / np.maximum(den, 1e-3), np.inf)
        binary = np.asarray(
            cv2.morphologyEx(
                (dl > 0.5 * level).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)
            ),
            np.uint8,
        )
        grown = _largest(binary, prefer=core)
        if not grown.any():
            break
        core = grown
    region = core.astype(np.uint8)
    # fill holes (dark details, an occluder inside the screen stays a notch)
    contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros_like(region)
    cv2.drawContours(filled, contours, -1, (1,), thickness=-1)
    mask = filled.astype(bool)
    h, wd = mask.shape
    touches = tuple(  # a corner's tip on the edge is fine, a cut side is not
        name
        for name, edge in (
            ("top", mask[0, :]),
            ("bottom", mask[h - 1, :]),
            ("left", mask[:, 0]),
            ("right", mask[:, wd - 1]),
        )
        if np.count_nonzero(edge) > max(3, 0.03 * len(edge))
    )
    return ScreenRegion(mask, contrast, touches, gain)


CLIPPED = 250  # grey level: a pixel this bright may be clipped


def exposure_gain(
    white: NDArray[np.uint8], black: NDArray[np.uint8], screen: NDArray[np.bool_]
) -> float:
    """How much brighter the room is in the white image than in the black one, in
    linear light (grey levels undone with gamma 2.2): the median ratio over the pixels
    away from the ``screen`` mask (grey, H x W) that are neither dark nor clipped in
    either image, held to 0.2-5; 1 when fewer than 2 % of the picture qualify.

    Auto-exposure sets the two captures differently (the black screen lets the
    camera open up): the room then changes between them, and near a dim part of the
    screen the room can change more than the screen. Scaled by this gain, the black
    image's room matches the white image's and the difference is the screen's."""
    h, w = screen.shape
    k = max(3, int(0.02 * math.hypot(w, h))) | 1
    near = cv2.dilate(screen.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)
    ok = ~near & (white >= 16) & (white < CLIPPED) & (black >= 16) & (black < CLIPPED)
    if np.count_nonzero(ok) < 0.02 * screen.size:
        return 1.0
    lin = (np.arange(256) / 255.0) ** 2.2
    ratio = lin[white[ok]] / lin[black[ok]]
    return float(np.clip(np.median(ratio), 0.2, 5.0))


def at_exposure(image: NDArray[np.uint8], gain: float) -> NDArray[np.float32]:
    """Grey image (uint8) as it would read with ``gain`` times the light (gamma 2.2,
    float32 grey levels, not clipped at 255); the image itself when ``gain`` is 1."""
    if gain == 1.0:
        return image.astype(np.float32)
    lut = (255.0 * (gain * (np.arange(256) / 255.0) ** 2.2) ** (1 / 2.2)).astype(np.float32)
    out: NDArray[np.float32] = lut[image]
    return out


def _side_fit(pts: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """A robust quadratic fit of contour points ``pts`` near the side a -> b, in the side's
    frame (t along, s across): s = c0 + c1 t + c2 t^2; returns (c0, c1, c2, a, b)-frame
    parameters as an array [c0, c1, c2]. Points off the fit by > max(1.5 px, 3 MAD) are
    dropped (an occluder's notch, a corner's rounding)."""
    e = b - a
    length = float(np.hypot(*e))
    ux = e / length
    uy = np.array([-ux[1], ux[0]])
    t = (pts - a) @ ux
    s = (pts - a) @ uy
    keep = (t > 0.04 * length) & (t < 0.96 * length)
    coef = np.zeros(3)
    for _ in range(6):
        if np.count_nonzero(keep) < 6:
            break
        A = np.column_stack([np.ones(np.count_nonzero(keep)), t[keep], t[keep] ** 2])
        coef, *_ = np.linalg.lstsq(A, s[keep], rcond=None)
        r = s - (coef[0] + coef[1] * t + coef[2] * t * t)
        mad = float(np.median(np.abs(r[keep]))) * 1.4826
        new = keep & (np.abs(r) <= max(1.5, 3.0 * mad))
        if np.array_equal(new, keep):
            break
        keep = new
    return np.asarray(coef, np.float64)


def _side_point(coef: FloatArray, a: FloatArray, b: FloatArray, t: float) -> FloatArray:
    e = b - a
    length = float(np.hypot(*e))
    ux = e / length
    uy = np.array([-ux[1], ux[0]])
    tt = t * length
    s = coef[0] + coef[1] * tt + coef[2] * tt * tt
    return np.asarray(a + tt * ux + s * uy, np.float64)


def _four_corners(hull: FloatArray) -> FloatArray:
    """Four corners of a convex outline (4, 2), clockwise from the top-left one: the
    polygon approximation with exactly four vertices (tolerance searched), else the
    hull points extreme along the diagonals."""
    h32 = hull.astype(np.float32).reshape(-1, 1, 2)
    peri = cv2.arcLength(h32, True)
    quad = None
    lo, hi = 0.001, 0.2
    for _ in range(30):
        eps = math.sqrt(lo * hi)
        approx = cv2.approxPolyDP(h32, eps * peri, True).reshape(-1, 2).astype(np.float64)
        if len(approx) == 4:
            quad = approx
            break
        lo, hi = (eps, hi) if len(approx) > 4 else (lo, eps)
    centre = hull.mean(axis=0)
    if quad is None:
        pts = []
        for dx, dy in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            score = (hull[:, 0] - centre[0]) * dx + (hull[:, 1] - centre[1]) * dy
            pts.append(hull[int(np.argmax(score))])
        return np.array(pts)
    ang = np.arctan2(quad[:, 1] - centre[1], quad[:, 0] - centre[0])
    quad = quad[np.argsort(ang)]  # clockwise on the screen (v down)
    first = int(np.argmin(quad[:, 0] + quad[:, 1]))
    return np.roll(quad, -first, axis=0)


def _corners_and_mids(
    quad: FloatArray, coefs: Sequence[FloatArray]
) -> tuple[list[FloatArray], list[FloatArray]]:
    """Corner i where the fitted sides i-1 and i meet (alternate projections onto the
    two curves, from the rough corner ``quad[i]``; where they wander further than a
    quarter of the shorter side from it, :func:`_closest_approach`) and each side's point
    at its middle; side i's fit (:func:`_side_fit`) is in the frame of quad[i] -> quad[i+1]."""
    corners = []
    for i in range(4):  # corner i: sides i-1 (ending at it) and i (starting at it)
        j = (i - 1) % 4
        p = quad[i].copy()
        reach = 0.25 * _shorter(quad, j, i)  # image px from the rough corner
        for _ in range(20):
            p_old = p
            for k in (j, i):
                a, b = quad[k], quad[(k + 1) % 4]
                e = b - a
                length = float(np.hypot(*e))
                t = float((p - a) @ (e / length)) / length
                p = _side_point(coefs[k], a, b, t)
            if np.hypot(*(p - quad[i])) > reach or np.hypot(*(p - p_old)) < 1e-4:
                break
        if np.hypot(*(p - quad[i])) > reach:
            p = _closest_approach(quad, coefs, j, i)
        corners.append(p)
    mids = [_side_point(coefs[i], quad[i], quad[(i + 1) % 4], 0.5) for i in range(4)]
    return corners, mids


def _shorter(quad: FloatArray, j: int, i: int) -> float:
    """The shorter of the rough sides j and i (image px)."""
    return min(float(np.hypot(*(quad[(k + 1) % 4] - quad[k]))) for k in (j, i))


def _closest_approach(quad: FloatArray, coefs: Sequence[FloatArray], j: int, i: int) -> FloatArray:
    """Corner i where the alternating projections of :func:`_corners_and_mids` do not
    settle near the rough corner (a strongly curved fit swings them away, then to
    infinity): the midpoint of the closest pair of points of side j's end (t in
    0.75..1.25) and side i's start (t in -0.25..0.25), sampled every 1/2000 of a side."""
    t = np.linspace(-0.25, 0.25, 1001)
    a = np.array([_side_point(coefs[j], quad[j], quad[i], 1.0 + x) for x in t])
    b = np.array([_side_point(coefs[i], quad[i], quad[(i + 1) % 4], x) for x in t])
    d = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])
    k, m = np.unravel_index(int(np.argmin(d)), d.shape)
    return np.asarray(0.5 * (a[k] + b[m]), np.float64)


def border_from_region(region: ScreenRegion) -> BorderPolygon:
    """The eight-sided border polygon (P0 top-left corner, P1 top side, ... as
    :class:`BorderPolygon`) fitted to the screen region's outline.

    Rough corners from the convex hull of the outline (an occluder's notch is
    bridged), then each side is a robust quadratic fit to the outline points
    along it (lens distortion bends the sides), each corner the intersection of
    its two sides' fits, each mid-side vertex the side's fit at its middle.
    """
    if region.touches:
        raise CalibrationError(
            "the screen is cut by the picture's "
            + " and ".join(region.touches)
            + " edge: the whole screen must be in the picture (move or turn the camera)"
        )
    m = region.mask.astype(np.uint8)
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(np.float64)
    hull = cv2.convexHull(c.astype(np.float32)).reshape(-1, 2).astype(np.float64)
    quad = _four_corners(hull)
    coefs = []
    for i in range(4):
        a, b = quad[i], quad[(i + 1) % 4]
        e = b - a
        length = float(np.hypot(*e))
        ux = e / length
        uy = np.array([-ux[1], ux[0]])
        t = (c - a) @ ux
        s = (c - a) @ uy
        near = (t > -0.05 * length) & (t < 1.05 * length) & (np.abs(s) < 0.12 * length + 3)
        coefs.append(_side_fit(c[near], a, b))
    corners, mids = _corners_and_mids(quad, coefs)
    # pixel-centre contour -> the edge half a pixel further out (the mask's boundary)
    v = np.array(
        [corners[0], mids[0], corners[1], mids[1], corners[2], mids[2], corners[3], mids[3]]
    )
    out = v + 0.5 * np.sign(v - v.mean(axis=0)) * (np.abs(v - v.mean(axis=0)) > 1)
    return BorderPolygon(np.asarray(out, np.float64))


def border_from_edges(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    border: BorderPolygon,
    black_gain: float = 1.0,
) -> BorderPolygon:
    """``border`` refitted to the sub-pixel edge points (:func:`edge_points`) found
    along it: each side a robust quadratic through its points, corners where the fits
    meet, mid-side vertices the fits at their middles (image px).

    The outline of the thresholded region follows the screen's edge only where the
    white-minus-black difference is well above the threshold: where a projector's or
    a monitor's light falls off toward a corner, or a reflection lies on it, the
    outline turns ragged and cuts in, and the sides fitted to it meet in the wrong
    place (9-18 image px off on the tuning scene 50159, 50 px at the glare of 50036;
    refitted, within 1.2 and 3 px); the edge points take the half-level crossing of
    each profile's own inside and outside levels and do not cut in. Where a side has
    fewer than six edge points, ``border`` is returned as it is. ``black_gain``: as
    for :func:`edge_points`.
    """
    sides = edge_points(white, black, border, black_gain=black_gain)
    v = border.vertices
    quad = v[[0, 2, 4, 6]]
    coefs = []
    for i in range(4):
        a, b = quad[i], quad[(i + 1) % 4]
        pts = sides[i][:, :2]
        if len(pts) < 6:
            return border
        coefs.append(_side_fit(pts, a, b))
    corners, mids = _corners_and_mids(quad, coefs)
    out = np.array(
        [corners[0], mids[0], corners[1], mids[1], corners[2], mids[2], corners[3], mids[3]]
    )
    return BorderPolygon(np.asarray(out, np.float64))


def edge_points(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    border: BorderPolygon,
    *,
    per_side: int = 32,
    gamma: float = 2.2,
    strip: float = 0.4,
    strip_lines: int = 9,
    ends: float = 0.06,
    black_gain: float = 1.0,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Sub-pixel points on the lit area's top, right, bottom and left edges: (K, 4)
    arrays of (u, v, nu, nv), image px and the outward unit normal.

    Along each side of the border polygon, ``per_side`` profiles across the edge of
    the white-minus-black difference, in linear light (grey levels undone with
    ``gamma``): the edge is where the profile crosses halfway between its inside and
    outside levels (a blurred edge crosses there whatever the blur). A profile whose
    inside is not clearly brighter than its outside (an occluder, a corner) is
    dropped.

    Each profile is the mean of ``strip_lines`` parallel ones spread over ``strip``
    of the spacing between profiles on either side (0: one line): compression and
    sensor noise are averaged out, the edge's curvature over a few px is not seen.
    On the tuning scenes of issue 12 one line left 0.05-0.4 image px of noise per
    point. The profiles are measured twice, the second time centred on the first
    crossing. ``black_gain`` scales the black image's linear light first (the white
    capture's exposure over the black one's, :func:`exposure_gain`).
    """
    w = (to_gray(white).astype(np.float32) / 255.0) ** gamma
    b = (to_gray(black).astype(np.float32) / 255.0) ** gamma
    d = np.ascontiguousarray(w - black_gain * b)
    v = border.vertices
    centre = v.mean(axis=0)
    offs = np.arange(-5.0, 5.0001, 0.25)
    out: list[FloatArray] = []
    for side in range(4):
        a, m, c = v[2 * side], v[2 * side + 1], v[(2 * side + 2) % 8]
        t = (np.arange(per_side) + 0.5) / per_side
        t = t[(t > ends) & (t < 1.0 - ends)]
        first = t < 0.5
        p = np.where(
            first[:, None], a + (m - a) * (2 * t)[:, None], m + (c - m) * (2 * t - 1)[:, None]
        )
        tang = np.where(first[:, None], (m - a)[None, :], (c - m)[None, :])
        tang /= np.linalg.norm(tang, axis=1, keepdims=True)
        nrm = np.stack([tang[:, 1], -tang[:, 0]], axis=1)
        flip = ((p - centre) * nrm).sum(axis=1) < 0
        nrm[flip] *= -1  # outward
        reach = strip * (np.linalg.norm(m - a) + np.linalg.norm(c - m)) / per_side
        along = np.linspace(-reach, reach, strip_lines) if strip > 0 and strip_lines > 1 else [0.0]
        o = _edge_crossings(d, p, nrm, tang, offs, along)
        ok = np.isfinite(o)
        p, nrm, tang = p[ok] + o[ok, None] * nrm[ok], nrm[ok], tang[ok]
        # again, centred on the edge: where the polygon's chord strays a few px from a
        # curved edge, the inside and outside levels were taken across the edge
        o = _edge_crossings(d, p, nrm, tang, offs, along)
        ok = np.isfinite(o) & (np.abs(o) < 2.0)
        pts = np.c_[p[ok] + o[ok, None] * nrm[ok], nrm[ok]]
        out.append(np.asarray(pts, np.float64).reshape(-1, 4))
    return out[0], out[1], out[2], out[3]


def _edge_crossings(
    d: NDArray[np.float32],
    p: FloatArray,
    nrm: FloatArray,
    tang: FloatArray,
    offs: FloatArray,
    along: Sequence[float] | FloatArray,
) -> FloatArray:
    """Offset (image px along ``nrm``) of the edge's half-level crossing on each
    profile through ``p``, the profiles averaged over the parallel lines ``along``
    (px along ``tang``); NaN where the profile shows no clear edge within 4 px."""
    if len(p) == 0:  # no profile left on this side (cv2.remap refuses an empty map)
        return np.zeros(0)
    prof = np.zeros((len(p), len(offs)))
    for s_ in along:
        q = p[:, None, :] + offs[None, :, None] * nrm[:, None, :] + s_ * tang[:, None, :]
        prof += cv2.remap(
            d,
            q[..., 0].astype(np.float32),
            q[..., 1].astype(np.float32),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
    prof /= len(along)
    inside = np.median(prof[:, :8], axis=1)  # offsets -5 .. -3.25
    outside = np.median(prof[:, -8:], axis=1)
    half = 0.5 * (inside + outside)
    good = inside - outside > 0.15 * max(float(np.median(inside)), 1e-6)
    out = np.full(len(p), np.nan)
    for k in np.flatnonzero(good):
        s = prof[k] - half[k]
        cross = np.flatnonzero((s[:-1] > 0) & (s[1:] <= 0))
        if len(cross) == 0:
            continue
        j = int(cross[np.argmin(np.abs(offs[cross]))])
        f = s[j] / (s[j] - s[j + 1])
        o = offs[j] + f * (offs[j + 1] - offs[j])
        if abs(o) < 4.0:
            out[k] = o
    return out

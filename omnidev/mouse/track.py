"""The tracking stage of the camera mouse (dissertation sec. 6.2.4-6.2.5).

Each landmark found in the previous frame opens a tracking window five
landmark diameters wide around its last center. Inside the window every
candidate circle (x, y, r) is scored with the deformable circular template of
Fig. 6.6: eight *sampling bars* evenly around the circle, each of ``n``
pixels across the rim, n/2 inside and n/2 outside. A bar's *edge value* is
the sum of its outer minus the sum of its inner gray values (positive for the
landmarks' black circle on a white square); the *fitting measure* F is the sum
over the eight bars. The best candidate is the landmark when F, divided by the
number of sampled pixels pairs (a mean contrast in gray levels), exceeds a
threshold; otherwise the landmark is missing in this frame.

Scoring every center at once is a correlation of the window with a sparse
kernel (+1 on outer bar pixels, -1 on inner ones) at the last radius; the
radii next to it are scored only at the 3 x 3 centers around the best one,
which is refined to sub-pixel by a parabola through the scores around it.
The kernel (2 (r + n/2) + 1 pixels wide) is correlated in a few pieces of
neighbouring bars, each small enough for cv2.filter2D's direct path over
its nonzero taps (a whole kernel of 130 pixels or more goes through a DFT,
several times slower); ``correlate="kernel"`` keeps the one-filter2D form
as the reference. Both sum the same gray levels (the DFT to ~1e-12), so they
give the same centers.

Missing landmarks (sec. 6.2.5): with one or two missing, the dissertation
predicts each by adding the displacement of the found landmarks since the last
frame (their mean) to its last position (``predict="translation"``). Beyond
it, ``predict="similarity"`` carries the missing ones with the rotation, scale
and shift the found ones underwent (exact for motion parallel to the screen;
the translation drifts as soon as the hand turns or moves closer); the default,
``predict="flow"`` (:data:`omnidev.mouse.DEFAULT_PREDICT`, as the plugin and
the CLI), follows the monitor plane's image motion. With three or four missing
the frame is a failure and the caller holds the last cursor.

Coordinates: image pixels, x right, y down, origin at the top-left pixel's center.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.mouse import DEFAULT_PREDICT
from omnidev.mouse.flow import PlaneFlow, apply_h, frame_homography

BARS = 8


@dataclass(frozen=True)
class Circle:
    """A tracked landmark: center (px), radius (px) and mean edge contrast (gray levels)."""

    x: float
    y: float
    r: float
    contrast: float


@lru_cache(maxsize=64)
def template_kernel(r: int, n: int) -> NDArray[np.float32]:
    """The sparse kernel of the eight sampling bars around a circle of radius ``r``.

    Bar pixels lie on the rays at 0, 45, ..., 315 degrees, at integer distances
    r - n/2 .. r - 1 (inner, weight -1) and r + 1 .. r + n/2 (outer, weight +1)
    from the center, rounded to pixels. The kernel's center is the circle's center.
    """
    half = n // 2
    size = 2 * (r + half) + 1
    k = np.zeros((size, size), np.float32)
    c = r + half
    # distances r-half .. r-1 inside, r+1 .. r+half outside: the rim pixel itself
    # (half dark, half bright) is left out, so the bar is symmetric about the edge
    dists = [(d, -1.0) for d in range(r - half, r)] + [(d, 1.0) for d in range(r + 1, r + half + 1)]
    for b in range(BARS):
        t = 2 * math.pi * b / BARS
        for d, w in dists:
            px = math.floor(c + d * math.cos(t) + 0.5)
            py = math.floor(c + d * math.sin(t) + 0.5)
            k[py, px] += w
    k.setflags(write=False)  # cached: shared by every call
    return k


# cv2.filter2D correlates float32 through a DFT once the kernel has 130 pixels or
# more (zeros included); below that it runs directly over the nonzero taps only,
# which for the 8 * n taps of the template is several times faster
_DIRECT_AREA = 121


@dataclass(frozen=True)
class _Piece:
    """Part of the template kernel: ``kernel`` (float32) whose top-left pixel lies
    (dy, dx) pixels from the template's center."""

    dy: int
    dx: int
    kernel: NDArray[np.float32]


def _group_bars(boxes: list[tuple[int, int, int, int]], start: int) -> list[list[int]]:
    """Consecutive bars (from ``start``, going around) merged while their joint
    bounding box (y0, x0, y1, x1, inclusive) stays within ``_DIRECT_AREA`` pixels."""
    groups: list[list[int]] = []
    box: tuple[int, int, int, int] | None = None
    for b in [(start + i) % BARS for i in range(BARS)]:
        y0, x0, y1, x1 = boxes[b]
        if box is not None:
            j = (min(box[0], y0), min(box[1], x0), max(box[2], y1), max(box[3], x1))
            if (j[2] - j[0] + 1) * (j[3] - j[1] + 1) <= _DIRECT_AREA:
                groups[-1].append(b)
                box = j
                continue
        groups.append([b])
        box = boxes[b]
    return groups


@lru_cache(maxsize=64)
def template_pieces(r: int, n: int) -> tuple[_Piece, ...]:
    """The kernel of :func:`template_kernel` cut, along its bars, into as few pieces
    as possible that cv2.filter2D correlates directly (at most ``_DIRECT_AREA``
    pixels each). The pieces' taps are exactly the kernel's, each in one piece."""
    k = template_kernel(r, n)
    c = k.shape[0] // 2
    ys, xs = np.nonzero(k)
    dys, dxs = ys - c, xs - c
    bar = np.rint(np.arctan2(dys, dxs) / (2 * math.pi / BARS)).astype(np.intp) % BARS
    boxes = [
        (int(dys[m].min()), int(dxs[m].min()), int(dys[m].max()), int(dxs[m].max()))
        for m in (bar == b for b in range(BARS))
    ]
    groups = min((_group_bars(boxes, s) for s in range(BARS)), key=len)
    pieces = []
    for g in groups:
        m = np.isin(bar, g)
        y0, x0 = int(dys[m].min()), int(dxs[m].min())
        piece = np.zeros((int(dys[m].max()) - y0 + 1, int(dxs[m].max()) - x0 + 1), np.float32)
        piece[dys[m] - y0, dxs[m] - x0] = k[ys[m], xs[m]]
        piece.setflags(write=False)
        pieces.append(_Piece(y0, x0, piece))
    return tuple(pieces)


@lru_cache(maxsize=64)
def _tap_offsets(r: int, n: int, stride: int) -> tuple[NDArray[np.intp], NDArray[np.float32]]:
    """Flat offsets (9 x taps) of the template's nonzero taps around the 3 x 3 centers
    about a center, in a C-contiguous image of row length ``stride``, and their weights."""
    k = template_kernel(r, n)
    c = k.shape[0] // 2
    ys, xs = np.nonzero(k)
    taps = (ys - c) * stride + (xs - c)
    around = np.array([dy * stride + dx for dy in (-1, 0, 1) for dx in (-1, 0, 1)], np.intp)
    offsets = np.asarray(around[:, None] + taps[None, :], np.intp)
    weights = np.ascontiguousarray(k[ys, xs], np.float32)
    offsets.setflags(write=False)
    weights.setflags(write=False)
    return offsets, weights


def _parabola(a: float, b: float, c: float) -> float:
    """Offset of the vertex of the parabola through (-1, a), (0, b), (1, c), in [-0.5, 0.5]."""
    den = a - 2 * b + c
    if den >= 0:
        return 0.0
    return max(-0.5, min(0.5, 0.5 * (a - c) / den))  # plain floats: np.clip costs ~5 us


def _local_scores(
    patch: NDArray[np.float32], k: NDArray[np.float32], iy: int, ix: int
) -> NDArray[np.float32] | None:
    """Template scores at the 3 x 3 centers around (iy, ix) of ``patch``, or None at its edge."""
    reach = k.shape[0] // 2
    y0, x0 = iy - 1 - reach, ix - 1 - reach
    y1, x1 = iy + 2 + reach, ix + 2 + reach
    if y0 < 0 or x0 < 0 or y1 > patch.shape[0] or x1 > patch.shape[1]:
        return None
    sub = patch[y0:y1, x0:x1]
    out = np.asarray(cv2.filter2D(sub, cv2.CV_32F, k), np.float32)
    return out[reach : reach + 3, reach : reach + 3]


def _window_scores_kernel(patch: NDArray[np.float32], r: int, n: int) -> NDArray[np.float32] | None:
    """Template scores (radius r) at the window's centers where the template fits,
    plus a one-pixel ring around them that reads zeros beyond the window, as
    (h - 2 reach + 2) x (w - 2 reach + 2); None if no center fits. One
    cv2.filter2D with the whole kernel: the straightforward reference."""
    reach = r + n // 2
    h, w = patch.shape
    if h <= 2 * reach or w <= 2 * reach:
        return None
    score = cv2.filter2D(patch, cv2.CV_32F, template_kernel(r, n), borderType=cv2.BORDER_CONSTANT)
    return np.asarray(score, np.float32)[reach - 1 : h - reach + 1, reach - 1 : w - reach + 1]


def _window_scores_pieces(
    padded: NDArray[np.float32], r: int, n: int
) -> NDArray[np.float32] | None:
    """As :func:`_window_scores_kernel`, from the window ``padded`` by one pixel of
    zeros on each side, as a sum of direct correlations with :func:`template_pieces`."""
    reach = r + n // 2
    oh, ow = padded.shape[0] - 2 * reach, padded.shape[1] - 2 * reach
    if oh <= 2 or ow <= 2:
        return None
    out: NDArray[np.float32] | None = None
    for p in template_pieces(r, n):
        ph, pw = p.kernel.shape
        y0, x0 = reach + p.dy, reach + p.dx
        sub = padded[y0 : y0 + oh + ph - 1, x0 : x0 + ow + pw - 1]
        resp = np.asarray(
            cv2.filter2D(sub, cv2.CV_32F, p.kernel, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT),
            np.float32,
        )[:oh, :ow]
        if out is None:
            out = resp  # a view of filter2D's fresh output: ours to add into
        else:
            out += resp
    return out


def track_circle(
    gray: NDArray[np.uint8],
    x: float,
    y: float,
    r: float,
    *,
    n: int = 6,
    radius_steps: int = 1,
    min_contrast: float = 25.0,
    correlate: Literal["pieces", "kernel"] = "pieces",
    streak: bool = True,
    recentre: bool = True,
) -> Circle | None:
    """Find the landmark near its last position (x, y) and radius r, or None.

    Args:
        gray: the frame, H x W uint8.
        x, y, r: last center and radius, pixels.
        n: sampling pixels per bar (n/2 inside, n/2 outside the circle).
        radius_steps: radii tried are round(r) - steps .. round(r) + steps.
        min_contrast: the fitting threshold, as the mean outer-minus-inner gray
            difference per sampled pixel pair.
        correlate: how the scores are computed, with the same result:
            ``"pieces"`` (fast) correlates the kernel cut into pieces that OpenCV
            runs directly over their taps, and sums only the taps of the other
            radii at the 3 x 3 centers; ``"kernel"`` (reference) runs one
            cv2.filter2D per radius with the whole kernel.
        streak: the centre of a motion-blurred landmark is the middle of the
            ridge of scores along its streak (:func:`_plateau_centre`), not the
            ridge's highest point (False: the peak, as the dissertation).
        recentre: when that ridge runs into the side of the centres the window
            can score (a landmark that moved about four radii since the last
            frame), search once more in a window centred on it.
    """
    H, W = gray.shape[:2]
    half_win = math.ceil(5 * r)  # window side = five diameters
    x0, y0 = round(x) - half_win, round(y) - half_win
    x1, y1 = round(x) + half_win + 1, round(y) + half_win + 1
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if cx1 - cx0 < 3 or cy1 - cy0 < 3:
        return None
    r0 = max(round(r), n // 2 + 1)
    lo = max(r0 - radius_steps, n // 2 + 1)
    others = [o for o in range(lo, r0 + radius_steps + 1) if o != r0]
    # every center at the last radius (one correlation), then the radii around
    # it only at the 3 x 3 centers around the best one
    h, w = cy1 - cy0, cx1 - cx0
    if correlate == "pieces":
        # zeros around the window, as the reference's constant border reads them
        padded = np.zeros((h + 2, w + 2), np.float32)
        padded[1:-1, 1:-1] = gray[cy0:cy1, cx0:cx1]
        score = _window_scores_pieces(padded, r0, n)
    elif correlate == "kernel":
        patch = gray[cy0:cy1, cx0:cx1].astype(np.float32)
        score = _window_scores_kernel(patch, r0, n)
    else:
        raise ValueError(f"correlate must be 'pieces' or 'kernel', got {correlate!r}")
    if score is None:
        return None
    # score[i, j] is the center (reach - 1 + i, reach - 1 + j) of the window
    vy, vx = divmod(int(np.argmax(score[1:-1, 1:-1])), score.shape[1] - 2)
    plateau = _plateau_centre(score[1:-1, 1:-1], vy, vx) if streak else None
    reach = r0 + n // 2
    if plateau is not None:
        vy, vx = round(plateau[0]), round(plateau[1])
        edge = (
            (plateau[2] and cy0 == y0)
            or (plateau[3] and cx0 == x0)
            or (plateau[4] and cy1 == y1)
            or (plateau[5] and cx1 == x1)
        )
        if recentre and edge:
            # the ridge runs into the window's side: look again around its middle
            again = track_circle(
                gray,
                float(cx0 + vx + reach),
                float(cy0 + vy + reach),
                r,
                n=n,
                radius_steps=radius_steps,
                min_contrast=min_contrast,
                correlate=correlate,
                streak=streak,
                recentre=False,
            )
            if again is not None:
                return again
    iy, ix = vy + reach, vx + reach
    rr, local = r0, score[vy : vy + 3, vx : vx + 3]
    for other in others:
        if correlate == "kernel":
            cand = _local_scores(patch, template_kernel(other, n), iy, ix)
        else:
            ro = other + n // 2  # the 3 x 3 centers' templates inside the window
            if iy - 1 - ro < 0 or ix - 1 - ro < 0 or iy + 2 + ro > h or ix + 2 + ro > w:
                continue
            offsets, weights = _tap_offsets(other, n, w + 2)
            taps = padded.ravel()[offsets + ((iy + 1) * (w + 2) + ix + 1)]
            cand = (taps @ weights).reshape(3, 3)
        if cand is not None and cand[1, 1] > local[1, 1]:
            rr, local = other, cand
    contrast = float(local[1, 1]) / (BARS * (n // 2))
    if contrast < min_contrast:
        return None
    if plateau is not None:
        dy, dx = plateau[0] - vy, plateau[1] - vx
    else:
        dy = _parabola(float(local[0, 1]), float(local[1, 1]), float(local[2, 1]))
        dx = _parabola(float(local[1, 0]), float(local[1, 1]), float(local[1, 2]))
    return Circle(cx0 + ix + dx, cy0 + iy + dy, float(rr), contrast)


def _plateau_centre(
    score: NDArray[np.float32], vy: int, vx: int, level: float = 0.8
) -> tuple[float, float, bool, bool, bool, bool] | None:
    """The middle (row, column, sub-pixel) of the ridge of template scores around the
    best one (vy, vx), or None where there is no ridge.

    A motion-blurred disc is a streak along which the template fits about equally
    well: its best score lies anywhere on a ridge as long as the blur, so the peak
    (and a parabola through it) wanders along it by px. The ridge is the centres
    scoring ``level`` of the best or more and connected to it; where it reaches 3 px
    or more, its centroid weighted by the score above that level is the streak's
    middle (a sharp disc's peak is narrower: the parabola is kept there). The four
    flags say whether the ridge touches the top, left, bottom, right side of ``score``.
    """
    top = float(score[vy, vx])
    if top <= 0:
        return None
    thr = level * top
    # a sharp peak (the common case) is decided without labelling: a ridge 3 px long
    # reaches the ring two px around the peak, and a ridge has 3 high centres in its 3x3
    b0, b1 = max(vy - 2, 0), min(vy + 3, score.shape[0])
    a0, a1 = max(vx - 2, 0), min(vx + 3, score.shape[1])
    ring = score[b0:b1, a0:a1] >= thr
    ring[max(vy - 1, 0) - b0 : vy + 2 - b0, max(vx - 1, 0) - a0 : vx + 2 - a0] = False
    if not ring.any():
        return None
    y0, y1 = max(vy - 1, 0), min(vy + 2, score.shape[0])
    x0, x1 = max(vx - 1, 0), min(vx + 2, score.shape[1])
    if int(np.count_nonzero(score[y0:y1, x0:x1] >= thr)) < 3:
        return None
    _, labels = cv2.connectedComponents((score >= thr).astype(np.uint8), connectivity=8)
    ys, xs = np.nonzero(labels == labels[vy, vx])
    if max(int(np.ptp(ys)), int(np.ptp(xs))) < 3:
        return None
    w = score[ys, xs].astype(np.float64) - thr
    total = float(w.sum())
    h, wd = score.shape
    return (
        float(w @ ys) / total,
        float(w @ xs) / total,
        int(ys.min()) == 0,
        int(xs.min()) == 0,
        int(ys.max()) == h - 1,
        int(xs.max()) == wd - 1,
    )


def _similarity(src: NDArray[np.float64], dst: NDArray[np.float64]) -> NDArray[np.float64]:
    """The 2 x 3 similarity (rotation, scale, shift) taking two points onto two points."""
    a = complex(*(src[1] - src[0]))
    b = complex(*(dst[1] - dst[0]))
    z = 1 + 0j if abs(a) < 1e-09 else b / a
    R = np.array([[z.real, -z.imag], [z.imag, z.real]])
    t = dst[0] - R @ src[0]
    return np.hstack([R, t[:, None]])


def _rays(p: NDArray[np.float64], f: float, c: tuple[float, float]) -> NDArray[np.float64]:
    """Unit viewing rays (N x 3) of image points (N x 2, px) of a pinhole camera."""
    d = np.column_stack([(p[:, 0] - c[0]) / f, (p[:, 1] - c[1]) / f, np.ones(len(p))])
    out: NDArray[np.float64] = d / np.linalg.norm(d, axis=1, keepdims=True)
    return out


def rotate_points(
    p: NDArray[np.float64], R: NDArray[np.float64], f: float, c: tuple[float, float]
) -> NDArray[np.float64]:
    """Image points (N x 2, px) after the camera turned by R about its center."""
    d = _rays(p, f, c) @ R.T
    z = np.where(d[:, 2] > 1e-6, d[:, 2], 1e-6)
    return np.column_stack([c[0] + f * d[:, 0] / z, c[1] + f * d[:, 1] / z])


def rotation_between(
    src: NDArray[np.float64], dst: NDArray[np.float64], f: float, c: tuple[float, float]
) -> NDArray[np.float64]:
    """The camera rotation (3 x 3) about its center that best carries ``src`` onto ``dst``.

    Points (N x 2, N >= 2) in pixels of a pinhole camera with focal length f and
    principal point c. Least squares on the viewing rays (orthogonal
    Procrustes / Kabsch), which is exact for a camera turning in place, the way
    a hand aims a webcam.
    """
    a, b = _rays(src, f, c), _rays(dst, f, c)
    U, _, Vt = np.linalg.svd(b.T @ a)
    D = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(U @ Vt)))])
    R: NDArray[np.float64] = U @ D @ Vt
    return R


def rotation_and_focal(
    src: NDArray[np.float64],
    dst: NDArray[np.float64],
    c: tuple[float, float],
    fov_deg: tuple[float, float] = (25.0, 130.0),
    steps: int = 43,
) -> tuple[NDArray[np.float64], float]:
    """The camera rotation (3 x 3) and focal length (px) that best carry ``src`` onto
    ``dst`` (N x 2 pixels, N >= 2) for a pinhole camera turning about its centre with
    principal point ``c``: :func:`rotation_between` at each of ``steps`` focal lengths
    spanning the horizontal field of view ``fov_deg`` (image width 2 c_x + 1), the one
    with the least squared reprojection error kept."""
    half = c[0] + 0.5
    fs = half / np.tan(np.radians(np.linspace(fov_deg[0], fov_deg[1], steps)) / 2)

    def rays(p: NDArray[np.float64]) -> NDArray[np.float64]:
        d = np.empty((len(fs), len(p), 3))
        d[:, :, 0] = (p[:, 0] - c[0])[None, :] / fs[:, None]
        d[:, :, 1] = (p[:, 1] - c[1])[None, :] / fs[:, None]
        d[:, :, 2] = 1.0
        out: NDArray[np.float64] = d / np.linalg.norm(d, axis=2, keepdims=True)
        return out

    a, b = rays(src), rays(dst)
    U, _, Vt = np.linalg.svd(np.einsum("fni,fnj->fij", b, a))
    det = np.sign(np.linalg.det(U @ Vt))
    U[:, :, 2] *= det[:, None]
    R = U @ Vt  # (F, 3, 3)
    q = np.einsum("fij,fnj->fni", R, a)
    z = np.where(q[:, :, 2] > 1e-6, q[:, :, 2], 1e-6)
    err = (c[0] + fs[:, None] * q[:, :, 0] / z - dst[None, :, 0]) ** 2 + (
        c[1] + fs[:, None] * q[:, :, 1] / z - dst[None, :, 1]
    ) ** 2
    k = int(np.argmin(err.sum(axis=1)))
    return np.asarray(R[k], np.float64), float(fs[k])


def turn_extrapolates_better(
    ref: NDArray[np.float64],
    cur: NDArray[np.float64],
    ref_found: NDArray[np.float64],
    cur_found: NDArray[np.float64],
    ref_missing: NDArray[np.float64],
    c: tuple[float, float],
    weight: int,
    hold: float = 0.25,
    min_features: int = 16,
) -> tuple[NDArray[np.float64], float] | None:
    """Whether a camera turn (:func:`rotation_and_focal`, 4 parameters) should carry the
    missing landmarks rather than the monitor plane's homography (8): the rotation and
    focal fitted to the plane's features (``ref`` -> ``cur``, N x 2, the homography's
    inliers) and the found landmarks (weighted ``weight`` times), or None for the
    homography.

    A homography fitted to features bunched on one side of the monitor extrapolates
    badly to a landmark far outside them, a turn is stiffer but ignores the hand's
    shift. The test is the extrapolation itself: the ``hold`` share of features nearest
    the missing landmarks (reference positions ``ref_missing``) is left out, both models
    are fitted to the rest, and the one that carries the left-out features closer (median
    px) wins. Below ``min_features`` features the turn is taken."""
    if len(ref) >= min_features:
        d = np.linalg.norm(ref[:, None, :] - ref_missing[None, :, :], axis=2).min(axis=1)
        out = d <= np.quantile(d, hold)
        src = np.concatenate([ref[~out]] + [ref_found] * weight)
        dst = np.concatenate([cur[~out]] + [cur_found] * weight)
        H, _ = cv2.findHomography(src, dst, 0)
        if H is None:
            return None
        R, f = rotation_and_focal(src, dst, c)
        plane = apply_h(np.asarray(H, np.float64), ref[out])
        e_plane = np.median(np.linalg.norm(plane - cur[out], axis=1))
        e_turn = np.median(np.linalg.norm(rotate_points(ref[out], R, f, c) - cur[out], axis=1))
        if e_turn >= e_plane:
            return None
    src = np.concatenate([ref] + [ref_found] * weight)
    dst = np.concatenate([cur] + [cur_found] * weight)
    return rotation_and_focal(src, dst, c)


def _bar_length(n: int, r: float) -> int:
    """Sampling-bar length for a landmark of radius ``r`` px: ``n``, shortened (even, >= 2)
    so that its inner half stays inside a small disc (r < n/2 + 1 at 320 x 240)."""
    return max(2, min(n, 2 * int(0.7 * r)))


def _similarity_lsq(src: NDArray[np.float64], dst: NDArray[np.float64]) -> NDArray[np.float64]:
    """The 2 x 3 least-squares similarity taking points ``src`` (N x 2) onto ``dst``, N >= 2.

    As complex numbers, dst = a src + b with a = s e^{i theta}: linear least
    squares about the centroids.
    """
    a, b = _similarity_c([complex(*p) for p in src], [complex(*p) for p in dst])
    return np.array([[a.real, -a.imag, b.real], [a.imag, a.real, b.imag]])


def _similarity_c(zs: list[complex], zd: list[complex]) -> tuple[complex, complex]:
    """(a, b) of the least-squares dst = a src + b on complex points (plain Python: the
    tracker calls it a dozen times a frame on four points, where numpy costs more)."""
    n = len(zs)
    ms, md = sum(zs) / n, sum(zd) / n
    den = sum(abs(z - ms) ** 2 for z in zs)
    a = sum((u - ms).conjugate() * (v - md) for u, v in zip(zs, zd, strict=True)) / den
    a = a if den > 1e-12 else 1 + 0j
    return a, md - a * ms


def refine_center(
    gray: NDArray[np.uint8], x: float, y: float, r: float, iterations: int = 2
) -> tuple[float, float]:
    """The dark disc's centroid near (x, y) (px): sub-pixel and unbiased by motion blur.

    The template's best score is flat along a motion-blurred streak, so its
    peak wanders along it; the centroid of darkness, w = clip((hi - I) / (hi -
    lo), 0, 1) with lo/hi the 5th/95th grey percentiles, inside a circle of
    radius 1.4 r (inside the landmark's white square), is symmetric about the
    streak's middle. Iterated from the template's center. ``r`` should be the
    disc's radius from the landmark geometry (:attr:`LandmarkTracker.disc_radii`):
    the template's whole-pixel radius may be 0.7 px too big, which at 320 x 240
    lets the circle reach the dark bezel.
    """
    H, W = gray.shape[:2]
    R = math.ceil(1.4 * r)
    mask = _disc_mask(R, 1.4 * r)
    g = _offsets(R)
    lo = hi = 0.0
    for k in range(iterations):
        ix, iy = round(x), round(y)
        if ix - R < 0 or iy - R < 0 or ix + R >= W or iy + R >= H:
            break
        patch = gray[iy - R : iy + R + 1, ix - R : ix + R + 1].astype(np.float32)
        if k == 0:  # the grey levels of disc and square, from the first window
            flat = patch.ravel()
            i5, i95 = int(0.05 * (flat.size - 1)), int(0.95 * (flat.size - 1))
            part = np.partition(flat, (i5, i95))
            lo, hi = float(part[i5]), float(part[i95])
            if hi - lo < 1:
                break
        w = np.clip((hi - patch) * (1.0 / (hi - lo)), 0, 1) * mask
        total = float(w.sum())
        if total <= 0:
            break
        x = ix + float(w.sum(axis=0) @ g) / total
        y = iy + float(w.sum(axis=1) @ g) / total
    return x, y


@lru_cache(maxsize=64)
def _offsets(R: int) -> NDArray[np.float32]:
    g = np.arange(-R, R + 1, dtype=np.float32)
    g.setflags(write=False)
    return g


@lru_cache(maxsize=64)
def _disc_mask(R: int, radius: float) -> NDArray[np.float32]:
    g = np.arange(-R, R + 1, dtype=np.float32)
    m = (g[None, :] ** 2 + g[:, None] ** 2 <= radius * radius).astype(np.float32)
    m.setflags(write=False)
    return m


def _off_plane(
    new: NDArray[np.float64], found: list[bool], pred: NDArray[np.float64], tol: float
) -> list[int]:
    """Found landmarks (indices) to drop as not where the monitor plane's motion put them.

    A hit farther than ``tol`` px from its prediction ``pred`` (4, 2) is taken for an
    impostor. (Accepting hits that share one offset from a drifted prediction found
    more landmarks again but let impostors through on the tuning seeds: refused.)
    """
    idx = [i for i in range(4) if found[i]]
    dev = new - pred
    far = [i for i in idx if float(np.hypot(*dev[i])) > tol]
    if not far:
        return []
    return far


@dataclass
class LandmarkTracker:
    """Tracks the four landmarks (TL, TR, BR, BL) frame to frame with prediction.

    Attributes:
        centers: last positions (4 x 2), found or predicted; None before the first lock.
        radius: median landmark radius in pixels.
        radii: each landmark's radius in pixels (from detection, updated by
            tracking: an oblique view makes the far landmarks smaller).
        found: which landmarks were found (not predicted) in the last frame.
        contrast: running mean edge contrast of found landmarks; a hit below
            ``relative_contrast`` of it (a landmark cut by the image border)
            counts as missing.
    """

    n: int = 6
    min_contrast: float = 25.0
    relative_contrast: float = 0.6
    predict: str = DEFAULT_PREDICT
    motion: bool = True
    consistency: bool = True
    back_tol: float = 2.0
    focal_px: float | None = None
    disc_radii: NDArray[np.float64] | None = None
    principal: tuple[float, float] = (0.0, 0.0)
    refine: bool = True
    centers: NDArray[np.float64] | None = None
    previous: NDArray[np.float64] | None = None
    contrast: float = 0.0
    radius: float = 0.0
    radii: NDArray[np.float64] = field(default_factory=lambda: np.zeros(4))
    found: list[bool] = field(default_factory=lambda: [False] * 4)
    flow: PlaneFlow = field(default_factory=PlaneFlow)
    flow_tol: float = 0.8
    ref_centers: NDArray[np.float64] | None = None
    prev_gray: NDArray[np.uint8] | None = None
    predicted_by: str = ""
    coast_frames: int = 60
    coasting: int = 0

    def lock(
        self,
        centers: NDArray[np.float64],
        radius: float | NDArray[np.float64],
        gray: NDArray[np.uint8] | None = None,
    ) -> None:
        """Start tracking from the detection stage's four centers (TL, TR, BR, BL),
        measured on the grey frame ``gray`` (the previous frame for the next update's
        image motion; None: no image motion until a frame has been tracked). A frame
        kept from before the lock, with these centers, gave flow a wrong plane motion
        (held-out video 50270: a cursor 971 px off right after a re-detection)."""
        self.prev_gray = gray
        self.centers = np.asarray(centers, np.float64).reshape(4, 2).copy()
        self.previous = None
        self.radii = np.broadcast_to(np.asarray(radius, np.float64), (4,)).copy()
        self.radius = statistics.median(self.radii.tolist())
        self.found = [True] * 4
        self.contrast = 0.0
        self.flow.stop()
        self.coasting = 0

    def _outliers(
        self, new: NDArray[np.float64], found: list[bool], guess: NDArray[np.float64]
    ) -> list[int]:
        """Found landmarks whose move disagrees with the others' (a false match).

        Landmarks found in both frames are checked against their neighbours'
        motion. With a velocity (two frames tracked), each one's surprise, its
        position minus where its own last move would have carried it, should
        equal the others': a hand's jerk or turn surprises all four alike,
        while a landmark that jumped to screen content or the bezel stands
        out. The worst is dropped while it lies farther than the tolerance
        from the median surprise of the others, two landmarks always remain.
        Right after a lock, the three whose moves agree best on a
        least-squares similarity judge the fourth instead. A landmark found
        again after being predicted must lie within ``back_tol`` tolerances of
        where the reliable ones' move (a similarity) carries its predicted
        position. The tolerance, max(5 px, radius) + 15 % of the median move,
        allows for motion blur and the perspective change of a fast turn.
        """
        assert self.centers is not None
        idx = [i for i, ok in enumerate(found) if ok and self.found[i]]
        back = [i for i, ok in enumerate(found) if ok and not self.found[i]]
        if len(idx) < 2:
            return []
        zo = [complex(*p) for p in self.centers]
        zn = [complex(*p) for p in new]
        move = statistics.median(abs(zn[i] - zo[i]) for i in idx)
        tol = max(5.0, self.radius) + 0.15 * move
        dropped: list[int] = []
        if self.previous is not None and self.motion:
            surprise = {i: zn[i] - complex(*guess[i]) for i in idx}
            while len(idx) >= 3:
                dev = []
                for i in idx:
                    others = [surprise[j] for j in idx if j != i]
                    ref = complex(
                        statistics.median(z.real for z in others),
                        statistics.median(z.imag for z in others),
                    )
                    dev.append(abs(surprise[i] - ref))
                worst = int(np.argmax(dev))
                if dev[worst] <= tol:
                    break
                dropped.append(idx.pop(worst))
        elif len(idx) == 4:
            best: tuple[float, int, float] | None = None
            for i in idx:
                rest = [j for j in idx if j != i]
                a, b = _similarity_c([zo[j] for j in rest], [zn[j] for j in rest])
                internal = math.sqrt(sum(abs(a * zo[j] + b - zn[j]) ** 2 for j in rest) / 3)
                res = abs(a * zo[i] + b - zn[i])
                if best is None or internal < best[0]:
                    best = (internal, i, res)
            assert best is not None
            internal, i, res = best
            if res > tol + 2 * internal:
                dropped.append(i)
                idx.remove(i)
        if back:
            a, b = _similarity_c([zo[j] for j in idx], [zn[j] for j in idx])
            dropped += [i for i in back if abs(a * zo[i] + b - zn[i]) > self.back_tol * tol]
        return dropped

    def _search(self, gray: NDArray[np.uint8], guess: NDArray[np.float64]) -> list[Circle | None]:
        """The template's best circle in each window centred at ``guess`` (4, 2), None
        where it falls short of the contrast floors."""
        hits = [
            track_circle(
                gray,
                float(cx),
                float(cy),
                float(r),
                n=_bar_length(self.n, float(r)),
                min_contrast=self.min_contrast,
            )
            for (cx, cy), r in zip(guess, self.radii, strict=True)
        ]
        # A landmark cut by the image border still half-fits the template: a hit
        # must reach a good part of the contrast the landmarks had so far.
        floor = self.relative_contrast * self.contrast
        return [h if h is not None and h.contrast >= floor else None for h in hits]

    def _coast(
        self, gray: NDArray[np.uint8], found: list[bool], new: NDArray[np.float64] | None
    ) -> None:
        """Fewer than two landmarks found: no cursor (the dissertation's hold). With
        ``predict="flow"`` the four positions keep following the monitor plane's image
        motion for up to ``coast_frames`` frames (``coasting`` counts them), so that
        landmarks coming back are tracked where they reappear without waiting for all
        four (the detection stage needs them all); otherwise, or when the plane's
        features give out, the lock is lost (``coasting`` = 0)."""
        self.found = found
        prev = self.prev_gray
        self.prev_gray = gray
        if self.predict != "flow" or prev is None or self.centers is None:
            self.coasting = 0
            return None
        if self.coasting >= self.coast_frames:
            self.coasting = 0
            return None
        if not self.flow.active:
            self.flow.start(prev, self.centers)
            self.ref_centers = self.centers.copy()
            self.flow.step(gray)
        elif self.flow.gray is not gray:
            self.flow.step(gray)
        assert self.ref_centers is not None
        idx = [i for i, ok in enumerate(found) if ok and new is not None]
        H = self.flow.fit(self.ref_centers[idx], new[idx] if new is not None else np.zeros((0, 2)))
        if H is None:
            self.coasting = 0
            return None
        pred = apply_h(H, self.ref_centers)
        self.previous, self.centers = self.centers, pred
        self.flow.replenish(gray, pred)
        self.coasting += 1
        return None

    def _judged(self, found: list[bool]) -> list[bool]:
        """The found landmarks the plane's motion may judge: those found in the last
        frame too. A landmark coming back after being predicted has no measured position
        for the plane to carry (its prediction, a few px off after a sweep, would reject
        the landmark itself); the return check of :meth:`_outliers` judges it. While
        coasting (fewer than two found in the last frame) the plane judges every one: its
        motion is all the positions rest on (tuning video 151: exempted, two landmarks
        coming back kept the cursor 48 px off for 20 frames)."""
        if sum(self.found) < 2:
            return list(found)
        return [ok and was for ok, was in zip(found, self.found, strict=True)]

    def _plane_guess(self, gray: NDArray[np.uint8]) -> NDArray[np.float64] | None:
        """Where the monitor plane's frame-to-frame homography carries the last centres."""
        assert self.prev_gray is not None and self.centers is not None
        Hff = frame_homography(self.prev_gray, gray, self.centers)
        return None if Hff is None else apply_h(Hff, self.centers)

    def update(self, gray: NDArray[np.uint8]) -> NDArray[np.float64] | None:
        """The four centers in this frame (missing ones predicted), or None on failure.

        None (three or more landmarks missing, or never locked) means: hold the
        last cursor and run the detection stage again.
        """
        if self.centers is None:
            return None
        # Beyond the dissertation (which centres each window on the last position):
        # centre it where the last frame-to-frame move carries the landmark, so a
        # fast sweep does not leave the window or land on the bezel next to it.
        guess = self.centers
        if self.motion and self.previous is not None:
            guess = self.centers + (self.centers - self.previous)
        # Beyond it again (predict="flow"): when the hand moves fast or a landmark is
        # missing, the monitor plane's frame-to-frame homography from tracked features
        # places the windows (a sweep's acceleration defeats the constant-velocity guess)
        # and judges the hits (a blurred impostor is not where the plane went).
        plane_guess: NDArray[np.float64] | None = None
        use_flow = self.predict == "flow" and self.prev_gray is not None
        if use_flow:
            assert self.prev_gray is not None
            step = 0.0
            if self.previous is not None:
                step = float(np.median(np.linalg.norm(self.centers - self.previous, axis=1)))
            if step > max(3.0, 0.5 * self.radius) or not all(self.found):
                plane_guess = self._plane_guess(gray)
                if plane_guess is not None:
                    guess = plane_guess
        hits = self._search(gray, guess)
        if use_flow and plane_guess is None:
            # the hits say the hand jerked (or some are missing): look again where the
            # monitor plane went
            jump = [h is None or math.hypot(h.x - g[0], h.y - g[1]) > max(3.0, 0.5 * self.radius)
                    for h, g in zip(hits, guess, strict=True)]  # fmt: skip
            if any(jump):
                plane_guess = self._plane_guess(gray)
                if plane_guess is not None:
                    hits = self._search(gray, plane_guess)
        found = [h is not None for h in hits]
        if sum(found) < 2:
            self._coast(gray, found, None)
            return None
        if self.refine:
            disc = [None] * 4 if self.disc_radii is None else list(self.disc_radii)
            hits = [
                None
                if h is None
                else Circle(
                    *refine_center(gray, h.x, h.y, h.r if rd is None else float(rd)),
                    h.r,
                    h.contrast,
                )
                for h, rd in zip(hits, disc, strict=True)
            ]
        new = self.centers.copy()
        for i, h in enumerate(hits):
            if h is not None:
                new[i] = (h.x, h.y)
        if plane_guess is not None:
            moved = float(np.median(np.linalg.norm(plane_guess - self.centers, axis=1)))
            tol = max(5.0, self.flow_tol * self.radius) + 0.1 * moved
            for i in _off_plane(new, self._judged(found), plane_guess, tol):
                found[i], hits[i], new[i] = False, None, self.centers[i]
            if sum(found) < 2:
                self._coast(gray, found, new)
                return None
        if self.consistency:
            for i in self._outliers(new, found, guess):
                found[i], hits[i], new[i] = False, None, self.centers[i]
        if self.predict == "flow" and self.flow.active and self.ref_centers is not None:
            # the monitor plane's own motion judges the landmarks found: one that is
            # not where the plane carried it (a blurred impostor) is dropped
            self.flow.step(gray)
            Hf = self.flow.fit(np.zeros((0, 2)), np.zeros((0, 2)))
            if Hf is not None:
                pred = apply_h(Hf, self.ref_centers)
                moved = float(np.median(np.linalg.norm(pred - self.centers, axis=1)))
                tol = max(5.0, self.flow_tol * self.radius) + 0.1 * moved
                for i in _off_plane(new, self._judged(found), pred, tol):
                    found[i], hits[i], new[i] = False, None, self.centers[i]
                if sum(found) < 2:
                    self._coast(gray, found, new)
                    return None
        moves = [
            (h.x - self.centers[i, 0], h.y - self.centers[i, 1])
            for i, h in enumerate(hits)
            if h is not None
        ]
        missing = [i for i, ok in enumerate(found) if not ok]
        self.predicted_by = ""
        if missing and self.predict == "flow":
            # the homography of the monitor plane from the reference frame (the last
            # one before a landmark went missing), fitted to tracked features and the
            # landmarks still found, carries the missing ones
            if not self.flow.active and self.prev_gray is not None:
                self.flow.start(self.prev_gray, self.centers)
                self.ref_centers = self.centers.copy()
                self.flow.step(gray)
            if self.flow.active and self.ref_centers is not None:
                idx = [i for i, ok in enumerate(found) if ok]
                H = self.flow.fit(self.ref_centers[idx], new[idx])
                turn = None
                if H is not None and self.focal_px:
                    turn = turn_extrapolates_better(
                        self.flow.ref, self.flow.cur, self.ref_centers[idx], new[idx],
                        self.ref_centers[missing], self.principal, self.flow.landmark_weight,
                    )  # fmt: skip
                if turn is not None:
                    R, f = turn
                    c = self.principal
                    new[missing] = rotate_points(self.ref_centers[missing], R, f, c)
                    self.flow.replenish(gray, new, lambda p: rotate_points(p, R.T, f, c))
                    missing = []
                    self.predicted_by = "flow-turn"
                elif H is not None:
                    new[missing] = apply_h(H, self.ref_centers[missing])
                    self.flow.replenish(gray, new)
                    missing = []
                    self.predicted_by = "flow"
            if missing and self.focal_px:  # too few features: the camera's turn
                idx = [i for i, ok in enumerate(found) if ok]
                R = rotation_between(self.centers[idx], new[idx], self.focal_px, self.principal)
                new[missing] = rotate_points(
                    self.centers[missing], R, self.focal_px, self.principal
                )
                missing = []
                self.predicted_by = "rotation"
        elif self.predict == "flow":
            self.flow.stop()
        if missing and self.predict == "similarity":
            # rotation, scale and shift of the found landmarks since the last frame
            # (exact for motion parallel to the screen), applied to the missing ones
            idx = [i for i, ok in enumerate(found) if ok]
            M, _ = (
                cv2.estimateAffinePartial2D(
                    self.centers[idx].astype(np.float32),
                    new[idx].astype(np.float32),
                    method=cv2.LMEDS,
                )
                if len(idx) > 2
                else (_similarity(self.centers[idx], new[idx]), None)
            )
            if M is not None:
                for i in missing:
                    new[i] = M[:, :2] @ self.centers[i] + M[:, 2]
                missing = []
        if missing and self.predict == "rotation":
            idx = [i for i, ok in enumerate(found) if ok]
            f = self.focal_px or 0.0
            if f > 0:
                R = rotation_between(self.centers[idx], new[idx], f, self.principal)
                new[missing] = rotate_points(self.centers[missing], R, f, self.principal)
                missing = []
        if missing:  # the dissertation's prediction: the found landmarks' displacement
            shift = np.mean(np.array(moves), axis=0)
            for i in missing:
                new[i] = self.centers[i] + shift
        for i, h in enumerate(hits):
            if h is not None:
                self.radii[i] = h.r
        self.radius = statistics.median(self.radii.tolist())
        contrasts = [h.contrast for h in hits if h is not None]
        self.contrast = (
            statistics.median(contrasts)
            if self.contrast == 0
            else 0.9 * self.contrast + 0.1 * statistics.median(contrasts)
        )
        self.previous, self.centers = self.centers, new
        self.found = found
        self.prev_gray = gray
        self.coasting = 0
        return new.copy()

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
it, and the default, ``predict="similarity"`` carries the missing ones with
the rotation, scale and shift the found ones underwent (exact for motion
parallel to the screen; the translation drifts as soon as the hand turns or
moves closer). With three or four missing the frame is a failure and the
caller holds the last cursor.

Coordinates: image pixels, x right, y down, origin at the top-left pixel's center.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

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
    reach = r0 + n // 2
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
    dy = _parabola(float(local[0, 1]), float(local[1, 1]), float(local[2, 1]))
    dx = _parabola(float(local[1, 0]), float(local[1, 1]), float(local[1, 2]))
    return Circle(cx0 + ix + dx, cy0 + iy + dy, float(rr), contrast)


def _similarity(src: NDArray[np.float64], dst: NDArray[np.float64]) -> NDArray[np.float64]:
    """The 2 x 3 similarity (rotation, scale, shift) taking two points onto two points."""
    a = complex(*(src[1] - src[0]))
    b = complex(*(dst[1] - dst[0]))
    z = 1 + 0j if abs(a) < 1e-09 else b / a
    R = np.array([[z.real, -z.imag], [z.imag, z.real]])
    t = dst[0] - R @ src[0]
    return np.hstack([R, t[:, None]])


@dataclass
class LandmarkTracker:
    """Tracks the four landmarks (TL, TR, BR, BL) frame to frame with prediction.

    Attributes:
        centers: last positions (4 x 2), found or predicted; None before the first lock.
        radius: landmark radius in pixels (from detection, updated by tracking).
        found: which landmarks were found (not predicted) in the last frame.
        contrast: running mean edge contrast of found landmarks; a hit below
            ``relative_contrast`` of it (a landmark cut by the image border)
            counts as missing.
    """

    n: int = 6
    min_contrast: float = 25.0
    relative_contrast: float = 0.6
    predict: str = "similarity"
    centers: NDArray[np.float64] | None = None
    contrast: float = 0.0
    radius: float = 0.0
    found: list[bool] = field(default_factory=lambda: [False] * 4)

    def lock(self, centers: NDArray[np.float64], radius: float) -> None:
        """Start tracking from the detection stage's four centers (TL, TR, BR, BL)."""
        self.centers = np.asarray(centers, np.float64).reshape(4, 2).copy()
        self.radius = float(radius)
        self.found = [True] * 4
        self.contrast = 0.0

    def update(self, gray: NDArray[np.uint8]) -> NDArray[np.float64] | None:
        """The four centers in this frame (missing ones predicted), or None on failure.

        None (three or more landmarks missing, or never locked) means: hold the
        last cursor and run the detection stage again.
        """
        if self.centers is None:
            return None
        hits = [
            track_circle(
                gray, float(cx), float(cy), self.radius, n=self.n, min_contrast=self.min_contrast
            )
            for cx, cy in self.centers
        ]
        # A landmark cut by the image border still half-fits the template: a hit
        # must reach a good part of the contrast the landmarks had so far.
        floor = self.relative_contrast * self.contrast
        hits = [h if h is not None and h.contrast >= floor else None for h in hits]
        found = [h is not None for h in hits]
        if sum(found) < 2:
            self.found = found
            return None
        new = self.centers.copy()
        moves = []
        for i, h in enumerate(hits):
            if h is not None:
                moves.append((h.x - self.centers[i, 0], h.y - self.centers[i, 1]))
                new[i] = (h.x, h.y)
        missing = [i for i, ok in enumerate(found) if not ok]
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
        if missing:  # the dissertation's prediction: the found landmarks' displacement
            shift = np.mean(np.array(moves), axis=0)
            for i in missing:
                new[i] = self.centers[i] + shift
        radii = [h.r for h in hits if h is not None]
        self.radius = float(np.median(radii))
        contrasts = [h.contrast for h in hits if h is not None]
        self.contrast = (
            float(np.median(contrasts))
            if self.contrast == 0
            else max(0.9 * self.contrast + 0.1 * float(np.median(contrasts)), 0.0)
        )
        self.centers = new
        self.found = found
        return new.copy()

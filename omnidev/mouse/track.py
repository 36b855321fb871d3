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
kernel (+1 on outer bar pixels, -1 on inner ones), one ``cv2.filter2D`` per
radius; the best center is refined to sub-pixel by a parabola through the
scores around it.

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


def _parabola(a: float, b: float, c: float) -> float:
    """Offset of the vertex of the parabola through (-1, a), (0, b), (1, c), in [-0.5, 0.5]."""
    den = a - 2 * b + c
    if den >= 0:
        return 0.0
    return float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))


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


def track_circle(
    gray: NDArray[np.uint8],
    x: float,
    y: float,
    r: float,
    *,
    n: int = 6,
    radius_steps: int = 1,
    min_contrast: float = 25.0,
) -> Circle | None:
    """Find the landmark near its last position (x, y) and radius r, or None.

    Args:
        gray: the frame, H x W uint8.
        x, y, r: last center and radius, pixels.
        n: sampling pixels per bar (n/2 inside, n/2 outside the circle).
        radius_steps: radii tried are round(r) - steps .. round(r) + steps.
        min_contrast: the fitting threshold, as the mean outer-minus-inner gray
            difference per sampled pixel pair.
    """
    H, W = gray.shape[:2]
    half_win = math.ceil(5 * r)  # window side = five diameters
    x0, y0 = round(x) - half_win, round(y) - half_win
    x1, y1 = round(x) + half_win + 1, round(y) + half_win + 1
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if cx1 - cx0 < 3 or cy1 - cy0 < 3:
        return None
    patch = gray[cy0:cy1, cx0:cx1].astype(np.float32)
    r0 = max(round(r), n // 2 + 1)
    # every center at the last radius (one correlation), then the radii around
    # it only at the 3 x 3 centers around the best one
    k0 = template_kernel(r0, n)
    reach = r0 + n // 2
    score = np.asarray(
        cv2.filter2D(patch, cv2.CV_32F, k0, borderType=cv2.BORDER_CONSTANT), np.float32
    )
    valid = score[reach : score.shape[0] - reach, reach : score.shape[1] - reach]
    if valid.size == 0:
        return None
    vy, vx = divmod(int(np.argmax(valid)), valid.shape[1])
    iy, ix = vy + reach, vx + reach
    rr, local = r0, score[iy - 1 : iy + 2, ix - 1 : ix + 2]
    for other in range(max(r0 - radius_steps, n // 2 + 1), r0 + radius_steps + 1):
        if other == r0:
            continue
        cand = _local_scores(patch, template_kernel(other, n), iy, ix)
        if cand is not None and cand[1, 1] > local[1, 1]:
            rr, local = other, cand
    contrast = float(local[1, 1]) / (BARS * (n // 2))
    if contrast < min_contrast:
        return None
    dy = dx = 0.0
    if local.shape == (3, 3):
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

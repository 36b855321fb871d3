"""Image motion of the monitor plane, for predicting landmarks out of the picture (issue 13).

While one or two landmarks are missing, :class:`PlaneFlow` follows corner features on
the monitor (bezel, the landmark cards and what lies just around them; screen content
too unless ``exclude`` names the screen: a video or a scrolling page moves on it) from a
*reference* frame (the last frame before a landmark went missing) through every later
frame by pyramidal Lucas-Kanade, checked forwards and backwards. The homography from the
reference to the current frame, fitted by RANSAC to the surviving features together with
the landmarks still found (weighted as many features), carries the missing landmarks'
reference positions into the current frame (the tracker may take a camera turn fitted to
the same points instead, :func:`omnidev.mouse.track.turn_extrapolates_better`).
Measuring from the reference rather than chaining frame-to-frame predictions keeps the
error from accumulating; features that leave the picture are replaced by new ones whose
reference positions come from the current homography (or turn).

Pure: grey uint8 images in, pixel positions out (image pixels, x right, y down, origin at
the centre of the top-left pixel).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass
class PlaneFlow:
    """Features on the monitor plane tracked from a reference frame (see the module
    docstring).

    Attributes:
        max_features: features kept (Shi-Tomasi corners inside the landmark quadrilateral
            grown by ``grow``).
        min_features: below this many, new ones are detected in the current frame.
        ransac_px: RANSAC reprojection threshold (px).
        fb_px: largest forward-backward Lucas-Kanade disagreement (px) of a kept feature.
        landmark_weight: how many features a found landmark counts as in the fit.
        exclude: the screen's corners (4, 2) from the landmark quadrilateral, or None:
            no features are taken inside it (grown by ``exclude_grow``), as a video or a
            scrolling page moves across the screen and would carry the fit with it.
    """

    max_features: int = 150
    min_features: int = 40
    grow: float = 1.15
    ransac_px: float = 2.0
    fb_px: float = 1.0
    landmark_weight: int = 8
    win: int = 15
    levels: int = 3
    ref: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    cur: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    gray: NDArray[np.uint8] | None = None
    H: FloatArray | None = None  # reference -> current frame
    inliers: int = 0
    exclude: Callable[[FloatArray], FloatArray] | None = None
    exclude_grow: float = 1.03

    @property
    def active(self) -> bool:
        return self.gray is not None

    def stop(self) -> None:
        self.gray = None
        self.H = None
        self.ref = np.zeros((0, 2))
        self.cur = np.zeros((0, 2))

    def start(self, gray: NDArray[np.uint8], quad: FloatArray) -> None:
        """Make ``gray`` the reference frame; features inside ``quad`` (4, 2) grown."""
        self.gray = gray
        self.H = np.eye(3)
        pts = self._features(gray, quad, self.max_features)
        self.ref = pts.copy()
        self.cur = pts

    def _features(self, gray: NDArray[np.uint8], quad: FloatArray, n: int) -> FloatArray:
        c = quad.mean(axis=0)
        poly = np.round(c + (quad - c) * self.grow).astype(np.int32)
        mask = np.zeros(gray.shape, np.uint8)
        cv2.fillConvexPoly(mask, poly, 255)
        side = float(np.median(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
        dist = max(4.0, side / 25.0)
        if self.exclude is not None:
            screen = self.exclude(quad)
            mid = screen.mean(axis=0)
            cut = np.round(mid + (screen - mid) * self.exclude_grow).astype(np.int32)
            cv2.fillConvexPoly(mask, cut, 0)
        p = cv2.goodFeaturesToTrack(gray, n, 0.01, dist, mask=mask, blockSize=5)
        return np.zeros((0, 2)) if p is None else p.reshape(-1, 2).astype(np.float64)

    def step(self, gray: NDArray[np.uint8]) -> None:
        """Follow the features from the last frame into ``gray``."""
        assert self.gray is not None
        if len(self.cur):
            p0 = self.cur.astype(np.float32).reshape(-1, 1, 2)
            lk = {"winSize": (self.win, self.win), "maxLevel": self.levels}
            p1, st, _ = cv2.calcOpticalFlowPyrLK(self.gray, gray, p0, None, **lk)  # type: ignore[call-overload]
            p0b, stb, _ = cv2.calcOpticalFlowPyrLK(gray, self.gray, p1, None, **lk)  # type: ignore[call-overload]
            fb = np.linalg.norm((p0b - p0).reshape(-1, 2), axis=1)
            ok = (st.ravel() == 1) & (stb.ravel() == 1) & (fb < self.fb_px)
            h, w = gray.shape
            q = p1.reshape(-1, 2).astype(np.float64)
            ok &= (q[:, 0] >= 0) & (q[:, 0] <= w - 1) & (q[:, 1] >= 0) & (q[:, 1] <= h - 1)
            self.ref, self.cur = self.ref[ok], q[ok]
        self.gray = gray

    def fit(self, ref_lm: FloatArray, cur_lm: FloatArray) -> FloatArray | None:
        """The reference -> current homography from the features and the found
        landmarks (reference positions ``ref_lm`` (k, 2) -> ``cur_lm`` (k, 2)), or None
        when too few features agree. Features off the fit are dropped."""
        src = np.concatenate([self.ref] + [ref_lm] * self.landmark_weight)
        dst = np.concatenate([self.cur] + [cur_lm] * self.landmark_weight)
        if len(self.ref) < 8 or len(src) < 8:
            self.H = None
            return None
        H, mask = cv2.findHomography(src, dst, cv2.RANSAC, self.ransac_px, maxIters=500)
        if H is None:
            self.H = None
            return None
        m = mask.ravel().astype(bool)
        feat = m[: len(self.ref)]
        self.inliers = int(feat.sum())
        if self.inliers < 8:
            self.H = None
            return None
        self.ref, self.cur = self.ref[feat], self.cur[feat]
        self.H = np.asarray(H, np.float64)
        return self.H

    def replenish(
        self,
        gray: NDArray[np.uint8],
        quad: FloatArray,
        to_ref: Callable[[FloatArray], FloatArray] | None = None,
    ) -> None:
        """Add features when fewer than ``min_features`` remain: new corners inside the
        current ``quad`` (4, 2), their reference positions through ``to_ref`` (current ->
        reference pixels), by default the inverse of the current homography."""
        if len(self.cur) >= self.min_features or (to_ref is None and self.H is None):
            return
        new = self._features(gray, quad, self.max_features - len(self.cur))
        if not len(new):
            return
        if len(self.cur):
            d = np.linalg.norm(new[:, None, :] - self.cur[None, :, :], axis=2).min(axis=1)
            new = new[d > 3.0]
        if not len(new):
            return
        if to_ref is not None:
            ref = to_ref(new)
        else:
            assert self.H is not None
            inv = np.linalg.inv(self.H)
            ref = np.asarray(cv2.perspectiveTransform(new.reshape(-1, 1, 2), inv), np.float64)
            ref = ref.reshape(-1, 2)
        self.ref = np.concatenate([self.ref, ref])
        self.cur = np.concatenate([self.cur, new])


def apply_h(H: FloatArray, pts: FloatArray) -> FloatArray:
    """Points (n, 2) through the homography H (3, 3)."""
    q = np.column_stack([pts, np.ones(len(pts))]) @ H.T
    out: FloatArray = q[:, :2] / q[:, 2:3]
    return out


def frame_homography(
    prev: NDArray[np.uint8],
    cur: NDArray[np.uint8],
    quad: FloatArray,
    *,
    features: int = 80,
    ransac_px: float = 2.0,
) -> FloatArray | None:
    """The monitor plane's homography from ``prev`` to ``cur`` (grey uint8), from corner
    features inside the landmark quadrilateral ``quad`` (4, 2) of ``prev``, the screen's
    among them (from one frame to the next its content moves little; without them the
    bezel's few features misplaced the windows on the oblique fixture), followed by
    Lucas-Kanade (forward-backward checked) and fitted by RANSAC; None when fewer than
    10 features agree."""
    f = PlaneFlow(max_features=features, ransac_px=ransac_px)
    f.start(prev, quad)
    if len(f.cur) < 10:
        return None
    f.step(cur)
    return (
        f.fit(np.zeros((0, 2)), np.zeros((0, 2))) if f.inliers >= 0 and len(f.cur) >= 10 else None
    )

"""The detection stage of the camera mouse (dissertation sec. 6.2.1), step by step.

1. Threshold the grey image into a binary image I (dark = landmark candidate).
2. Connected components of the dark pixels of I.
3. Keep regions whose area and bounding-box width-to-height ratio suit a landmark circle.
4. Every group of four remaining region centers C1..C4 (ordered TL, TR, BR, BL) is kept
   when its quadrilateral S is like the screen: (a) opposite sides roughly equal,
   (b) all four corners roughly right angles, (c) width-to-height ratio R of S near the
   landmark layout's.
5. The groups passing step 4 form the candidate set D_L; none means no detection.
6. For each group, each side C_iC_{i+1} is paired with the parallel screen border just
   inside it: a Hough transform over a narrow range of angles around the side's direction,
   restricted to a search window W along the side's inner edge, votes with the edge pixels
   (Canny) of W; its peak is the side's edge strength E_i; the group's total is
   E_1 + ... + E_4, and the group with the largest total is the landmark set.

Beyond the dissertation (each can be disabled): the centers are refined to sub-pixel by a
darkness-weighted centroid; each side's edge strength must reach ``min_edge_fraction``
of the searched border length, so dark blobs with no screen border between them do not
lock; and the border line found by the Hough transform must pass through the screen
corners that the group predicts (:func:`omnidev.mouse.geometry.screen_corners_from_landmarks`),
so a stray blob next to a missing landmark does not complete a group with the other three;
and the four regions' areas must agree with the disc areas that the group's own
homography predicts (``max_area_spread``).
A group is kept when at least ``min_border_sides`` of its four sides show a border line
above the floor and no side shows one off the predicted position.

Verification added for hand-held videos never seen in tuning (issue 13; each can be
turned off, which gives the stages above):

- ``threshold_mode="adaptive"``: a pixel is dark when it is darker than the mean of its
  neighbourhood at two scales (small and large discs), so a dim room, a bright screen
  or auto-exposure does not move the landmarks across one fixed grey level; the
  dissertation's fixed threshold stays selectable (``"fixed"``).
- appearance: a region must be darker than a ring around it (the landmark's white
  square), ``min_ring_contrast``;
- physical shape: the group's homography from the layout (mm) must be that of a plane
  seen by a pinhole camera with its principal point at the image centre and a focal
  length of a ``fov_range_deg`` field of view: its two plane axes must come out
  orthogonal and of equal length (``max_rigid_error``), so a text window's four
  corners or look-alikes of the wrong aspect ratio cannot pass under any plausible
  lens; and each region's area must be that of a landmark disc where the homography
  puts it (``disc_area_range``).

All positions are image pixels (x right, y down, origin at the center of the top-left pixel).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.mouse.geometry import homography_from_4_points, screen_corners_from_landmarks
from omnidev.mouse.landmarks import LandmarkLayout


@dataclass(frozen=True)
class DetectParams:
    """Tuning of :func:`detect_landmarks` (pixels unless said otherwise).

    Attributes:
        threshold: grey level below which a pixel is dark (step 1).
        min_area, max_area: area of a landmark circle's region (pixels, step 3).
        max_elongation: largest bounding-box width/height (or height/width) ratio (step 3).
        max_side_ratio: largest ratio of opposite sides' lengths (step 4a).
        max_angle_error_deg: largest deviation of a corner angle from 90 degrees (step 4b).
        max_aspect_error: largest relative deviation of R from the layout's (step 4c).
        max_regions: at most this many regions (the largest) enter the exhaustive search.
        hough_angle_deg: the Hough transform searches directions within this many degrees
            of the side's (step 6a), in steps of ``hough_angle_step_deg``.
        end_margin: fraction of each side left out at both ends of W (the landmarks' own
            white squares are there).
        min_edge_fraction: each side's edge strength must reach this fraction of W's
            length (0 turns the check off, as in the dissertation).
        max_border_offset_px, max_border_offset_frac: the Hough peak line of each side
            must pass within max(max_border_offset_px, max_border_offset_frac x the
            landmark-to-border distance in pixels) of both screen corners predicted from
            the group's landmarks and the layout (motion blur moves the edges found by a
            few pixels; inf turns the check off, as in the dissertation).
        min_border_sides: a group is kept when at least this many of its sides show a
            border line above the edge floor (screen content as dark as the bezel can hide
            one side's border), and none shows one off the predicted position (a stray
            blob standing in for a missing landmark misplaces the sides it touches).
        max_area_spread: each region's area over the area the group's homography predicts
            for a landmark disc there; the largest of the four ratios over the smallest
            must not exceed this (inf turns the check off, as in the dissertation).
        canny_low, canny_high: hysteresis thresholds of the Canny edge map voting in the
            Hough transform (grey levels of the Sobel gradient).
        faint_canny: with "predicted", the thresholds of a second edge map a side votes
            with when its colour step was found at the nearest offset but the first
            map's edges fell short of the floor (a white bezel next to a white page: a
            step of 12-20 grey levels); None: the first map only.
        refine: refine centers by the darkness-weighted centroid (else binary centroid).
        border_search: "predicted" (step 6's Hough window is a band of half-width
            max(``max_border_offset_px``, ``border_band_frac`` x the landmark-to-border
            distance) around the screen border the group predicts) or the
            dissertation's "side" (from the landmark side inwards).
        min_border_step: with "predicted", a side votes only when the colour steps
            across the predicted border coherently along it: in the channel of the
            largest mean difference between both sides, the mean reaches this many grey
            levels and 3/4 of the points agree in sign (edges of sensor noise or of a
            textured wall do not; 0 turns it off).
        border_step_scales: the step is sampled at max(2, ``border_band_frac`` x the
            landmark-to-border distance) px to both sides of the predicted border, times
            each of these in turn, and the side votes when one of them steps: a bezel of
            a few pixels, blur and a border predicted a pixel off put the samples at 1 x
            on the content (e.g. 320x240 with 6 px discs: no side stepped at 1 x, three
            at 1.5-2 x). Issue 13, tuning videos 100-139: frames with a cursor 0.876 ->
            0.938 with (1, 1.5, 2); held out 30000-30059: 0.834 -> 0.873, no other
            figure worse, no cursor on the no-monitor and look-alike videos.
        threshold_mode: "adaptive" (darker than the local mean by ``adaptive_c`` grey
            levels over windows of ``block_fracs`` x the image's smaller side), the
            dissertation's "fixed" (``threshold``), or "both" (adaptive, then fixed
            when adaptive finds no group; the default).
        max_area_frac: with "adaptive", regions may cover up to this fraction of the
            image (instead of ``max_area``).
        min_ring_contrast: a region's centre must be this many grey levels darker than
            the median of a ring at 1.3 x its radius (0 turns the check off).
        max_rigid_error: largest deviation from a rigid plane of the group's homography
            (the cosine between its plane axes and their relative length difference,
            at the best focal length of ``fov_range_deg``); inf turns the check off.
        fov_range_deg: horizontal fields of view that a webcam may have.
        disc_area_range: each region's area over the landmark disc's area that the
            homography predicts there must lie in this range.
        border_bends: with "predicted", where a side's straight border does not vote
            (no colour step, no edge, or an edge line off the predicted corners), the
            border bent outwards (a barrel lens) by each of these fractions of the
            side's length at its middle (a parabola through the predicted corners;
            negative: inwards, a pincushion lens) is tried in turn; every side bent
            must bend the same way. () keeps the borders straight (as before
            2026-12-07). Tuning video 225 (k1 -0.45): the border bows out 10-16 px.
        bent_edge_fraction: a bent side votes when its edge covers this fraction of
            its window (a straight one: ``min_edge_fraction``): the bend is one more
            parameter to line chance edges up with (on the three-landmarks fixture's
            textured wall a bent side of a false group reached 0.76; the true bent
            sides of tuning video 225, 0.84-0.99).
    """

    threshold: int = 100
    min_area: int = 12
    max_area: int = 5000
    max_elongation: float = 2.2
    max_side_ratio: float = 1.8
    max_angle_error_deg: float = 35.0
    max_aspect_error: float = 0.45
    max_regions: int = 24
    hough_angle_deg: float = 6.0
    hough_angle_step_deg: float = 0.5
    end_margin: float = 0.2
    min_edge_fraction: float = 0.5
    max_border_offset_px: float = 3.0
    max_border_offset_frac: float = 0.5
    min_border_sides: int = 3
    max_area_spread: float = 1.3
    canny_low: float = 30.0
    canny_high: float = 90.0
    faint_canny: tuple[float, float] | None = (10.0, 30.0)
    refine: bool = True
    threshold_mode: str = "both"
    border_search: str = "predicted"
    min_border_step: float = 12.0
    border_step_scales: tuple[float, ...] = (1.0, 1.5, 2.0)
    border_band_frac: float = 0.3
    block_fracs: tuple[float, ...] = (0.06, 0.2)
    adaptive_c: float = 12.0
    max_area_frac: float = 0.02
    min_ring_contrast: float = 20.0
    max_rigid_error: float = 0.15
    fov_range_deg: tuple[float, float] = (30.0, 120.0)
    disc_area_range: tuple[float, float] = (0.3, 3.0)
    border_bends: tuple[float, ...] = (0.02, 0.04, -0.02)
    bent_edge_fraction: float = 0.8


@dataclass(frozen=True)
class HoughLine:
    """A Hough peak in a side's frame: the line at angle ``phi`` (radians) from the side
    p -> p + length * t_hat, at distance ``rho`` (pixels, along the rotated normal) from
    the side's midpoint; t_hat and n_hat the side's unit direction and inward normal."""

    phi: float
    rho: float
    p: NDArray[np.float64]
    t_hat: NDArray[np.float64]
    n_hat: NDArray[np.float64]
    length: float

    def distance(self, pts: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distances (pixels) of (n, 2) image points from the line."""
        rel = np.atleast_2d(pts) - self.p
        s = rel @ self.t_hat - self.length / 2.0
        t = rel @ self.n_hat
        d = t * math.cos(self.phi) - s * math.sin(self.phi) - self.rho
        return np.asarray(np.abs(d), dtype=np.float64)


@dataclass(frozen=True)
class Detection:
    """A detected landmark set: centers (4, 2) TL, TR, BR, BL (pixels), the screen corners
    (4, 2) TL, TR, BR, BL (pixels) they predict, the total edge strength of step 6c, the
    per-side strengths E_1..E_4 (votes = edge pixels) and the size of the candidate set
    D_L."""

    centers: NDArray[np.float64]
    screen_corners: NDArray[np.float64]
    strength: float
    side_strengths: tuple[float, float, float, float]
    candidates: int


def to_gray(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """An (H, W) uint8 grey image from (H, W) or BGR (H, W, 3) uint8."""
    if image.ndim == 3:
        return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    if image.ndim != 2:
        raise ValueError(f"expected an (H, W) or (H, W, 3) image, got shape {image.shape}")
    return image


def edge_map(image: NDArray[np.uint8], params: DetectParams = DetectParams()) -> NDArray[np.uint8]:
    """Canny edges (H, W) uint8 (255 = edge) voting in step 6; for a BGR image the union of
    the three channels' edges, so a border between colours of equal grey still shows."""
    lo, hi = params.canny_low, params.canny_high
    if image.ndim == 2:
        return np.asarray(cv2.Canny(image, lo, hi), dtype=np.uint8)
    out = np.zeros(image.shape[:2], np.uint8)
    for ch in cv2.split(image):
        np.maximum(out, cv2.Canny(ch, lo, hi), out=out)
    return out


def find_dark_regions(
    gray: NDArray[np.uint8], params: DetectParams = DetectParams()
) -> NDArray[np.float64]:
    """Steps 1-3: centers (n, 2) of the dark regions shaped like landmark circles
    (refined when ``params.refine``). The largest ``params.max_regions`` regions are kept,
    largest first."""
    centers, labels, stats, ids = _regions(gray, params)
    if params.refine:
        for k, i in enumerate(ids):
            centers[k] = _weighted_centroid(gray, stats[i], labels, i)
    return centers


def _regions(
    gray: NDArray[np.uint8], params: DetectParams
) -> tuple[NDArray[np.float64], _RegionLabels, NDArray[np.int32], list[int]]:
    """Steps 1-3: binary centroids (n, 2), the label image, the stats and the labels kept.

    With ``threshold_mode="adaptive"`` the dark masks of the scales are labelled apart
    and the label image holds them side by side (labels of scale k offset by the counts
    of the scales before); a region found at two scales is kept once (the larger).
    """
    H, W = gray.shape
    if params.threshold_mode == "fixed":
        masks = [(gray < params.threshold).astype(np.uint8)]
        max_area = params.max_area
    elif params.threshold_mode in ("adaptive", "both"):
        masks = []
        g = gray.astype(np.float32)
        for frac in params.block_fracs:
            b = max(3, round(frac * min(H, W)) | 1)
            mean = cv2.boxFilter(g, -1, (b, b), borderType=cv2.BORDER_REPLICATE)
            masks.append((g < mean - params.adaptive_c).astype(np.uint8))
        max_area = max(params.max_area, round(params.max_area_frac * H * W))
    else:
        raise ValueError(
            f"threshold_mode must be 'adaptive' or 'fixed', got {params.threshold_mode!r}"
        )
    # the scales' label images side by side: label l of scale k is l + offset_k in a
    # (k, H, W) stack flattened by _RegionLabels
    label_list: list[NDArray[np.int32]] = []
    all_stats: list[NDArray[np.int32]] = [np.zeros((1, 5), np.int32)]
    all_cent: list[NDArray[np.float64]] = [np.zeros((1, 2))]
    offsets = []
    offset = 0
    for dark in masks:
        n, labels, stats, centroids = cv2.connectedComponentsWithStats(dark, connectivity=8)
        label_list.append(np.asarray(labels, np.int32))
        offsets.append(offset)
        all_stats.append(np.asarray(stats[1:], np.int32))
        all_cent.append(np.asarray(centroids[1:], np.float64))
        offset += n - 1
    stats = np.concatenate(all_stats)
    centroids = np.concatenate(all_cent)
    x, y, w, h, area = (stats[:, k].astype(np.int64) for k in range(5))
    ok = (area >= params.min_area) & (area <= max_area)
    ok &= np.maximum(w, h) <= params.max_elongation * np.minimum(w, h)
    # a region touching the image border is cut off: its center would be wrong
    ok &= (x > 0) & (y > 0) & (x + w < W) & (y + h < H)
    # a disc or an ellipse fills about pi/4 of its box; text strokes and frames less
    ok &= area >= 0.45 * w * h
    ok[0] = False
    idx = np.flatnonzero(ok)
    r = np.sqrt(area[idx] / math.pi)
    contrast = _ring_contrasts(gray, np.asarray(centroids[idx], np.float64), r)
    if params.min_ring_contrast > 0:
        sel = contrast >= params.min_ring_contrast
        idx, r, contrast = idx[sel], r[sel], contrast[sel]
    # the regions darkest against their ring first (the largest with a fixed threshold);
    # a blob found at both scales is kept once
    order = np.argsort(-contrast if params.threshold_mode != "fixed" else -area[idx], kind="stable")
    kept: list[int] = []
    for k in order:
        i = int(idx[k])
        c = centroids[i]
        if any(np.hypot(*(centroids[j] - c)) < max(2.0, 0.5 * r[k]) for j in kept):
            continue
        kept.append(i)
        if len(kept) >= params.max_regions:
            break
    out = np.array(centroids[kept], dtype=np.float64).reshape(len(kept), 2)
    return out, _RegionLabels(label_list, offsets), np.asarray(stats, np.int32), kept


@dataclass(frozen=True)
class _RegionLabels:
    """Label images of the threshold scales; global label g (1-based) is local label
    g - offsets[k] of scale k, the last k with offsets[k] < g."""

    images: list[NDArray[np.int32]]
    offsets: list[int]

    def mask(self, label: int, y0: int, y1: int, x0: int, x1: int) -> NDArray[np.bool_]:
        k = max(i for i, o in enumerate(self.offsets) if o < label)
        return np.asarray(self.images[k][y0:y1, x0:x1] == label - self.offsets[k])


def _ring_contrasts(
    gray: NDArray[np.uint8], c: NDArray[np.float64], r: NDArray[np.float64]
) -> NDArray[np.float64]:
    """How much darker (grey levels) each region centred at ``c`` (n, 2) with radius
    ``r`` (n,) px is than the median of 16 samples on a ring at 1.3 r + 1 px around it
    (the landmark's white square): ring median minus the 3 x 3 mean at the centre."""
    H, W = gray.shape
    if len(c) == 0:
        return np.zeros(0)
    ang = np.arange(16) * (math.pi / 8)
    rr = (1.3 * r + 1.0)[:, None]
    xs = np.clip(np.round(c[:, 0:1] + rr * np.cos(ang)).astype(np.intp), 0, W - 1)
    ys = np.clip(np.round(c[:, 1:2] + rr * np.sin(ang)).astype(np.intp), 0, H - 1)
    ring = np.median(gray[ys, xs].astype(np.float64), axis=1)
    ix = np.clip(np.round(c[:, 0]).astype(np.intp), 1, W - 2)
    iy = np.clip(np.round(c[:, 1]).astype(np.intp), 1, H - 2)
    core = np.zeros(len(c))
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            core += gray[iy + dy, ix + dx]
    return np.asarray(ring - core / 9.0, np.float64)


def focal_range_px(width: int, fov_range_deg: tuple[float, float]) -> tuple[float, float]:
    """The focal lengths (px, shortest first) of a ``width``-px-wide pinhole camera whose
    horizontal field of view spans ``fov_range_deg`` (degrees, narrowest first)."""
    lo, hi = fov_range_deg
    return (width / 2 / math.tan(math.radians(hi) / 2), width / 2 / math.tan(math.radians(lo) / 2))


def rigid_plane_error(
    plane_to_image: NDArray[np.float64],
    center_px: NDArray[np.float64],
    focal_range_px: tuple[float, float],
) -> tuple[float, float]:
    """How far a plane-to-image homography is from a plane seen by a pinhole camera
    with square pixels, principal point ``center_px`` and a focal length in
    ``focal_range_px``: (error, best focal px).

    With K = diag(f, f, 1) about the principal point, K^-1 H = [a1 a2 a3] must have
    a1 . a2 = 0 and |a1| = |a2| (columns of a rotation, scaled). The focal length is
    the least-squares one of the two conditions (in 1 / f^2), clamped to the range;
    the error is the larger of |cos(a1, a2)| and | |a1| / |a2| - 1 |.
    """
    T = np.array([[1.0, 0.0, -center_px[0]], [0.0, 1.0, -center_px[1]], [0.0, 0.0, 1.0]])
    h = T @ plane_to_image
    h = h / np.linalg.norm(h[:, :2])
    P = h[0, 0] * h[0, 1] + h[1, 0] * h[1, 1]
    Q = h[2, 0] * h[2, 1]
    R = h[0, 0] ** 2 + h[1, 0] ** 2 - h[0, 1] ** 2 - h[1, 1] ** 2
    S = h[2, 0] ** 2 - h[2, 1] ** 2
    lo, hi = focal_range_px
    den = P * P + R * R
    x = -(P * Q + R * S) / den if den > 0 else 1.0 / (lo * hi)
    x = min(max(x, 1.0 / hi**2), 1.0 / lo**2)
    f = 1.0 / math.sqrt(x)
    a1 = np.array([h[0, 0] / f, h[1, 0] / f, h[2, 0]])
    a2 = np.array([h[0, 1] / f, h[1, 1] / f, h[2, 1]])
    n1, n2 = float(np.linalg.norm(a1)), float(np.linalg.norm(a2))
    cos = abs(float(a1 @ a2)) / (n1 * n2)
    return max(cos, abs(n1 / n2 - 1.0)), f


def _weighted_centroid(
    gray: NDArray[np.uint8], stat: NDArray[np.int32], labels: _RegionLabels, label: int
) -> NDArray[np.float64]:
    """Darkness-weighted centroid over the region's box grown by 2 pixels; darkness is
    scaled between the box's brightest level (0) and the region's mean level (1)."""
    x, y, w, h = (int(v) for v in stat[:4])
    x0, y0 = max(0, x - 2), max(0, y - 2)
    x1, y1 = min(gray.shape[1], x + w + 2), min(gray.shape[0], y + h + 2)
    patch = gray[y0:y1, x0:x1].astype(np.float64)
    mask = labels.mask(label, y0, y1, x0, x1)
    inner = patch[mask]
    lo, hi = float(inner.mean()), float(patch.max())
    if hi - lo < 1.0:
        ys, xs = np.nonzero(mask)
        return np.array([xs.mean() + x0, ys.mean() + y0])
    wgt = np.clip((hi - patch) / (hi - lo), 0.0, 1.0)
    # Pixels not connected to the region (a neighbour's darkness) are left out.
    grown = cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    wgt = wgt * grown
    ys, xs = np.mgrid[y0:y1, x0:x1]
    s = wgt.sum()
    return np.array([(wgt * xs).sum() / s, (wgt * ys).sum() / s])


def order_corners(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Four points (4, 2) ordered TL, TR, BR, BL: clockwise (y down) by angle about their
    mean, starting from the one whose direction from the mean is nearest to up-left
    (-135 deg). Also takes a stack (m, 4, 2) of groups."""
    p = np.asarray(points, dtype=np.float64)
    return p if p.size == 0 else _order_batch(p.reshape(-1, 4, 2)).reshape(p.shape)


def _order_batch(p: NDArray[np.float64]) -> NDArray[np.float64]:
    idx = _order_batch_index(p)
    return np.take_along_axis(p, idx[..., None], axis=1)


def _order_batch_index(p: NDArray[np.float64]) -> NDArray[np.intp]:
    """(m, 4) permutations putting each group of (m, 4, 2) in TL, TR, BR, BL order."""
    d = p - p.mean(axis=1, keepdims=True)
    ang = np.arctan2(d[..., 1], d[..., 0])  # (m, 4)
    order = np.argsort(ang, axis=1)
    ang_sorted = np.take_along_axis(ang, order, axis=1)
    # Angular distance of each sorted point's direction from -135 degrees.
    off = np.abs((ang_sorted + 3 * math.pi / 4 + math.pi) % (2 * math.pi) - math.pi)
    start = np.argmin(off, axis=1)
    idx = np.take_along_axis(order, (start[:, None] + np.arange(4)[None, :]) % 4, axis=1)
    return np.asarray(idx, dtype=np.intp)


def shape_checks(
    quad: NDArray[np.float64], expected_aspect: float, params: DetectParams = DetectParams()
) -> bool:
    """Step 4 (a, b, c) on an ordered quadrilateral C1..C4 (TL, TR, BR, BL), (4, 2) pixels."""
    q = np.asarray(quad, dtype=np.float64).reshape(1, 4, 2)
    return bool(_shape_checks_batch(q, expected_aspect, params)[0])


def _shape_checks_batch(
    q: NDArray[np.float64], expected_aspect: float, params: DetectParams
) -> NDArray[np.bool_]:
    """Step 4 on a stack (m, 4, 2) of ordered quadrilaterals: (m,) passes."""
    e = np.roll(q, -1, axis=1) - q  # edges C1C2, C2C3, C3C4, C4C1
    d = np.hypot(e[..., 0], e[..., 1])  # (m, 4)
    ok = d.min(axis=1) > 1e-9
    dd = np.where(d > 1e-9, d, 1.0)
    # (a) opposite sides roughly equal: |C1-C2| ~ |C3-C4|, |C1-C4| ~ |C2-C3|.
    r = params.max_side_ratio
    ok &= np.maximum(dd[:, 0], dd[:, 2]) <= r * np.minimum(dd[:, 0], dd[:, 2])
    ok &= np.maximum(dd[:, 1], dd[:, 3]) <= r * np.minimum(dd[:, 1], dd[:, 3])
    # (b) four roughly right angles: |cos| of each corner angle (between the incoming and
    # the outgoing edge) small, and a convex clockwise quadrilateral (all turns positive).
    prev = np.roll(e, 1, axis=1)
    dprev = np.roll(dd, 1, axis=1)
    cos = np.abs((prev * e).sum(axis=2)) / (dprev * dd)
    ok &= (cos <= math.sin(math.radians(params.max_angle_error_deg))).all(axis=1)
    cross = prev[..., 0] * e[..., 1] - prev[..., 1] * e[..., 0]
    ok &= (cross > 0).all(axis=1)
    # (c) R = ((|C1-C2| + |C3-C4|)/2) / ((|C1-C4| + |C2-C3|)/2) near the layout's ratio.
    R = (dd[:, 0] + dd[:, 2]) / (dd[:, 1] + dd[:, 3])
    ok &= np.abs(R / expected_aspect - 1.0) <= params.max_aspect_error
    return np.asarray(ok, dtype=np.bool_)


def side_edge_strength(
    edges: NDArray[np.uint8],
    p: NDArray[np.float64],
    q: NDArray[np.float64],
    depth_px: float,
    params: DetectParams = DetectParams(),
    bend_px: float = 0.0,
) -> tuple[float, float, HoughLine | None]:
    """Steps 6a-6b for one side p -> q of a clockwise quadrilateral (y down).

    The search window W is the band along the side, from the side itself ``depth_px``
    pixels inwards (to the side's right when walking p -> q), leaving out ``end_margin``
    of the side at both ends. A Hough transform over lines at angles within
    ``hough_angle_deg`` of the side's direction, 1-pixel distance bins, is voted by the
    edge pixels of W; the peak is taken over two adjacent distance bins (a digital line
    is two bins wide). Returns (peak votes E_i, length of W along the side in pixels,
    the peak's line or None when W holds no edge pixel). ``bend_px``: W follows a
    parabola through p and q that lies this many pixels outwards (to the side's left) at
    the middle, and the Hough lines are straight in W's bent frame.
    """
    if not (np.isfinite(p).all() and np.isfinite(q).all()):  # a degenerate group
        return 0.0, 0.0, None
    v = q - p
    length = float(np.hypot(*v))
    if not length >= 1.0:
        return 0.0, 0.0, None
    t_hat = v / length
    n_hat = np.array([-t_hat[1], t_hat[0]])  # inwards for clockwise order with y down
    s0, s1 = params.end_margin * length, (1.0 - params.end_margin) * length
    sag = abs(bend_px)
    corners = np.array(
        [p + t_hat * s + n_hat * t for s in (s0, s1) for t in (-1.0 - sag, depth_px + 1.0 + sag)]
    )
    h, w = edges.shape
    x0, y0 = np.floor(corners.min(axis=0)).astype(int)
    x1, y1 = np.ceil(corners.max(axis=0)).astype(int) + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 <= x0 or y1 <= y0:
        return 0.0, s1 - s0, None
    ys, xs = np.nonzero(edges[y0:y1, x0:x1])
    rel = np.column_stack([xs + x0, ys + y0]).astype(np.float64) - p
    s = rel @ t_hat
    t = rel @ n_hat
    if bend_px:
        u = s / length
        t = t + bend_px * 4.0 * u * (1.0 - u)
    inside = (s >= s0) & (s <= s1) & (t >= 0.0) & (t <= depth_px)
    s, t = s[inside], t[inside]
    if s.size == 0:
        return 0.0, s1 - s0, None
    # Hough: line at angle phi from the side, distance rho from the side's midpoint.
    phis = np.radians(
        np.arange(
            -params.hough_angle_deg,
            params.hough_angle_deg + 1e-9,
            params.hough_angle_step_deg,
        )
    )
    sm = s - length / 2.0
    rho = t[None, :] * np.cos(phis)[:, None] - sm[None, :] * np.sin(phis)[:, None]
    bins = np.floor(rho + 0.5).astype(np.int64)
    lo = int(bins.min())
    nb = int(bins.max()) - lo + 1
    flat = (bins - lo) + (np.arange(phis.size) * nb)[:, None]
    acc = np.bincount(flat.ravel(), minlength=phis.size * nb).reshape(phis.size, nb)
    # A digital 1-pixel line spreads over two neighbouring 1-pixel rho bins: the peak is
    # taken over pairs of bins (a 2-pixel wide line).
    centre = 0.0
    if nb > 1:
        acc = acc[:, :-1] + acc[:, 1:]
        centre = 0.5
    k_phi, k_rho = np.unravel_index(int(np.argmax(acc)), acc.shape)
    peak = HoughLine(float(phis[k_phi]), float(k_rho + lo + centre), p, t_hat, n_hat, length)
    return float(acc[k_phi, k_rho]), s1 - s0, peak


def detect_landmarks(
    image: NDArray[np.uint8],
    layout: LandmarkLayout,
    params: DetectParams = DetectParams(),
) -> Detection | None:
    """The detection stage of sec. 6.2.1 on one frame (grey or BGR uint8).

    Returns the landmark set with the largest total edge strength, or None when no group
    of four regions passes the shape checks and the edge-strength floor (no false lock
    with fewer than four landmark-like blobs).
    """
    if params.threshold_mode == "both":
        # the dissertation's fixed threshold first, the adaptive one where it finds
        # nothing (a dim room, a bright screen); the same checks verify both
        found = detect_landmarks(image, layout, replace(params, threshold_mode="fixed"))
        if found is None:
            found = detect_landmarks(image, layout, replace(params, threshold_mode="adaptive"))
        return found
    gray = to_gray(image)
    centers, labels, stats, ids = _regions(gray, params)
    if len(centers) < 4:
        return None
    expected = layout.landmark_aspect_ratio()
    # Step 4, exhaustively: every group of four regions, vectorized over the groups.
    groups = _combinations4(len(centers))
    perm = _order_batch_index(centers[groups])
    groups = np.take_along_axis(groups, perm, axis=1)
    quads = centers[groups]
    passed = _shape_checks_batch(quads, expected, params)
    candidates, cand_groups = list(quads[passed]), list(groups[passed])
    if not candidates:
        return None
    edges = edge_map(image, params)
    faint: NDArray[np.uint8] | None = None  # the faint_canny map, made when first needed
    # Inward distance of the screen border from each landmark side, in mm (monitor plane).
    lm = layout.landmark_centers_mm()
    sc = layout.screen_corners_mm()
    side_mm = np.linalg.norm(lm - np.roll(lm, -1, axis=0), axis=1)
    inset_mm = [
        _inset(lm[i], lm[(i + 1) % 4], sc[i], sc[(i + 1) % 4], layout.square_side_mm)
        for i in range(4)
    ]
    areas = np.array([float(stats[i][4]) for i in ids])
    disc_mm2 = math.pi * (layout.circle_diameter_mm / 2.0) ** 2
    h_img, w_img = gray.shape
    centre = np.array([(w_img - 1) / 2.0, (h_img - 1) / 2.0])
    focal_range = focal_range_px(w_img, params.fov_range_deg)
    # Disc areas, then the rigid-plane check, vectorized over the candidates.
    cq = np.asarray(candidates)
    cg = np.asarray(cand_groups)
    Hs = homographies_from_4_points(layout.landmark_centers_mm(), cq)
    ratio = areas[cg] / (disc_mm2 * _area_scale_batch(Hs, layout.landmark_centers_mm()))
    keep = np.ones(len(cq), bool)
    if math.isfinite(params.max_area_spread):
        keep &= ratio.max(axis=1) <= params.max_area_spread * ratio.min(axis=1)
    if math.isfinite(params.max_rigid_error):
        lo_a, hi_a = params.disc_area_range
        keep &= (ratio.min(axis=1) >= lo_a) & (ratio.max(axis=1) <= hi_a)
        keep &= rigid_plane_errors(Hs, centre, focal_range) <= params.max_rigid_error
    best: Detection | None = None
    best_group: NDArray[np.intp] | None = None

    def predicted_side(
        screen: NDArray[np.float64], i: int, px_per_mm: float, bend_px: float
    ) -> tuple[bool, float, float, HoughLine | None]:
        """Side i of the border the group predicts (bent outwards by ``bend_px`` at its
        middle): whether the colour steps across it, and its edge votes, window length
        and Hough line."""
        nonlocal faint
        # a band around the screen border where the group puts it (the bezel's outer
        # edge, between an overhanging card and the screen, stays out)
        a, b = screen[i], screen[(i + 1) % 4]
        step_px = max(2.0, params.border_band_frac * inset_mm[i] * px_per_mm)
        # the nearest offset first: the faint map below votes only where it steps
        near = stepped = True
        if params.min_border_step > 0:
            scales = sorted(params.border_step_scales)
            near = bool(scales) and _border_step(image, a, b, scales[0] * step_px, params, bend_px)
            stepped = near or any(
                _border_step(image, a, b, k * step_px, params, bend_px) for k in scales[1:]
            )
        if not stepped:
            return False, 0.0, 0.0, None
        band = max(params.max_border_offset_px, params.border_band_frac * inset_mm[i] * px_per_mm)
        v = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
        nrm = np.array([-v[1], v[0]])
        e, span, line = side_edge_strength(
            edges, a - nrm * band, b - nrm * band, 2 * band, params, bend_px
        )
        # the faint map only where the colour steps right at the border (on a
        # textured wall its edges line up by chance: fixture three-landmarks)
        if e < params.min_edge_fraction * span and params.faint_canny is not None and near:
            if faint is None:
                faint = edge_map(
                    image,
                    replace(
                        params, canny_low=params.faint_canny[0], canny_high=params.faint_canny[1]
                    ),
                )
            e, span, line = side_edge_strength(
                faint, a - nrm * band, b - nrm * band, 2 * band, params, bend_px
            )
        return True, e, span, line

    def off_border(
        line: HoughLine | None, screen: NDArray[np.float64], i: int, px_per_mm: float
    ) -> bool:
        """Whether side i's edge line misses the predicted corners (a wrong group)."""
        if line is None or not math.isfinite(params.max_border_offset_px):
            return False
        off = line.distance(screen[[i, (i + 1) % 4]])
        tol = max(
            params.max_border_offset_px, params.max_border_offset_frac * inset_mm[i] * px_per_mm
        )
        return bool(off.max() > tol)

    def votes(
        side: tuple[bool, float, float, HoughLine | None],
        screen: NDArray[np.float64],
        i: int,
        px_per_mm: float,
        fraction: float = params.min_edge_fraction,
    ) -> bool:
        """Whether side i steps, shows an edge over ``fraction`` of its window and the
        edge meets the predicted corners."""
        stepped, e, span, line = side
        return stepped and e >= fraction * span and not off_border(line, screen, i, px_per_mm)

    def straight_or_bent(
        screen: NDArray[np.float64], i: int, px_per_mm: float, bends: list[float]
    ) -> tuple[bool, float, float, HoughLine | None]:
        """Side i of the predicted border as :func:`predicted_side` measures it: straight,
        or where the straight side does not vote the first of ``params.border_bends``
        that does (appended to ``bends``; every side of a group bends the same way)."""
        side = predicted_side(screen, i, px_per_mm, 0.0)
        if votes(side, screen, i, px_per_mm):
            return side
        side_px = float(np.linalg.norm(screen[(i + 1) % 4] - screen[i]))
        for f in params.border_bends:  # a lens bends the border
            if bends and f * bends[0] < 0:
                continue
            bent = predicted_side(screen, i, px_per_mm, f * side_px)
            if votes(bent, screen, i, px_per_mm, params.bent_edge_fraction):
                bends.append(f)
                return bent
        return side

    for quad, group in zip(cq[keep], cg[keep], strict=True):
        strengths: list[float] = []
        weak = 0
        misplaced = False
        bends: list[float] = []  # the bends the sides were found with (fraction of length)
        screen = screen_corners_from_landmarks(quad, layout)
        if not np.all(np.isfinite(screen)):
            continue
        for i in range(4):
            p, q = quad[i], quad[(i + 1) % 4]
            px_per_mm = float(np.linalg.norm(q - p)) / side_mm[i]
            if params.border_search == "predicted":
                stepped, e, span, line = straight_or_bent(screen, i, px_per_mm, bends)
                if not stepped:
                    weak += 1  # no change of colour across the border: no vote
                    if weak > 4 - params.min_border_sides:
                        break
                    strengths.append(0.0)
                    continue
            else:
                depth = max(4.0, 2.0 * inset_mm[i] * px_per_mm)
                e, span, line = side_edge_strength(edges, p, q, depth, params)
            if e < params.min_edge_fraction * span:
                weak += 1  # no clear border here (content as dark as the bezel): no vote
            else:
                misplaced = off_border(line, screen, i, px_per_mm)
            if misplaced or weak > 4 - params.min_border_sides:
                break
            strengths.append(e)
        if misplaced or weak > 4 - params.min_border_sides:
            continue
        total = float(sum(strengths))
        if best is None or total > best.strength:
            best = Detection(
                quad,
                screen,
                total,
                (strengths[0], strengths[1], strengths[2], strengths[3]),
                len(candidates),
            )
            best_group = group
    if best is None or best_group is None or not params.refine:
        return best
    # Sub-pixel centers of the chosen four only, and the screen corners they predict.
    refined = np.array(
        [_weighted_centroid(gray, stats[ids[k]], labels, ids[k]) for k in best_group]
    )
    return Detection(
        refined,
        screen_corners_from_landmarks(refined, layout),
        best.strength,
        best.side_strengths,
        best.candidates,
    )


@lru_cache(maxsize=64)
def _combinations4(n: int) -> NDArray[np.intp]:
    """(C(n, 4), 4) every group of four of n indices (cached, read-only)."""
    out = np.array(list(itertools.combinations(range(n), 4)), dtype=np.intp).reshape(-1, 4)
    out.setflags(write=False)
    return out


def homographies_from_4_points(
    src: NDArray[np.float64], dst: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(m, 3, 3) exact homographies taking the four points ``src`` (4, 2) onto each of
    ``dst`` (m, 4, 2), by the 8 x 8 DLT systems (h33 = 1) solved together; a degenerate
    group gives NaN."""
    m = len(dst)
    A = np.zeros((m, 8, 8))
    b = np.zeros((m, 8))
    for i in range(4):
        x, y = src[i]
        u, v = dst[:, i, 0], dst[:, i, 1]
        A[:, 2 * i, 0], A[:, 2 * i, 1], A[:, 2 * i, 2] = x, y, 1.0
        A[:, 2 * i, 6], A[:, 2 * i, 7] = -u * x, -u * y
        A[:, 2 * i + 1, 3], A[:, 2 * i + 1, 4], A[:, 2 * i + 1, 5] = x, y, 1.0
        A[:, 2 * i + 1, 6], A[:, 2 * i + 1, 7] = -v * x, -v * y
        b[:, 2 * i], b[:, 2 * i + 1] = u, v
    det = np.linalg.det(A)
    ok = np.abs(det) > 1e-12
    A[~ok] = np.eye(8)
    h = np.linalg.solve(A, b[..., None])[..., 0]
    h[~ok] = np.nan
    return np.concatenate([h, np.ones((m, 1))], axis=1).reshape(m, 3, 3)


def _area_scale_batch(Hs: NDArray[np.float64], plane: NDArray[np.float64]) -> NDArray[np.float64]:
    """(m, 4) image pixels per plane unit^2 at the four plane points (4, 2) under each
    homography of (m, 3, 3): the Jacobian determinant of the projective map."""
    v = np.einsum("mij,kj->mki", Hs, np.column_stack([plane, np.ones(4)]))  # (m, 4, 3)
    w = v[..., 2]
    a, bb = Hs[:, None, 0, :2], Hs[:, None, 1, :2]  # (m, 1, 2)
    g = Hs[:, None, 2, :2]
    # J = (A w - p g^T) / w^2 with A the top-left 2x2, p = (v0, v1)
    j00 = (a[..., 0] * w - v[..., 0] * g[..., 0]) / w**2
    j01 = (a[..., 1] * w - v[..., 0] * g[..., 1]) / w**2
    j10 = (bb[..., 0] * w - v[..., 1] * g[..., 0]) / w**2
    j11 = (bb[..., 1] * w - v[..., 1] * g[..., 1]) / w**2
    return np.asarray(np.abs(j00 * j11 - j01 * j10), np.float64)


def rigid_plane_errors(
    Hs: NDArray[np.float64], center_px: NDArray[np.float64], focal_range_px: tuple[float, float]
) -> NDArray[np.float64]:
    """:func:`rigid_plane_error` of each homography of (m, 3, 3), vectorized (NaN -> inf)."""
    T = np.array([[1.0, 0.0, -center_px[0]], [0.0, 1.0, -center_px[1]], [0.0, 0.0, 1.0]])
    h = T @ Hs
    h = h / np.linalg.norm(h[:, :, :2].reshape(len(h), -1), axis=1)[:, None, None]
    P = h[:, 0, 0] * h[:, 0, 1] + h[:, 1, 0] * h[:, 1, 1]
    Q = h[:, 2, 0] * h[:, 2, 1]
    R = h[:, 0, 0] ** 2 + h[:, 1, 0] ** 2 - h[:, 0, 1] ** 2 - h[:, 1, 1] ** 2
    S = h[:, 2, 0] ** 2 - h[:, 2, 1] ** 2
    lo, hi = focal_range_px
    den = P * P + R * R
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(den > 0, -(P * Q + R * S) / np.where(den > 0, den, 1.0), 1.0 / (lo * hi))
    x = np.clip(x, 1.0 / hi**2, 1.0 / lo**2)
    f = 1.0 / np.sqrt(x)
    a1 = np.stack([h[:, 0, 0] / f, h[:, 1, 0] / f, h[:, 2, 0]], 1)
    a2 = np.stack([h[:, 0, 1] / f, h[:, 1, 1] / f, h[:, 2, 1]], 1)
    n1, n2 = np.linalg.norm(a1, axis=1), np.linalg.norm(a2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.maximum(np.abs((a1 * a2).sum(1)) / (n1 * n2), np.abs(n1 / n2 - 1.0))
    return np.asarray(np.where(np.isfinite(err), err, np.inf), np.float64)


def _area_scale(
    plane_mm: NDArray[np.float64], image_px: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Image pixels per plane mm^2 at each of the four plane points (4, 2) mm, by the
    Jacobian determinant of the homography taking them to ``image_px`` (4, 2)."""
    Hm = homography_from_4_points(plane_mm, image_px)
    v = np.column_stack([plane_mm, np.ones(4)]) @ Hm.T  # (4, 3) homogeneous image points
    w = v[:, 2]
    out = np.empty(4)
    for k in range(4):
        J = (Hm[:2, :2] * w[k] - np.outer(v[k, :2], Hm[2, :2])) / w[k] ** 2
        out[k] = abs(np.linalg.det(J))
    return out


def _border_step(
    image: NDArray[np.uint8],
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    offset: float,
    params: DetectParams,
    bend_px: float = 0.0,
) -> bool:
    """Whether the colour steps across the segment a -> b (px) the same way along it:
    24 points (the ``end_margin`` left out at both ends) sampled ``offset`` px to both
    sides; in the channel with the largest mean difference, the mean reaches
    ``params.min_border_step`` and three quarters of the points share its sign (a
    textured wall or noise differs too, but not coherently); and the bezel side is plain
    (its spread at most 10 grey levels + a quarter of the step). ``bend_px``: the border
    is the parabola through a and b that lies this many px outwards at the middle."""
    v = b - a
    n = float(np.hypot(*v))
    if n < 4:
        return False
    t = v / n
    nrm = np.array([-t[1], t[0]])
    s = np.linspace(params.end_margin, 1 - params.end_margin, 24)[:, None]
    pts = a + s * v - (bend_px * 4.0) * (s * (1.0 - s)) * nrm
    h, w = image.shape[:2]
    img = image if image.ndim == 3 else image[..., None]

    def sample(q: NDArray[np.float64]) -> NDArray[np.float64]:
        x = np.clip(np.round(q[:, 0]).astype(np.intp), 0, w - 1)
        y = np.clip(np.round(q[:, 1]).astype(np.intp), 0, h - 1)
        return img[y, x].astype(np.float64)

    outside = sample(pts - offset * nrm)  # the bezel side (nrm points into the screen)
    d = sample(pts + offset * nrm) - outside  # (24, channels), signed
    m = d.mean(axis=0)
    c = int(np.argmax(np.abs(m)))
    same = float(np.mean(np.sign(d[:, c]) == np.sign(m[c])))
    flat = float(outside[:, c].std()) <= 10.0 + 0.25 * abs(float(m[c]))  # a bezel is plain
    return bool(abs(m[c]) >= params.min_border_step and same >= 0.75 and flat)


def _inset(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    sa: NDArray[np.float64],
    sb: NDArray[np.float64],
    square_mm: float,
) -> float:
    """Largest inward distance (mm) from the landmark line a -> b to the screen border
    sa -> sb (at least the landmark square's half side, so W is never empty)."""
    v = (b - a) / np.linalg.norm(b - a)
    n = np.array([-v[1], v[0]])
    return float(max((sa - a) @ n, (sb - a) @ n, square_mm / 2.0))

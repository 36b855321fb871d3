"""The cursor of the camera mouse: the screen point under the image center (sec. 6.2.2-6.2.3).

Inputs are the four screen corners C1'..C4' in image pixels, ordered TL, TR, BR, BL
(x right, y down, origin at the center of the top-left pixel), and the image center C0'.
Outputs are normalized screen coordinates (u, v) in [0, 1] x [0, 1] (0, 0 = the screen's
top-left corner), ready for :class:`omnidev.screen.ScreenMapping`; points off the screen
fall outside [0, 1].

Two methods, selectable with ``method``:

- ``"affine"``: the dissertation's correction (eqs. 6.1-6.4) from three corners. Exact
  only when the view is affine (camera far away, screen facing it); its error grows
  with the obliqueness of the view.
- ``"homography"``: the plane-to-plane projective map from all four corners, exact for a
  planar screen seen by a pinhole camera.
"""

from __future__ import annotations

from typing import Literal

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from omnidev.mouse.landmarks import LandmarkLayout

Method = Literal["affine", "homography"]
_UNIT_SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _corners(corners_px: ArrayLike) -> NDArray[np.float64]:
    c = np.asarray(corners_px, dtype=np.float64)
    if c.shape != (4, 2) or not np.isfinite(c).all():
        raise ValueError(f"corners must be a finite (4, 2) array TL, TR, BR, BL, got {c.shape}")
    return c


def image_center(width: int, height: int) -> NDArray[np.float64]:
    """The image center C0' (pixels) of a ``width`` x ``height`` image: ((w-1)/2, (h-1)/2)."""
    return np.array([(width - 1) / 2.0, (height - 1) / 2.0])


def corrected_rectangle(corners_px: ArrayLike) -> NDArray[np.float64]:
    """Corners C1''..C4'' of the corrected rectangle S'' (sec. 6.2.3), in pixels.

    C1'' = (0, 0), C2'' = (L, 0), C3'' = (L, H), C4'' = (0, H) with

    - eq. 6.3: L = (|C1' - C2'| + |C3' - C4'|) / 2
    - eq. 6.4: H = (|C1' - C4'| + |C2' - C3'|) / 2

    Example:
        >>> corrected_rectangle([[10, 10], [110, 10], [110, 60], [10, 60]]).tolist()
        [[0.0, 0.0], [100.0, 0.0], [100.0, 50.0], [0.0, 50.0]]
    """
    c = _corners(corners_px)
    L = (np.linalg.norm(c[0] - c[1]) + np.linalg.norm(c[2] - c[3])) / 2.0  # eq. 6.3
    H = (np.linalg.norm(c[0] - c[3]) + np.linalg.norm(c[1] - c[2])) / 2.0  # eq. 6.4
    return np.array([[0.0, 0.0], [L, 0.0], [L, H], [0.0, H]])


def affine_coefficients(
    corners_px: ArrayLike, *, use: tuple[int, int, int] = (0, 1, 3)
) -> NDArray[np.float64]:
    """The affine map S' -> S'' of eqs. 6.1-1 and 6.1-2 as a 2x3 matrix [[a, b, c], [d, e, f]].

    - eq. 6.1-1: x'' = a x' + b y' + c
    - eq. 6.1-2: y'' = d x' + e y' + f

    solved from three corner pairs (C_i', C_i''), i in ``use`` (indices into TL, TR, BR, BL;
    the dissertation does not say which three, the default takes TL, TR, BL so that the
    origin C1'' and both axes are fitted exactly), S'' from :func:`corrected_rectangle`.
    """
    c = _corners(corners_px)
    if len(set(use)) != 3 or not all(0 <= i < 4 for i in use):
        raise ValueError(f"use must name three distinct corners 0..3, got {use}")
    target = corrected_rectangle(c)
    # Rows [x', y', 1] in float64 (cv2.getAffineTransform would round to float32).
    A = np.column_stack([c[list(use)], np.ones(3)])
    coef = np.linalg.solve(A, target[list(use)])  # (3, 2): columns (a, b, c), (d, e, f)
    return np.asarray(coef.T, dtype=np.float64)


def cursor_affine(
    corners_px: ArrayLike, center_px: ArrayLike, *, use: tuple[int, int, int] = (0, 1, 3)
) -> NDArray[np.float64]:
    """The cursor by the dissertation's affine correction (sec. 6.2.2, eqs. 6.1-6.4).

    C0'' = A(C0'), C1'' = A(C1') with A of eqs. 6.1 (:func:`affine_coefficients`), then
    eq. 6.2: u0 = k (x0'' - x1''), v0 = k (y0'' - y1''). Here k normalizes by the
    corrected rectangle's sides (k = 1/L for u0, 1/H for v0, eqs. 6.3-6.4), giving
    normalized screen coordinates; multiply by the screen's pixel size for eq. 6.2's
    pixels. (The bracketed right-hand side printed in eq. 6.2, k[a(x0'-x1') + b(y0'-y1')
    + c], equals k(x0'' - x1'' + c): the c cancels in the difference and should not be
    there; the definition k(x0'' - x1'') is what is computed.)

    Returns (2,) normalized (u, v).

    Example:
        >>> cursor_affine([[10, 10], [110, 10], [110, 60], [10, 60]], [60, 35]).round(9).tolist()
        [0.5, 0.5]
    """
    c = _corners(corners_px)
    p0 = np.asarray(center_px, dtype=np.float64).reshape(2)
    M = affine_coefficients(c, use=use)
    x0 = M[:, :2] @ p0 + M[:, 2]  # (x0'', y0''), eq. 6.1
    x1 = M[:, :2] @ c[0] + M[:, 2]  # (x1'', y1''), eq. 6.1 (= (0, 0) when TL is in ``use``)
    rect = corrected_rectangle(c)
    L, H = rect[2]
    return np.asarray((x0 - x1) / np.array([L, H]), dtype=np.float64)  # eq. 6.2


def homography_image_to_screen(corners_px: ArrayLike) -> NDArray[np.float64]:
    """3x3 homography mapping image pixels to normalized screen coordinates.

    Solved from the four corner correspondences C_i' -> unit square (direct linear
    transform, in float64); exact for a planar screen under perspective.
    """
    c = _corners(corners_px)
    return homography_from_4_points(c, _UNIT_SQUARE)


def homography_from_4_points(
    src: NDArray[np.float64], dst: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Exact 4-point homography src -> dst by the 8x8 DLT system (h33 = 1), float64."""
    A = np.zeros((8, 8))
    b = np.zeros(8)
    for i, ((x, y), (u, v)) in enumerate(zip(src, dst, strict=True)):
        A[2 * i] = [x, y, 1, 0, 0, 0, -u * x, -u * y]
        A[2 * i + 1] = [0, 0, 0, x, y, 1, -v * x, -v * y]
        b[2 * i], b[2 * i + 1] = u, v
    try:
        h = np.linalg.solve(A, b)
    except np.linalg.LinAlgError as exc:
        raise ValueError("degenerate quadrilateral: three corners are collinear") from exc
    return np.append(h, 1.0).reshape(3, 3)


def apply_homography(Hm: NDArray[np.float64], pts: ArrayLike) -> NDArray[np.float64]:
    """Map (n, 2) or (2,) points through a 3x3 homography (homogeneous divide)."""
    p = np.asarray(pts, dtype=np.float64)
    q = p.reshape(-1, 2) @ Hm[:, :2].T + Hm[:, 2]
    out = q[:, :2] / q[:, 2:3]
    return np.asarray(out.reshape(p.shape), dtype=np.float64)


def cursor_homography(corners_px: ArrayLike, center_px: ArrayLike) -> NDArray[np.float64]:
    """The cursor by a homography from the four corners: (2,) normalized (u, v).

    Example:
        >>> quad = [[10, 10], [110, 10], [110, 60], [10, 60]]
        >>> cursor_homography(quad, [60, 35]).round(9).tolist()
        [0.5, 0.5]
    """
    return apply_homography(homography_image_to_screen(corners_px), center_px)


def cursor_from_corners(
    corners_px: ArrayLike, center_px: ArrayLike, *, method: Method = "homography"
) -> NDArray[np.float64]:
    """The cursor (normalized (u, v)) from the screen corners by ``method``."""
    if method == "affine":
        return cursor_affine(corners_px, center_px)
    if method == "homography":
        return cursor_homography(corners_px, center_px)
    raise ValueError(f"unknown cursor method {method!r} (choose 'affine' or 'homography')")


def screen_corners_from_landmarks(
    landmark_centers_px: ArrayLike, layout: LandmarkLayout
) -> NDArray[np.float64]:
    """The screen corners C1'..C4' (image pixels) from the landmark centers C1..C4.

    The landmarks sit at known mm offsets from the screen corners in the monitor plane
    (``layout``); the homography of the landmark quadrilateral to that plane carries the
    screen corners (mm) back into the image, exactly under perspective.
    """
    c = _corners(landmark_centers_px)
    H_plane_to_image = homography_from_4_points(layout.landmark_centers_mm(), c)
    return apply_homography(H_plane_to_image, layout.screen_corners_mm())


def homography_check_opencv(corners_px: ArrayLike) -> NDArray[np.float64]:
    """The same map as :func:`homography_image_to_screen` by cv2.getPerspectiveTransform
    (float32 points), kept for cross-checking against OpenCV."""
    c = _corners(corners_px)
    Hm = cv2.getPerspectiveTransform(c.astype(np.float32), _UNIT_SQUARE.astype(np.float32))
    return np.asarray(Hm, dtype=np.float64)


def edges_to_pixel_centres(uv: ArrayLike, screen_px: tuple[int, int]) -> NDArray[np.float64]:
    """Normalized screen coordinates measured on the lit area's edges (0 = the left edge
    of pixel 0, 1 = the right edge of pixel N-1, what the corners' unit square gives)
    -> the pointer convention of :class:`omnidev.screen.ScreenMapping` (0 = the centre
    of pixel 0, 1 = the centre of pixel N-1) for a screen of ``screen_px`` (W, H) pixels.

    Example:
        >>> edges_to_pixel_centres([0.5 / 1920, 0.5], (1920, 1080)).round(12).tolist()
        [0.0, 0.5]
    """
    n = np.asarray(screen_px, np.float64)
    return np.asarray((np.asarray(uv, np.float64) * n - 0.5) / (n - 1), np.float64)


def rolling_shutter_correct(
    centers: NDArray[np.float64],
    previous: NDArray[np.float64],
    dt_s: float,
    readout_s: float,
    height: int,
    use: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Landmark centres (4, 2) px brought to the instant the image's centre row was
    read out, from a rolling shutter that reads rows top to bottom over ``readout_s``.

    Row v is read at ``(v - (H - 1) / 2) / H * readout_s`` from the centre row; each
    landmark moves back by its image velocity over that time. The velocity is its
    move since ``previous`` (the last frame's centres, ``dt_s`` earlier, read at their
    own rows' times); landmarks not in ``use`` (e.g. predicted ones) take the median
    velocity of those that are. Without usable landmarks the centres are returned as
    they are.
    """
    c = np.asarray(centers, np.float64)
    p = np.asarray(previous, np.float64)
    ok = np.ones(len(c), bool) if use is None else np.asarray(use, bool)
    if readout_s <= 0 or dt_s <= 0 or not ok.any():
        return c.copy()
    rc = (height - 1) / 2
    d_now = (c[:, 1] - rc) / height * readout_s
    d_prev = (p[:, 1] - rc) / height * readout_s
    vel = (c - p) / np.maximum(dt_s + d_now - d_prev, 0.25 * dt_s)[:, None]
    vel[~ok] = np.median(vel[ok], axis=0)
    return np.asarray(c - vel * d_now[:, None], np.float64)


class Lens:
    """A calibrated webcam lens (OpenCV's pinhole model with k1 k2 p1 p2 [k3 ...]):
    camera matrix ``K`` (3x3, px), distortion ``D`` and the image size it was
    calibrated at. :meth:`undistort` maps image pixels to the pixels of the same camera
    without distortion (a pinhole: straight lines stay straight, so the four-corner
    homography is exact)."""

    def __init__(self, K: ArrayLike, D: ArrayLike, size: tuple[int, int] | None = None) -> None:
        self.K = np.asarray(K, np.float64).reshape(3, 3)
        self.D = np.asarray(D, np.float64).reshape(-1)
        self.size = size

    def undistort(self, uv: ArrayLike) -> NDArray[np.float64]:
        """Distorted pixels (n, 2) -> undistorted pixels (n, 2) (iterative, to ~1e-9 px)."""
        p = np.asarray(uv, np.float64).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
        out = cv2.undistortPoints(p, self.K, self.D, R=None, P=self.K, criteria=crit)
        return np.asarray(out, np.float64).reshape(-1, 2)

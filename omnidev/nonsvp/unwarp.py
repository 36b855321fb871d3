"""Unwarping a misaligned hyperbolic-mirror camera's omni-image onto planar views.

Three ways, all for any planar view of :mod:`omnidev.views` (``TopView``,
``PlaneView``) whose points are in the mirror frame O_m, in millimetres:

- :func:`backprojected_view` — the dissertation's method (sec. 2.5.1): every
  omni pixel is back-projected (:func:`omnidev.nonsvp.backproject.backproject`)
  and its incident ray meets the view plane; the pixel's value lands on the
  nearest view pixel. The result has irregularly distributed unfilled pixels,
  which chapter 3 interpolates (:mod:`omnidev.nonsvp.interp`).
- :func:`dense_maps` — beyond the dissertation: every view pixel's plane point is
  projected into the omni-image numerically (:func:`omnidev.nonsvp.forward.project`),
  giving cv2.remap maps with no unfilled pixels.
- :func:`svp_maps` — the wrong-model baseline: the same with eq. 2.1's
  single-viewpoint mapping, as if the camera were aligned.

Pure: numpy in, numpy out. View pixels: row-major (H, W), centre of the top-left
pixel at (0, 0); omni pixels likewise.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.nonsvp.backproject import backproject
from omnidev.nonsvp.forward import project, project_svp_eq21
from omnidev.nonsvp.model import NonSvpCamera

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def view_plane(view: Any) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(origin, du, dv) of a planar view: the plane point of view pixel (0, 0) and the
    steps (mm) from one pixel to the next along a row (du) and down a column (dv)."""
    pts = np.asarray(view.points(None), np.float64)
    if pts.ndim != 3 or pts.shape[0] < 2 or pts.shape[1] < 2:
        raise ValueError("a view of at least 2 x 2 pixels is needed")
    o, du, dv = pts[0, 0], pts[0, 1] - pts[0, 0], pts[1, 0] - pts[0, 0]
    H, W = pts.shape[:2]
    flat = o + np.arange(W)[None, :, None] * du + np.arange(H)[:, None, None] * dv
    if not np.allclose(flat, pts, atol=1e-6 * max(1.0, float(np.abs(pts).max()))):
        raise ValueError(f"{type(view).__name__} is not a planar, evenly sampled view")
    return o, du, dv


def backprojected_values(
    cam: NonSvpCamera, values: NDArray[Any], view: Any
) -> tuple[NDArray[np.float64], BoolArray]:
    """Back-project any per-pixel values of the omni-image onto ``view``.

    Each omni pixel's incident ray (from its mirror point, in O_m) is cut with the
    view's plane; its value lands on the nearest view pixel (several landing on one
    pixel are averaged). Returns (view values (H, W[, C]) float64, filled (H, W)).
    """
    h, w = values.shape[:2]
    if (w, h) != tuple(cam.lens.size):
        raise ValueError(
            f"omni-image is {w}x{h}, the camera's is {cam.lens.size[0]}x{cam.lens.size[1]}"
        )
    o, du, dv = view_plane(view)
    n = np.cross(du, dv)
    n /= np.linalg.norm(n)
    vv, uu = np.mgrid[0:h, 0:w]
    uv = np.stack([uu.ravel(), vv.ravel()], axis=1).astype(np.float64)
    M, d, ok = backproject(cam, uv)
    denom = d @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((o - M) @ n) / denom
    ok &= np.isfinite(t) & (t > 0)
    X = M + t[:, None] * d
    # plane coordinates in view pixels: X - o = a du + b dv
    G = np.array([[du @ du, du @ dv], [du @ dv, dv @ dv]])
    rhs = np.stack([(X - o) @ du, (X - o) @ dv], axis=1)
    ab = np.linalg.solve(G, rhs.T).T
    H, W = np.asarray(view.points(None)).shape[:2]
    ci = np.rint(ab[:, 0])
    ri = np.rint(ab[:, 1])
    ok &= (ci >= 0) & (ci < W) & (ri >= 0) & (ri < H)
    idx = (ri[ok] * W + ci[ok]).astype(np.int64)
    src = values.reshape(h * w, -1)[ok].astype(np.float64)
    count = np.bincount(idx, minlength=H * W).astype(np.float64)
    chans = src.shape[1]
    acc = np.stack(
        [np.bincount(idx, weights=src[:, c], minlength=H * W) for c in range(chans)], axis=1
    )
    filled = count > 0
    out = np.zeros((H * W, chans))
    out[filled] = acc[filled] / count[filled, None]
    out = out.reshape((H, W, chans))
    return (out[:, :, 0] if values.ndim == 2 else out), filled.reshape(H, W)


def backprojected_view(
    cam: NonSvpCamera, omni: NDArray[np.uint8], view: Any
) -> tuple[NDArray[np.uint8], BoolArray]:
    """The dissertation's raw unwarped view (uint8, like ``omni``) and where it is filled
    (:func:`backprojected_values` of the omni-image's pixels)."""
    out, filled = backprojected_values(cam, omni, view)
    return np.clip(out + 0.5, 0, 255).astype(np.uint8), filled


def backprojected_edges(
    cam: NonSvpCamera, omni: NDArray[np.uint8], view: Any
) -> NDArray[np.float32]:
    """The edge-value image of sec. 3.2.2 on ``view``: the omni-image's Sobel edge value
    (:func:`omnidev.nonsvp.interp.sobel_edge_value`), unwarped the same way as its
    pixels; 0 where no omni pixel landed."""
    from omnidev.nonsvp.interp import sobel_edge_value

    gray = np.asarray(omni if omni.ndim == 2 else cv2.cvtColor(omni, cv2.COLOR_BGR2GRAY), np.uint8)
    e, _ = backprojected_values(cam, sobel_edge_value(gray), view)
    return e.astype(np.float32)


def dense_maps(
    cam: NonSvpCamera, view: Any
) -> tuple[NDArray[np.float32], NDArray[np.float32], BoolArray]:
    """(map_x, map_y, valid) for ``cv2.remap(omni, map_x, map_y, ...)``: each view pixel's
    plane point projected into the omni-image by the numerical forward projection."""
    pts = np.asarray(view.points(None), np.float64)
    H, W = pts.shape[:2]
    px, ok = project(cam, pts.reshape(-1, 3))
    w, h = cam.lens.size
    ok &= (px[:, 0] >= -0.5) & (px[:, 0] <= w - 0.5) & (px[:, 1] >= -0.5) & (px[:, 1] <= h - 0.5)
    px = np.where(ok[:, None], px, -1.0)
    return (
        px[:, 0].reshape(H, W).astype(np.float32),
        px[:, 1].reshape(H, W).astype(np.float32),
        ok.reshape(H, W),
    )


def svp_maps(
    cam: NonSvpCamera, view: Any, center: tuple[float, float] | None = None
) -> tuple[NDArray[np.float32], NDArray[np.float32], BoolArray]:
    """The same maps by eq. 2.1 (the single-viewpoint assumption), ignoring the pose.

    ``center``: the image centre eq. 2.1 uses (px); give the centre of the imaged
    mirror rim, as an SVP calibration would find it (a misaligned lens shifts the
    mirror's image by up to ~150 px); None uses the lens's principal point.
    """
    import dataclasses

    lens = cam.lens if center is None else dataclasses.replace(cam.lens, center=center)
    pts = np.asarray(view.points(None), np.float64)
    H, W = pts.shape[:2]
    px, ok = project_svp_eq21(cam.mirror, lens, pts.reshape(-1, 3))
    px = np.where(ok[:, None], px, -1.0)
    return (
        px[:, 0].reshape(H, W).astype(np.float32),
        px[:, 1].reshape(H, W).astype(np.float32),
        ok.reshape(H, W),
    )

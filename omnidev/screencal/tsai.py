"""Tsai's plane-to-plane calibration with one radial term (dissertation sec. 5.3.1).

Image pixel (x, y) -> distorted sensor point (eq. 5.8, with S_x = S_y = 1 / scale:
``u_d = (x - C_x) / scale``, C at the image centre, eq. 5.7) -> undistorted point
``u = u_d (1 + kappa1 r^2)`` (eq. 5.9) -> the ray (u, v, f) of the perspective camera
(eq. 5.10) -> the screen plane Z = 0 through the rigid motion R, T (eqs. 5.11-5.13;
R from a rotation vector). ``scale`` is the image half-diagonal in pixels so kappa1 is
unitless. Parameters are fitted by Levenberg-Marquardt on the screen-pixel
residuals, started from the homography's decomposition.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.screencal.lsq import levenberg_marquardt

FloatArray = NDArray[np.float64]


def _plane_matrix(p: FloatArray) -> FloatArray:
    """[f, kappa1, rx, ry, rz, tx, ty, tz] -> 3x3 M with (u, v, f) ~ M (X, Y, 1)."""
    rmat, _ = cv2.Rodrigues(p[2:5].reshape(3, 1))
    return np.asarray(np.c_[rmat[:, 0], rmat[:, 1], p[5:8]], np.float64)


def _apply(p: FloatArray, pts: FloatArray, centre: FloatArray, scale: float) -> FloatArray:
    ud = (pts - centre) / scale  # eq. 5.8
    r2 = (ud**2).sum(axis=1, keepdims=True)
    u = ud * (1 + p[1] * r2)  # eq. 5.9
    ray = np.c_[u, np.full(len(u), p[0])]  # eq. 5.10
    xyz = ray @ np.linalg.inv(_plane_matrix(p)).T  # eqs. 5.11-5.13, plane Z = 0
    return np.asarray(xyz[:, :2] / xyz[:, 2:], np.float64)


class TsaiMap:
    """Tsai's single-radial-term camera seeing the screen plane; screen = plane px."""

    name = "tsai"

    def __init__(self, p: FloatArray, image_size: tuple[int, int]) -> None:
        self.p = np.asarray(p, np.float64).ravel()
        w, h = image_size
        self.centre = np.array([(w - 1) / 2, (h - 1) / 2])  # eq. 5.7
        self.scale = 0.5 * float(np.hypot(w, h))

    @property
    def kappa1(self) -> float:
        """The radial distortion term of eq. 5.9 (r in image half-diagonals)."""
        return float(self.p[1])

    @classmethod
    def fit(cls, uv: FloatArray, xy: FloatArray, image_size: tuple[int, int]) -> TsaiMap:
        """Fit to image points ``uv`` (M, 2) with screen points ``xy`` (M, 2)."""
        model = cls(np.zeros(8), image_size)
        c, s = model.centre, model.scale
        # homography screen -> centred sensor; decompose H ~ K [r1 r2 T], K = diag(f, f, 1)
        hmat, _ = cv2.findHomography(xy, (uv - c) / s, 0)
        hm = np.asarray(hmat, np.float64)
        num = -(hm[0, 0] * hm[0, 1] + hm[1, 0] * hm[1, 1])
        den = hm[2, 0] * hm[2, 1]
        f2 = num / den if abs(den) > 1e-15 else 0.0
        if not f2 > 0:
            a = hm[0, 0] ** 2 + hm[1, 0] ** 2 - hm[0, 1] ** 2 - hm[1, 1] ** 2
            b = hm[2, 1] ** 2 - hm[2, 0] ** 2
            f2 = a / b if abs(b) > 1e-15 and a / b > 0 else 1.0
        f = float(np.sqrt(f2))
        m = np.diag([1 / f, 1 / f, 1.0]) @ hm
        lam = 1.0 / np.linalg.norm(m[:, 0])
        if m[2, 2] * lam < 0:
            lam = -lam
        r1, r2, t = m[:, 0] * lam, m[:, 1] * lam, m[:, 2] * lam
        u_, _, vt = np.linalg.svd(np.c_[r1, r2, np.cross(r1, r2)])
        rmat = u_ @ vt
        rvec, _ = cv2.Rodrigues(rmat)
        p0 = np.concatenate([[f, 0.0], rvec.ravel(), t])
        sx = float(np.ptp(xy[:, 0])) or 1.0
        p = levenberg_marquardt(lambda q: (_apply(q, uv, c, s) - xy).ravel() / sx, p0)
        return cls(p, image_size)

    def params(self) -> dict[str, FloatArray]:
        return {"tsai_params": self.p}

    def __call__(self, uv: FloatArray) -> FloatArray:
        return _apply(self.p, np.asarray(uv, np.float64).reshape(-1, 2), self.centre, self.scale)

"""A hand-held pinhole camera with radial distortion, and its pose.

Frames (all right-handed, metres): the *world* frame is the monitor's: origin at
the top-left corner of the screen's lit area, x to the right along the screen,
y down along the screen, z into the screen (away from the viewer). The *camera*
frame is OpenCV's: x right, y down, z along the optical axis. A pose holds the
camera centre ``C`` in world coordinates and ``R`` mapping world directions to
camera directions: ``X_cam = R @ (X_world - C)``.

Pixels: the centre of the top-left pixel is (0, 0); u to the right, v down.
Distortion is OpenCV's model on normalized coordinates (x, y) = (X/Z, Y/Z):
``x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)``,
``y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y`` with
``r^2 = x^2 + y^2``, then ``u = fx x_d + cx``, ``v = fy y_d + cy`` (the fixtures'
cameras use k1 and k2 only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class HandCamera:
    """Intrinsics (px) and distortion (OpenCV's k1, k2, p1, p2, k3) of the hand-held camera."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = -0.12
    k2: float = 0.02
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0

    @classmethod
    def default(cls, width: int = 640, height: int = 480) -> HandCamera:
        """A webcam-like lens: 56 degrees horizontal view, mild barrel distortion.

        The principal point is the image centre ((W-1)/2, (H-1)/2), so the
        optical axis passes through the image centre.
        """
        f = 600.0 * width / 640.0
        return cls(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0)

    def matrix(self) -> FloatArray:
        """The 3x3 camera matrix K (px)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def distortion(self) -> FloatArray:
        """OpenCV's distortion vector (k1, k2, p1, p2, k3)."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3])

    def _radial(self, r2: FloatArray) -> FloatArray:
        out: FloatArray = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        return out

    def _tangential(self, xy: FloatArray) -> FloatArray:
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        return np.stack(
            [
                2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x),
                self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y,
            ],
            -1,
        )

    def distort_normalized(self, xy: FloatArray) -> FloatArray:
        """Distort normalized coordinates (..., 2) -> distorted normalized (..., 2)."""
        r2 = np.sum(xy * xy, axis=-1, keepdims=True)
        out: FloatArray = xy * self._radial(r2)
        if self.p1 or self.p2:
            out = out + self._tangential(xy)
        return out

    def _undistort_radial(self, xy_d: FloatArray) -> FloatArray:
        rd = np.sqrt(np.sum(xy_d * xy_d, axis=-1))
        r = rd.copy()
        k1, k2, k3 = self.k1, self.k2, self.k3
        for _ in range(20):
            r2 = r * r
            f = r * self._radial(r2) - rd
            df = 1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + 7.0 * k3 * r2))
            r = r - f / df
        scale = np.where(rd > 0, r / np.where(rd > 0, rd, 1.0), 1.0)
        out: FloatArray = xy_d * scale[..., None]
        return out

    def undistort_normalized(self, xy_d: FloatArray) -> FloatArray:
        """Inverse of :meth:`distort_normalized`: Newton on the radius (~1e-14), and for
        the tangential terms a fixed-point iteration around it (~1e-12 for |p| <= 0.005).

        The radial polynomial r (1 + k1 r^2 + k2 r^4 + k3 r^6) must be increasing over
        the picture (the default coefficients and those of omnidev.sim.handheld are),
        so the inverse is unique.
        """
        if not (self.p1 or self.p2):
            return self._undistort_radial(xy_d)
        xy = self._undistort_radial(xy_d)
        for _ in range(12):
            xy = self._undistort_radial(xy_d - self._tangential(xy))
        return xy

    def pixel_to_normalized(self, uv: FloatArray) -> FloatArray:
        """Pixels (..., 2) -> undistorted normalized coordinates (..., 2)."""
        xd = np.stack([(uv[..., 0] - self.cx) / self.fx, (uv[..., 1] - self.cy) / self.fy], -1)
        return self.undistort_normalized(xd)

    def normalized_to_pixel(self, xy: FloatArray) -> FloatArray:
        """Undistorted normalized coordinates (..., 2) -> pixels (..., 2)."""
        d = self.distort_normalized(xy)
        return np.stack([self.fx * d[..., 0] + self.cx, self.fy * d[..., 1] + self.cy], -1)

    def max_normalized_radius(self) -> float:
        """The largest undistorted radius seen in the image (at its corners), plus 10 %.

        Projections beyond it are outside the picture however the polynomial
        folds; used to reject them.
        """
        corners = np.array(
            [
                [-0.5, -0.5],
                [self.width - 0.5, -0.5],
                [-0.5, self.height - 0.5],
                [self.width - 0.5, self.height - 0.5],
            ]
        )
        return float(np.max(np.linalg.norm(self.pixel_to_normalized(corners), axis=-1))) * 1.1


@dataclass(frozen=True)
class Pose:
    """Camera centre ``C`` (world, m) and rotation ``R`` (world -> camera)."""

    C: FloatArray
    R: FloatArray

    def to_camera(self, X: FloatArray) -> FloatArray:
        """World points (..., 3) -> camera-frame points (..., 3)."""
        out: FloatArray = (np.asarray(X, float) - self.C) @ self.R.T
        return out

    def optical_axis(self) -> FloatArray:
        """The optical axis (camera +z) as a world unit vector."""
        out: FloatArray = self.R[2].copy()
        return out


def look_at(C: FloatArray, target: FloatArray, roll_deg: float = 0.0) -> Pose:
    """A pose at ``C`` (world, m) whose optical axis passes through ``target``.

    With zero roll the camera's x axis is horizontal (perpendicular to world y
    and to the axis); ``roll_deg`` then turns the camera about its optical axis
    (degrees; positive turns the picture's content counter-clockwise on screen).
    """
    C = np.asarray(C, float)
    f = np.asarray(target, float) - C
    f /= np.linalg.norm(f)
    x = np.cross(np.array([0.0, 1.0, 0.0]), f)
    x /= np.linalg.norm(x)
    y = np.cross(f, x)
    R0 = np.stack([x, y, f])
    a = math.radians(roll_deg)
    Rz = np.array([[math.cos(a), math.sin(a), 0.0], [-math.sin(a), math.cos(a), 0.0], [0, 0, 1]])
    return Pose(C, Rz @ R0)


def project_points(
    cam: HandCamera, pose: Pose, X: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """World points (N, 3) -> distorted pixels (N, 2) and whether each is in the picture.

    "In the picture" means in front of the camera, within the undistorted radius
    the image covers, and inside [-0.5, W-0.5] x [-0.5, H-0.5].
    """
    Xc = pose.to_camera(np.atleast_2d(X))
    z = Xc[:, 2]
    front = z > 1e-9
    xy = Xc[:, :2] / np.where(front, z, 1.0)[:, None]
    uv = cam.normalized_to_pixel(xy)
    r = np.linalg.norm(xy, axis=-1)
    inside = (
        front
        & (r <= cam.max_normalized_radius())
        & (uv[:, 0] >= -0.5)
        & (uv[:, 0] <= cam.width - 0.5)
        & (uv[:, 1] >= -0.5)
        & (uv[:, 1] <= cam.height - 0.5)
    )
    return uv, inside

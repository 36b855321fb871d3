"""Imperfect mounts and sensors around an exact camera: a tilted axis and non-square pixels.

:class:`ImperfectCamera` wraps any rendered camera (``project`` / ``back_project``
in its own frame, z along its axis) and gives it

- a *tilt*: the camera's axis is turned against the world vertical. World
  directions d_w map to the base camera's frame by ``d_base = R d_w`` with
  ``R = rodrigues(tilt_axis_angle)``: the world frame of the wrapper is the
  landmarks' frame (Z up), the base camera's frame is tilted;
- *non-square pixels*: the base camera's image, relative to its center, is
  scaled by ``(1, aspect)`` and its center moved to ``center``, on an image of
  ``image_size`` (e.g. a 4:3 sensor read out at 1280 x 720: aspect 0.75).

Everything stays exact: ``project`` and ``back_project`` are the base camera's
composed with the rotation and the pixel scaling, so renders and exact maps
(:func:`omnidev.camera.build_maps`) agree with the landmarks to float precision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class _Base(Protocol):
    @property
    def image_size(self) -> tuple[int, int]: ...

    @property
    def center(self) -> tuple[float, float]: ...

    def default_elevation_deg(self) -> tuple[float, float]: ...

    def project(
        self, points: FloatArray, *, finite: bool = True
    ) -> tuple[FloatArray, BoolArray]: ...

    def back_project(self, uv: FloatArray) -> FloatArray: ...


def rotation_vector(axis_azimuth_deg: float, angle_deg: float) -> FloatArray:
    """3x3 rotation by ``angle_deg`` about the horizontal axis at ``axis_azimuth_deg``."""
    a, t = math.radians(axis_azimuth_deg), math.radians(angle_deg)
    k = np.array([math.cos(a), math.sin(a), 0.0])
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + math.sin(t) * K + (1 - math.cos(t)) * (K @ K), np.float64)


@dataclass(frozen=True)
class ImperfectCamera:
    """A base camera with a tilted mount and non-square pixels (a :class:`CameraModel`).

    Attributes:
        base: the exact camera (e.g. :class:`~omnidev.sim.SvpHyperbolicCamera`).
        rotation: (3, 3) world -> base-camera frame (identity: no tilt).
        aspect: v scale over u scale of the pixels (1: square).
        center: image center (u0, v0) px of the wrapped image (the base's center when None).
        size: (width, height) px of the wrapped image (the base's size when None).

    The base camera's own image bounds still apply (in its pixels): give it an
    image large enough for what the wrapped image shows.
    """

    base: _Base
    rotation: FloatArray
    aspect: float = 1.0
    center_px: tuple[float, float] | None = None
    size: tuple[int, int] | None = None
    kind: str = "sim-imperfect"

    @property
    def image_size(self) -> tuple[int, int]:
        return self.size if self.size is not None else self.base.image_size

    @property
    def center(self) -> tuple[float, float]:
        return self.center_px if self.center_px is not None else self.base.center

    @property
    def tilt_deg(self) -> float:
        """Angle between the camera axis and the world vertical, degrees."""
        c = float(np.clip(self.rotation[2, 2], -1.0, 1.0))
        return math.degrees(math.acos(c))

    def default_elevation_deg(self) -> tuple[float, float]:
        """The base's band narrowed by the tilt: what is seen at every world azimuth."""
        lo, hi = self.base.default_elevation_deg()
        t = self.tilt_deg
        return (lo + t, min(hi - t, 90.0 - t) if hi >= 90.0 else hi - t)

    def _to_base(self, uv: FloatArray) -> FloatArray:
        c, bc = self.center, self.base.center
        du = uv[..., 0] - c[0]
        dv = (uv[..., 1] - c[1]) / self.aspect
        return np.stack([bc[0] + du, bc[1] + dv], -1)

    def _from_base(self, uv: FloatArray) -> FloatArray:
        c, bc = self.center, self.base.center
        return np.stack([c[0] + uv[..., 0] - bc[0], c[1] + self.aspect * (uv[..., 1] - bc[1])], -1)

    def project(self, points: FloatArray, *, finite: bool = True) -> tuple[FloatArray, BoolArray]:
        p = np.asarray(points, np.float64) @ self.rotation.T
        uv_b, ok = self.base.project(p, finite=finite)
        uv = self._from_base(uv_b)
        w, h = self.image_size
        inside = (
            (uv[..., 0] >= -0.5)
            & (uv[..., 0] <= w - 0.5)
            & (uv[..., 1] >= -0.5)
            & (uv[..., 1] <= h - 0.5)
        )
        return uv, ok & inside

    def back_project(self, uv: FloatArray) -> FloatArray:
        """Unit world-frame directions (..., 3) of pixels (..., 2)."""
        d = self.base.back_project(self._to_base(np.asarray(uv, np.float64)))
        return np.asarray(d @ self.rotation, np.float64)


@dataclass(frozen=True)
class PolyFisheyeCamera:
    """A fisheye looking up (+z) with r = f (a + k1 a^3 + k2 a^5), a the angle from +z (rad).

    Not equidistant (k1 = k2 = 0 is), so a radial polynomial in the elevation
    cannot fit it exactly. Image u - u0 grows with x, v - v0 with y.
    """

    f: float  # px per radian
    k1: float
    k2: float
    image_size: tuple[int, int]
    center: tuple[float, float]
    max_angle: float  # rad from +z
    kind: str = "sim-poly-fisheye"

    def default_elevation_deg(self) -> tuple[float, float]:
        return (90.0 - math.degrees(self.max_angle), 90.0)

    def radius(self, a: FloatArray) -> FloatArray:
        a = np.asarray(a, np.float64)
        return np.asarray(self.f * (a + self.k1 * a**3 + self.k2 * a**5), np.float64)

    def project(self, points: FloatArray, *, finite: bool = True) -> tuple[FloatArray, BoolArray]:
        p = np.asarray(points, np.float64)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        a = np.arctan2(np.hypot(x, y), z)
        az = np.arctan2(y, x)
        r = self.radius(a)
        uv = np.stack([self.center[0] + r * np.cos(az), self.center[1] + r * np.sin(az)], -1)
        w, h = self.image_size
        valid = (
            (a <= self.max_angle)
            & (uv[..., 0] >= -0.5)
            & (uv[..., 0] <= w - 0.5)
            & (uv[..., 1] >= -0.5)
            & (uv[..., 1] <= h - 0.5)
        )
        return uv, valid

    def back_project(self, uv: FloatArray) -> FloatArray:
        uv = np.asarray(uv, np.float64)
        du = uv[..., 0] - self.center[0]
        dv = uv[..., 1] - self.center[1]
        r = np.hypot(du, dv)
        a = r / self.f
        for _ in range(20):  # Newton on f (a + k1 a^3 + k2 a^5) = r
            g = self.radius(a) - r
            dg = self.f * (1 + 3 * self.k1 * a**2 + 5 * self.k2 * a**4)
            a = a - g / dg
        bad = ~(np.abs(self.radius(a) - r) < 1e-6) | (a < 0) | (a > self.max_angle + 0.2)
        a = np.where(bad, np.nan, a)  # beyond the lens' field: no direction
        az = np.arctan2(dv, du)
        sa = np.sin(a)
        return np.stack([sa * np.cos(az), sa * np.sin(az), np.cos(a)], -1)

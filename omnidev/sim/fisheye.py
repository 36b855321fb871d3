"""An ideal equidistant fisheye looking up (+z): r = f * (angle from +z), exactly.

Image u - u0 grows with x and v - v0 with y, as for the mirror camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class EquidistantFisheyeCamera:
    """An equidistant fisheye: a :class:`omnidev.camera.CameraModel`."""

    f: float  # px per radian
    image_size: tuple[int, int]
    center: tuple[float, float]
    max_angle: float  # rad from the optical axis (+z)
    kind: str = "sim-equidistant"

    @classmethod
    def default(cls, size: int = 640) -> EquidistantFisheyeCamera:
        """190 degrees field of view filling 0.48 size of radius."""
        max_angle = math.radians(95.0)
        f = 0.48 * size / max_angle
        return cls(f, (size, size), (size / 2 - 0.5 - 1.7, size / 2 - 0.5 + 2.6), max_angle)

    def default_elevation_deg(self) -> tuple[float, float]:
        return (90.0 - math.degrees(self.max_angle), 90.0)

    def project(self, points: FloatArray, *, finite: bool = True) -> tuple[FloatArray, BoolArray]:
        p = np.asarray(points, np.float64)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        angle = np.arctan2(np.hypot(x, y), z)
        az = np.arctan2(y, x)
        r = self.f * angle
        uv = np.stack([self.center[0] + r * np.cos(az), self.center[1] + r * np.sin(az)], -1)
        w, h = self.image_size
        valid = (
            (angle <= self.max_angle)
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
        angle = np.hypot(du, dv) / self.f
        az = np.arctan2(dv, du)
        sa = np.sin(angle)
        return np.stack([sa * np.cos(az), sa * np.sin(az), np.cos(angle)], -1)

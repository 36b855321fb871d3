"""A single-viewpoint hyperbolic-mirror camera (dissertation eqs. 2.1-2.2), exactly.

Frame: origin at the mirror's focus O_w (the single viewpoint), z up towards
the mirror from the camera, which sits at the other focus (0, 0, -2c) looking
up. Mirror surface (eq. 2.2): z = -c + b sqrt(1 + r^2 / a^2), c = sqrt(a^2 + b^2),
cut at the rim radius. A scene point P is seen where the segment from P to O_w
meets the mirror; eq. 2.1 gives its pixel relative to the image center:

    u - u0 = f (b^2 - c^2) x / ((b^2 + c^2) z - 2 b c |P|),   v - v0 likewise with y.

Lengths of the mirror (a, b, rim) in mm; f in pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class SvpHyperbolicCamera:
    """An aligned (SVP) hypercatadioptric camera: a :class:`omnidev.camera.CameraModel`."""

    a: float  # mm
    b: float  # mm
    f: float  # px
    image_size: tuple[int, int]  # (width, height) px
    center: tuple[float, float]  # (u0, v0) px
    rim_radius: float  # mm, radius of the mirror's circular edge
    cutoff_radius: float  # px, the camera's own reflection around the center
    kind: str = "sim-svp-hyperbolic"

    @property
    def c(self) -> float:
        return math.hypot(self.a, self.b)

    @classmethod
    def default(cls, size: int = 640) -> SvpHyperbolicCamera:
        """A realistic mirror (a = 28.1, b = 23.4, rim 50 mm): elevations -75..+12.6 deg.

        f puts the rim at 0.48 size from the center; the center is off the image
        middle by (+3.4, -2.1) px so nothing can assume it.
        """
        a, b, rim = 28.1, 23.4, 50.0
        c = math.hypot(a, b)
        z_rim = -c + b * math.sqrt(1 + rim * rim / (a * a))
        rho = math.atan2(z_rim, rim)
        unit = a * a * math.cos(rho) / (2 * b * c - (b * b + c * c) * math.sin(rho))
        f = 0.48 * size / unit
        center = (size / 2 - 0.5 + 3.4, size / 2 - 0.5 - 2.1)
        return cls(a, b, f, (size, size), center, rim, 0.12 * size)

    @property
    def top_elevation(self) -> float:
        """Elevation (rad) of the rays reflected at the rim: the highest the camera sees."""
        z_rim = -self.c + self.b * math.sqrt(1 + self.rim_radius**2 / self.a**2)
        return math.atan2(z_rim, self.rim_radius)

    @property
    def bottom_elevation(self) -> float:
        """Elevation (rad) at the cut-off radius: the lowest the camera sees."""
        return float(self.elevation_of_radius(np.array(self.cutoff_radius)))

    def default_elevation_deg(self) -> tuple[float, float]:
        return (math.degrees(self.bottom_elevation), math.degrees(self.top_elevation))

    def radius_of_elevation(self, rho: FloatArray) -> FloatArray:
        """Exact image radius r(rho) in px (eq. 2.1 for a point at elevation rho)."""
        a, b, c = self.a, self.b, self.c
        rho = np.asarray(rho, np.float64)
        return np.asarray(
            self.f * a * a * np.cos(rho) / (2 * b * c - (b * b + c * c) * np.sin(rho)), np.float64
        )

    def elevation_of_radius(self, r: FloatArray) -> FloatArray:
        """Inverse of :meth:`radius_of_elevation`, rad."""
        d = self.back_project(
            np.stack(
                [self.center[0] + np.asarray(r, np.float64), np.full_like(r, self.center[1])], -1
            )
        )
        return np.asarray(np.arcsin(np.clip(d[..., 2], -1, 1)), np.float64)

    def project(self, points: FloatArray, *, finite: bool = True) -> tuple[FloatArray, BoolArray]:
        """Eq. 2.1 for (..., 3) points (or directions): (..., 2) pixels and a validity mask.

        Valid where the line to O_w meets the mirror inside its rim, the pixel
        is outside the cut-off disc and inside the image.
        """
        p = np.asarray(points, np.float64)
        a, b, c = self.a, self.b, self.c
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        R = np.sqrt(x * x + y * y + z * z)
        with np.errstate(divide="ignore", invalid="ignore"):
            den = (b * b + c * c) * z - 2 * b * c * R
            s = self.f * (b * b - c * c) / den
            uv = np.stack([self.center[0] + s * x, self.center[1] + s * y], -1)
            dz = z / R
            lam = a * a / (b - c * dz)  # distance from O_w to the mirror along the ray
            r_mirror = lam * np.sqrt(np.clip(1 - dz * dz, 0, None))
        r_img = np.hypot(uv[..., 0] - self.center[0], uv[..., 1] - self.center[1])
        w, h = self.image_size
        valid = (
            (den < 0)
            & (lam > 0)
            & (r_mirror <= self.rim_radius)
            & (r_img >= self.cutoff_radius)
            & (uv[..., 0] >= -0.5)
            & (uv[..., 0] <= w - 0.5)
            & (uv[..., 1] >= -0.5)
            & (uv[..., 1] <= h - 0.5)
        )
        return uv, valid & np.isfinite(uv).all(-1)

    def back_project(self, uv: FloatArray) -> FloatArray:
        """Unit directions (..., 3) from O_w of the scene points seen at pixels (..., 2).

        The inverse of eq. 2.1. With s = r / (f a^2) (r the pixel's radius),
        k = b^2 + c^2 and m = 2bc, the direction's z solves
        (s^2 k^2 + 1) z^2 - 2 s^2 m k z + s^2 m^2 - 1 = 0, whose discriminant is
        1 + s^2 a^4; the root with the minus sign is the one that gives z = -1 at
        the image center (the mirror's tip reflects the point straight below).
        """
        uv = np.asarray(uv, np.float64)
        a, b, c = self.a, self.b, self.c
        k, m = b * b + c * c, 2 * b * c
        du = uv[..., 0] - self.center[0]
        dv = uv[..., 1] - self.center[1]
        s = np.hypot(du, dv) / (self.f * a * a)
        s2 = s * s
        z = (s2 * m * k - np.sqrt(1 + s2 * a**4)) / (s2 * k * k + 1)
        g = (m - k * z) / (self.f * a * a)
        return np.stack([du * g, dv * g, z], -1)

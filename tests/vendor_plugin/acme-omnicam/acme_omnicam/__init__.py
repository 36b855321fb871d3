"""ACME OmniCam: an upward-looking equidistant fisheye (r = f * angle from the axis).

Uses only omnidev's public API: the calibration file helpers and the camera
model protocol.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omnidev.calibfile import check_header, open_storage, read_real
from omnidev.errors import CalibrationError

KIND = "acme-equidistant"


@dataclass(frozen=True)
class AcmeCamera:
    f_px: float
    center: tuple[float, float]
    image_size: tuple[int, int]
    max_angle_deg: float
    kind: str = KIND

    def default_elevation_deg(self) -> tuple[float, float]:
        return (90.0 - self.max_angle_deg, 90.0)

    def project(self, points: np.ndarray, *, finite: bool) -> tuple[np.ndarray, np.ndarray]:
        x, y, z = points[..., 0], points[..., 1], points[..., 2]
        angle = np.arctan2(np.hypot(x, y), z)
        az = np.arctan2(y, x)
        r = self.f_px * angle
        uv = np.stack([self.center[0] + r * np.cos(az), self.center[1] + r * np.sin(az)], -1)
        return uv, angle <= math.radians(self.max_angle_deg)


class AcmeUnwarper:
    kind = KIND

    def load(self, path: Path, options: Mapping[str, str]) -> AcmeCamera:
        if options:
            raise CalibrationError(f"{KIND} takes no options, got {', '.join(options)}")
        with open_storage(path) as fs:
            check_header(fs, path, KIND, 1)
            return AcmeCamera(
                read_real(fs, path, "f_px"),
                (read_real(fs, path, "cx"), read_real(fs, path, "cy")),
                (int(read_real(fs, path, "width")), int(read_real(fs, path, "height"))),
                read_real(fs, path, "max_angle_deg"),
            )

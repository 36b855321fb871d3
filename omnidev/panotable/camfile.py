"""Pano-mapping table files and the pano-table camera model.

File: cv2.FileStorage (``.yml`` or ``.yml.gz``) with ``kind: pano-table``,
``format_version: 1`` and the nodes listed in :func:`save_table`. The table
itself is stored (``table``: N x M, 2 channels, absolute pixels) so that a
table filled by any means can be used, not only by Algorithm 2.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omnidev.calibfile import check_header, open_storage, read_mat, read_real, write_storage
from omnidev.camera import BoolArray, FloatArray
from omnidev.errors import CalibrationError
from omnidev.panotable.table import LOOKUPS, Calibration, Lookup, PanoTable
from omnidev.views import azimuth_elevation

KIND = "pano-table"
FORMAT_VERSION = 1


def save_table(path: Path, calib: Calibration | PanoTable, *, force: bool = False) -> None:
    """Write a table (and, for a :class:`Calibration`, its landmark residuals) atomically."""
    table = calib.table if isinstance(calib, Calibration) else calib
    nodes: dict[str, object] = {
        "image_width": table.image_size[0],
        "image_height": table.image_size[1],
        "image_center": np.array(table.image_center, np.float64).reshape(1, 2),
        "radial_coeffs": np.asarray(table.coeffs, np.float64).reshape(1, -1),
        "rho_start_deg": math.degrees(table.rho_range[0]),
        "rho_end_deg": math.degrees(table.rho_range[1]),
        "M": table.M,
        "N": table.N,
        "azimuth_sign": table.azimuth_sign,
        "azimuth_offset_deg": math.degrees(table.azimuth_offset),
        "cutoff_radius": float(table.cutoff_radius),
    }
    if isinstance(calib, Calibration):
        nodes["landmark_radial_residual_px"] = calib.fit.residual_px.reshape(1, -1)
        nodes["landmark_reprojection_px"] = calib.reprojection_px.reshape(1, -1)
        nodes["radial_rms_px"] = calib.fit.rms_px
    nodes["table"] = table.table.astype(np.float32)
    write_storage(path, KIND, FORMAT_VERSION, nodes, force=force)


def load_table(path: Path) -> PanoTable:
    """Read a pano-table file; errors name the file and the key."""
    path = Path(path)
    with open_storage(path) as fs:
        check_header(fs, path, KIND, FORMAT_VERSION)
        coeffs = read_mat(fs, path, "radial_coeffs").reshape(-1)
        if coeffs.size != 5:
            raise CalibrationError(f"{path}: radial_coeffs has {coeffs.size} values, expected 5")
        center = read_mat(fs, path, "image_center").reshape(-1)
        if center.size != 2:
            raise CalibrationError(f"{path}: image_center must hold 2 values")
        M = int(read_real(fs, path, "M"))
        N = int(read_real(fs, path, "N"))
        table = read_mat(fs, path, "table")
        if table.ndim == 3 and table.shape == (N, M, 2):
            pass
        else:
            raise CalibrationError(
                f"{path}: table has shape {table.shape}, expected ({N}, {M}, 2) from M and N"
            )
        try:
            model = PanoTable(
                coeffs.astype(np.float64),
                (float(center[0]), float(center[1])),
                (int(read_real(fs, path, "image_width")), int(read_real(fs, path, "image_height"))),
                (
                    math.radians(read_real(fs, path, "rho_start_deg")),
                    math.radians(read_real(fs, path, "rho_end_deg")),
                ),
                M,
                N,
                int(read_real(fs, path, "azimuth_sign")),
                math.radians(read_real(fs, path, "azimuth_offset_deg")),
                read_real(fs, path, "cutoff_radius"),
            )
        except CalibrationError as exc:
            raise CalibrationError(f"{path}: {exc}") from None
        return model.with_table(table.astype(np.float64))


@dataclass(frozen=True)
class PanoTableCamera:
    """A camera described by a pano-mapping table (a :class:`omnidev.camera.CameraModel`).

    ``lookup`` selects how view directions find their pixel: "bilinear"
    (default), the dissertation's "nearest" entry, or "analytic".
    """

    table: PanoTable
    lookup: Lookup = "bilinear"
    kind: str = KIND

    @property
    def image_size(self) -> tuple[int, int]:
        return self.table.image_size

    def default_elevation_deg(self) -> tuple[float, float]:
        rs, re = self.table.rho_range
        return (math.degrees(rs), math.degrees(re))

    def project(self, points: FloatArray, *, finite: bool) -> tuple[FloatArray, BoolArray]:
        """Pixels of camera-frame points; only their direction from O_m matters (SVP model)."""
        theta, rho = azimuth_elevation(np.asarray(points, np.float64))
        return self.table.lookup(theta, rho, method=self.lookup)


def camera_from_file(path: Path, options: Mapping[str, str]) -> PanoTableCamera:
    """Load a pano-table camera; options: ``lookup=bilinear|nearest|analytic``."""
    unknown = sorted(set(options) - {"lookup"})
    if unknown:
        raise CalibrationError(f"pano-table has no option {unknown[0]!r} (options: lookup)")
    lookup = options.get("lookup", "bilinear")
    if lookup not in LOOKUPS:
        raise CalibrationError(
            f"pano-table option lookup={lookup!r}: choose one of {', '.join(LOOKUPS)}"
        )
    return PanoTableCamera(load_table(path), lookup)  # type: ignore[arg-type]

"""Pano-mapping table files and the pano-table camera model.

File: cv2.FileStorage (``.yml`` or ``.yml.gz``) with ``kind: pano-table``.

- ``format_version: 2`` (written since the generalized table): what *defines*
  the table, a few hundred bytes: the mapping's parameters (``radial_coeffs``,
  ``image_center``, ``azimuth_sign``, ``azimuth_offset_deg`` and, for the
  generalized table, ``aspect``, ``keystone``, ``tilt_rad``, ``harmonics``,
  ``harmonic_rho_norm`` and ``radial_base``: (gamma, c) of a unified-model
  radial term, absent when there is none), the table geometry (``M``, ``N``, ``rho_start_deg``,
  ``rho_end_deg``, ``cutoff_radius``, image size) and the fit's report. The
  table is rebuilt on load (Algorithm 2). A ``table`` node (N x M, 2 channels,
  absolute pixels) may be added (``store_table=True``) for a table filled by
  other means; it is then used as it is.
- ``format_version: 1`` (older files): the table is always stored; such files
  keep loading, with their stored table.

The file is parsed once (:func:`load_table`); ``omnidev.load_camera`` reads
the kind from the file's first bytes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from omnidev.budget import check_pixels
from omnidev.calibfile import open_storage, read_mat, read_real, read_string, write_storage
from omnidev.camera import INVALID, BoolArray, FloatArray, Maps
from omnidev.errors import CalibrationError, naming
from omnidev.panotable.general import table_angles
from omnidev.panotable.maps import view_maps as block_view_maps
from omnidev.panotable.table import (
    LOOKUPS,
    Calibration,
    GeneralCalibration,
    Lookup,
    PanoTable,
)
from omnidev.views import Panorama, View

KIND = "pano-table"
FORMAT_VERSION = 2
READS = (1, 2)
MAX_TABLE_SIDE = 32768
REBUILD_BYTES_PER_ENTRY = 32.0
"""Peak memory of loading (rebuilding) a table, bytes per entry (measured about 8; bound)."""


def save_table(
    path: Path,
    calib: Calibration | GeneralCalibration | PanoTable,
    *,
    force: bool = False,
    store_table: bool = False,
) -> None:
    """Write a table's definition (and, for a calibration, its fit report) atomically.

    ``store_table`` also writes the table entries (needed only for a table
    whose entries were not filled from its mapping).
    """
    table = calib if isinstance(calib, PanoTable) else calib.table
    m = table.mapping
    nodes: dict[str, object] = {
        "method": table.method,
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
    if table.method == "general":
        nodes["aspect"] = float(m.aspect)
        nodes["keystone"] = np.array(m.keystone, np.float64).reshape(1, 2)
        nodes["tilt_rad"] = np.array(m.tilt, np.float64).reshape(1, 2)
        nodes["tilt_deg"] = m.tilt_deg
        nodes["harmonic_rho_norm"] = np.array(m.rho_norm, np.float64).reshape(1, 2)
        if m.radial_base[0] != 0.0:
            nodes["radial_base"] = np.array(m.radial_base, np.float64).reshape(1, 2)
        if m.harmonics.size:
            nodes["harmonics"] = m.harmonics.reshape(-1, 4).astype(np.float64)
            nodes["harmonics_shape"] = np.array(m.harmonics.shape[:2], np.float64).reshape(1, 2)
    if isinstance(calib, Calibration):
        nodes["landmark_radial_residual_px"] = calib.fit.residual_px.reshape(1, -1)
        nodes["landmark_reprojection_px"] = calib.reprojection_px.reshape(1, -1)
        nodes["radial_rms_px"] = calib.fit.rms_px
    elif isinstance(calib, GeneralCalibration):
        nodes["terms"] = calib.fit.terms.describe()
        nodes["landmark_reprojection_px"] = calib.reprojection_px.reshape(1, -1)
        nodes["landmark_heldout_px"] = calib.heldout_px.reshape(1, -1)
        nodes["reprojection_rms_px"] = calib.fit.rms_px
        nodes["heldout_rms_px"] = calib.fit.heldout_rms_px
    if store_table:
        nodes["table"] = table.table.astype(np.float32)
    write_storage(path, KIND, FORMAT_VERSION, nodes, force=force)


def _opt_mat(fs: object, path: Path, key: str, size: int) -> FloatArray | None:
    node = fs.getNode(key)  # type: ignore[attr-defined]
    if node.empty():
        return None
    a = read_mat(fs, path, key).reshape(-1).astype(np.float64)  # type: ignore[arg-type]
    if a.size != size:
        raise CalibrationError(f"{path}: {key} has {a.size} values, expected {size}")
    return np.asarray(a, np.float64)


def load_table(path: Path) -> PanoTable:
    """Read a pano-table file (format 1 or 2) in one parse; errors name the file and the key."""
    path = Path(path)
    with open_storage(path) as fs:
        kind = read_string(fs, path, "kind")
        if kind != KIND:
            raise CalibrationError(f"{path}: a calibration of kind {kind!r}, not {KIND!r}")
        version = int(read_real(fs, path, "format_version"))
        if version not in READS:
            raise CalibrationError(
                f"{path}: {KIND} format version {version}; this omnidev reads versions "
                f"{', '.join(map(str, READS))}"
            )
        coeffs = read_mat(fs, path, "radial_coeffs").reshape(-1)
        if version == 1 and coeffs.size != 5:
            raise CalibrationError(f"{path}: radial_coeffs has {coeffs.size} values, expected 5")
        if not 2 <= coeffs.size <= 12:
            raise CalibrationError(f"{path}: radial_coeffs has {coeffs.size} values (2 to 12)")
        center = read_mat(fs, path, "image_center").reshape(-1)
        if center.size != 2:
            raise CalibrationError(f"{path}: image_center must hold 2 values")
        M = int(read_real(fs, path, "M"))
        N = int(read_real(fs, path, "N"))
        if not (1 <= M <= MAX_TABLE_SIDE and 1 <= N <= MAX_TABLE_SIDE):
            raise CalibrationError(
                f"{path}: table size M x N = {M} x {N}; each must be 1..{MAX_TABLE_SIDE}"
            )
        check_pixels(M, N, REBUILD_BYTES_PER_ENTRY, f"{path}: its {M}x{N} pano-mapping table")
        extra: dict[str, object] = {}
        if version >= 2:
            if not fs.getNode("aspect").empty():
                extra["aspect"] = read_real(fs, path, "aspect")
            for key, name in (("keystone", "keystone"), ("tilt_rad", "tilt")):
                v = _opt_mat(fs, path, key, 2)
                if v is not None:
                    extra[name] = (float(v[0]), float(v[1]))
            v = _opt_mat(fs, path, "radial_base", 2)
            if v is not None:
                if not np.all(np.isfinite(v)):
                    raise CalibrationError(f"{path}: radial_base must be finite")
                extra["radial_base"] = (float(v[0]), float(v[1]))
            v = _opt_mat(fs, path, "harmonic_rho_norm", 2)
            if v is not None:
                if not v[1] > 0:
                    raise CalibrationError(f"{path}: harmonic_rho_norm half-range must be > 0")
                extra["rho_norm"] = (float(v[0]), float(v[1]))
            if not fs.getNode("harmonics").empty():
                shape = _opt_mat(fs, path, "harmonics_shape", 2)
                h = read_mat(fs, path, "harmonics").astype(np.float64)
                if shape is None or h.shape != (int(shape[0]) * int(shape[1]), 4):
                    raise CalibrationError(
                        f"{path}: harmonics has shape {h.shape}, which harmonics_shape "
                        "(K, D + 1) does not explain (expected K (D + 1) rows of 4)"
                    )
                extra["harmonics"] = h.reshape(int(shape[0]), int(shape[1]), 4)
        table: NDArray[np.float32] | None = None
        if version == 1 or not fs.getNode("table").empty():
            t = read_mat(fs, path, "table")
            if not (t.ndim == 3 and t.shape == (N, M, 2)):
                raise CalibrationError(
                    f"{path}: table has shape {t.shape}, expected ({N}, {M}, 2) from M and N"
                )
            table = np.asarray(t, np.float32)
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
                **extra,  # type: ignore[arg-type]
            )
        except CalibrationError as exc:
            raise CalibrationError(naming(path, exc)) from None
    if table is not None:
        return model.with_table(table)
    return model  # the entries are filled from the mapping when a lookup needs them


@dataclass(frozen=True)
class PanoTableCamera:
    """A camera described by a pano-mapping table (a :class:`omnidev.camera.CameraModel`).

    ``lookup`` selects how view directions find their pixel: "bilinear", the
    dissertation's "nearest" entry, or "analytic" (the table's mapping itself).
    None (the default) takes "analytic" for a table defined by its mapping (a
    format-2 file: its bilinear lookup differs from the mapping by the
    interpolation error of a table of about one entry per pixel, under 1e-3 px,
    and costs building the table) and "bilinear" for a table whose entries were
    given (format 1, or ``store_table=True``).
    """

    table: PanoTable
    lookup: Lookup | None = None
    kind: str = KIND

    @property
    def image_size(self) -> tuple[int, int]:
        return self.table.image_size

    @property
    def resolved_lookup(self) -> Lookup:
        """The lookup used: ``lookup``, or the default for this table (see the class)."""
        if self.lookup is not None:
            return self.lookup
        return "bilinear" if self.table.stored_entries else "analytic"

    def default_elevation_deg(self) -> tuple[float, float]:
        """The table's elevation range; with a tilt, the band seen at every world azimuth."""
        rs, re = self.table.rho_range
        tilt = math.hypot(*self.table.tilt)
        lo = rs + tilt
        hi = math.pi / 2 if re >= math.pi / 2 - tilt - 1e-9 else re - tilt
        return (math.degrees(lo), math.degrees(hi))

    def project(self, points: FloatArray, *, finite: bool) -> tuple[FloatArray, BoolArray]:
        """Pixels of camera-frame points; only their direction from O_m matters (SVP model)."""
        theta, rho = table_angles(np.asarray(points, np.float64), self.table.tilt)
        return self.table.lookup(theta, rho, method=self.resolved_lookup)

    def view_maps(self, view: View) -> Maps:
        """Maps for ``view`` in row blocks, without the view's 3-D points (about 10-16 bytes
        per output pixel at peak; :mod:`omnidev.panotable.maps`).

        A panorama of an untilted table read through the table's entries goes
        from its column azimuths and row elevations straight to the entries
        (:func:`grid_maps`).
        """
        band = self.default_elevation_deg()
        lookup = self.resolved_lookup
        if isinstance(view, Panorama) and lookup != "analytic" and self.table.tilt == (0.0, 0.0):
            theta, rho = view.angles(band)
            return grid_maps(self.table, theta, rho, lookup)
        return block_view_maps(self.table, view, lookup, band)


BLOCK_PIXELS = 1 << 16
"""Output pixels per block of map building (bounds the temporaries)."""


def _empty_maps(H: int, W: int, size: tuple[int, int]) -> Maps:
    return Maps(
        np.empty((H, W), np.float32), np.empty((H, W), np.float32), np.empty((H, W), bool), size
    )


def _store(
    maps: Maps,
    r0: int,
    u: FloatArray | NDArray[np.float32],
    v: FloatArray | NDArray[np.float32],
    ok: BoolArray,
) -> None:
    """Write one block of rows: valid where ``ok`` and inside the image (half-pixel margin)."""
    w, h = maps.source_size
    ok = ok & (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
    n = ok.shape[0]
    maps.valid[r0 : r0 + n] = ok
    maps.map_x[r0 : r0 + n] = np.where(ok, u, INVALID)
    maps.map_y[r0 : r0 + n] = np.where(ok, v, INVALID)


def grid_maps(table: PanoTable, theta: FloatArray, rho: FloatArray, lookup: Lookup) -> Maps:
    """Maps of a grid of directions: azimuth per column (W,), elevation per row (H,), table frame.

    The table is read row block by row block: for "bilinear" each output row
    first interpolates between its two table rows (a (M + 1, 2) row), then
    between the two columns of each output column.
    """
    theta = np.asarray(theta, np.float64)
    rho = np.asarray(rho, np.float64)
    H, W = rho.size, theta.size
    maps = _empty_maps(H, W, table.image_size)
    rs, re = table.rho_range
    fi = np.mod(theta, 2 * math.pi) / (2 * math.pi / table.M)
    fj = (rho - rs) / ((re - rs) / table.N)
    row_ok = (fj >= 0) & (fj < table.N) & np.isfinite(fj)
    fj = np.where(row_ok, fj, 0.0)
    i0 = np.floor(fi).astype(np.intp) % table.M
    a = (fi - np.floor(fi)).astype(np.float32)[None, :]
    j0 = np.clip(np.floor(fj).astype(np.intp), 0, table.N - 1)
    b = (fj - j0).astype(np.float32)
    block = max(1, BLOCK_PIXELS // W)
    t = table.padded if lookup != "analytic" else None
    u: FloatArray | NDArray[np.float32]
    v: FloatArray | NDArray[np.float32]
    for r0 in range(0, H, block):
        sl = slice(r0, r0 + block)
        n = len(j0[sl])
        if lookup == "analytic":
            tt, rr = np.meshgrid(theta, rho[sl])
            u, v = table.mapping.pixels(tt, rr)
        elif lookup == "nearest":
            assert t is not None
            e = t[j0[sl][:, None], np.floor(fi).astype(np.intp)[None, :] % table.M]
            u, v = e[..., 0], e[..., 1]
        elif lookup == "bilinear":
            assert t is not None
            bb = b[sl][:, None, None]
            rows = (1 - bb) * t[j0[sl]] + bb * t[j0[sl] + 1]  # (n, M + 1, 2)
            u = (1 - a) * rows[:, i0, 0] + a * rows[:, i0 + 1, 0]
            v = (1 - a) * rows[:, i0, 1] + a * rows[:, i0 + 1, 1]
        else:
            raise ValueError(f"unknown lookup {lookup!r}; choose one of {', '.join(LOOKUPS)}")
        ok = np.broadcast_to(row_ok[sl][:, None], (n, W))
        if table.cutoff_radius > 0:
            ok = ok & table._outside_cutoff(u, v)
        _store(maps, r0, u, v, ok)
    return maps


def camera_from_file(path: Path, options: Mapping[str, str]) -> PanoTableCamera:
    """Load a pano-table camera; options: ``lookup=bilinear|nearest|analytic``."""
    unknown = sorted(set(options) - {"lookup"})
    if unknown:
        raise CalibrationError(f"pano-table has no option {unknown[0]!r} (options: lookup)")
    lookup = options.get("lookup")
    if lookup is not None and lookup not in LOOKUPS:
        raise CalibrationError(
            f"pano-table option lookup={lookup!r}: choose one of {', '.join(LOOKUPS)}"
        )
    return PanoTableCamera(load_table(path), lookup)  # type: ignore[arg-type]

"""OCamCalib corner sets (../shared/realdata) as pano-table landmark pairs.

calibration_and_corners.json holds, per calibration method, the OCamCalib model
(Scaramuzza polynomial ss, center xc (row) / yc (column), 1-based, affine c d e)
and, per view, the chessboard corners (MATLAB 1-based row/column) with the
view's extrinsics [r1 r2 t]: a corner's camera-frame point is
P = [r1 r2 t] @ [X, Y, 1] (board plane Z = 0, mm). OCamCalib's camera frame has
x along image rows and y along columns; the mirror's viewpoint is its origin.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class OcamCorners:
    uv: np.ndarray  # (n, 2) 0-based (column, row) pixels
    xyz: np.ndarray  # (n, 3) camera-frame points, mm
    view: np.ndarray  # (n,) index of the view each corner comes from
    images: list[str]
    model: dict
    image_center: tuple[float, float]  # 0-based (u0, v0)
    image_size: tuple[int, int]
    published_rms_px: float


def load_corners(path: Path, method: str = "ocamcalib_subpixel") -> OcamCorners:
    data = json.loads(Path(path).read_text())
    board = data["board"]
    XY1 = np.stack([board["X_mm"], board["Y_mm"], np.ones(len(board["X_mm"]))])
    m = data["methods"][method]
    model = m["model"]
    uv, xyz, view, images = [], [], [], []
    for i, v in enumerate(m["views"]):
        M = np.array(v["RRfin_r1_r2_t"], np.float64)
        xyz.append((M @ XY1).T)
        uv.append(np.stack([np.array(v["corner_col"]) - 1, np.array(v["corner_row"]) - 1], 1))
        view.append(np.full(XY1.shape[1], i))
        images.append(v["image"])
    return OcamCorners(
        np.concatenate(uv),
        np.concatenate(xyz),
        np.concatenate(view),
        images,
        model,
        (model["yc_col_1based"] - 1, model["xc_row_1based"] - 1),
        (model["width"], model["height"]),
        float(model["rms_stored"]),
    )


def ocam_project(model: dict, xyz: np.ndarray) -> np.ndarray:
    """OCamCalib's world2cam via its forward polynomial ss(rho)/rho = z/n: 0-based (u, v)."""
    ss = np.array(model["ss"], np.float64)
    out = np.empty((len(xyz), 2))
    for k, (x, y, z) in enumerate(xyz):
        n = np.hypot(x, y)
        poly = ss[::-1].copy()  # highest degree first for np.roots
        poly[-2] -= z / n  # ss(rho) - (z/n) rho = 0
        roots = np.roots(poly)
        real = roots[(np.abs(roots.imag) < 1e-9) & (roots.real > 0)].real
        rho = real.min()
        a, b = x / n * rho, y / n * rho
        row = model["c"] * a + model["d"] * b + model["xc_row_1based"]
        col = model["e"] * a + b + model["yc_col_1based"]
        out[k] = (col - 1, row - 1)
    return out

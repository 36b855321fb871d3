"""Real calibrations of real cameras (../shared/realdata) through omnidev.fisheye.formats.

- OCamCalib (Urban's sample sets): the imported calib_*.txt reprojects each set's stored
  chessboard corners (calibration_and_corners.json: per view [r1 r2 t], board points)
  with the stored RMS.
- Mei paracatadioptric: the cv2.omnidir calibration loads as the unified model and
  reprojects Mei's corners with the stored per-view RMS.
- TUM-VI: the KB4, double sphere and EUCM calibrations of the same lenses project the
  same rays to within 1 px.

Skipped, with the reason, when ../shared/realdata is absent.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from typing import Any

import cv2
import numpy as np
import pytest

from omnidev.errors import CalibrationError
from omnidev.fisheye.formats import import_calibration
from omnidev.fisheye.models import EUCM, DoubleSphere, KannalaBrandt, Scaramuzza, Unified
from tests.conftest import REALDATA

pytestmark = pytest.mark.skipif(
    not REALDATA.is_dir(), reason=f"{REALDATA} absent (shared/realdata not mounted)"
)

OCAM = REALDATA / "ocamcalib_urban_samples"
SETS = ("KaidanOmni", "MiniOmni", "Fisheye1", "Ladybug")
# calib_*.txt file of each method in calibration_and_corners.json, and the factor from its
# stored 'rms' to the RMS point error: Urban's bundle adjustment stores the per-coordinate
# RMS (SOURCE.txt), i.e. the point RMS / sqrt(2).
METHODS = {
    "ocamcalib_subpixel": ("calib_ocamcalib_subpixel.txt", 1.0),
    "urban_ba": ("calib_urban_ba.txt", math.sqrt(2.0)),
}
TUMVI = REALDATA / "tumvi_fisheye" / "calib"


def ocam_corners(data: dict[str, Any], method: str) -> tuple[np.ndarray, np.ndarray]:
    """(optical-frame points, 0-based (u, v) corners) of all views of ``method``.

    OCamCalib's camera frame (x along rows, y along columns, scene at -z) maps to the
    optical frame as (x, y, z)_opt = (y, x, -z)_ocam; corners are MATLAB 1-based.
    """
    board = data["board"]
    xy1 = np.stack([board["X_mm"], board["Y_mm"], np.ones(len(board["X_mm"]))])
    pts, uv = [], []
    for v in data["methods"][method]["views"]:
        p = (np.array(v["RRfin_r1_r2_t"], np.float64) @ xy1).T
        pts.append(np.stack([p[:, 1], p[:, 0], -p[:, 2]], 1))
        uv.append(np.stack([np.array(v["corner_col"]) - 1, np.array(v["corner_row"]) - 1], 1))
    return np.concatenate(pts), np.concatenate(uv)


def rms(lens: Any, pts: np.ndarray, uv: np.ndarray) -> float:
    q, ok = lens.project(pts)
    assert ok.all()
    return float(np.sqrt(np.mean(np.sum((q - uv) ** 2, axis=1))))


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("name", SETS)
def test_ocamcalib_import_reproduces_the_stored_rms(name: str, method: str) -> None:
    data = json.loads((OCAM / name / "calibration_and_corners.json").read_text())
    filename, factor = METHODS[method]
    got = import_calibration(OCAM / name / filename)
    lens = got.lens
    assert isinstance(lens, Scaramuzza) and lens.invpol is not None
    stored = data["methods"][method]["model"]
    assert got.image_size == (stored["width"], stored["height"])
    assert (lens.xc, lens.yc) == pytest.approx(
        (stored["xc_row_1based"] - 1, stored["yc_col_1based"] - 1), abs=1e-6
    )
    pts, uv = ocam_corners(data, method)
    with_invpol = rms(lens, pts, uv)  # world2cam as OCamCalib's C code does it
    with_ss = rms(dataclasses.replace(lens, invpol=None), pts, uv)  # the ss root, as the JSON
    expected = stored["rms_stored"] * factor
    print(
        f"{name} {method}: {len(uv)} corners, RMS {with_ss:.4f} px (ss) / {with_invpol:.4f} px "
        f"(invpol), stored {expected:.4f} px"
    )
    assert with_ss == pytest.approx(expected, rel=1e-3)
    assert with_invpol == pytest.approx(expected, rel=0.02)


def test_ocamcalib_matsuren_fisheye1600_loads() -> None:
    got = import_calibration(REALDATA / "ocamcalib_matsuren_fisheye1600" / "calib_results_0.txt")
    lens = got.lens
    assert isinstance(lens, Scaramuzza) and got.image_size == (1600, 1600)
    assert (lens.xc, lens.yc) == (794.308657, 798.175741)
    assert lens.ss[0] == -471.4441 and lens.invpol is not None and len(lens.invpol) == 10
    # its world2cam polynomial inverts its cam2world polynomial over the image circle
    theta = np.radians(np.linspace(0.0, 95.0, 200))
    rays = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], 1)
    q1, ok1 = lens.project(rays)
    q2, ok2 = dataclasses.replace(lens, invpol=None).project(rays)
    diff = float(np.abs(q1 - q2).max())
    print(f"matsuren fisheye1600: invpol vs ss up to 95 deg: max {diff:.4f} px")
    assert ok1.all() and ok2.all() and diff < 0.05


def test_mei_paracatadioptric_loads_and_reprojects_its_corners() -> None:
    path = REALDATA / "mei_paracatadioptric" / "calibration_and_corners.json"
    got = import_calibration(path)  # an OpenCV FileStorage JSON with K, D, xi
    lens = got.lens
    data = json.loads(path.read_text())
    assert isinstance(lens, Unified) and got.format == "opencv"
    assert lens.xi == data["xi"] and lens.skew == data["K"][0][1]
    assert (lens.k1, lens.k2, lens.p1, lens.p2) == tuple(data["D"])
    errors = []
    for v in data["views"]:
        xyz = np.array(v["board_XYZ_mm"]) / 1000.0  # the fitted poses are in metres
        rvec, tvec = np.array(v["fitted_rvec"]), np.array(v["fitted_tvec_m"])
        pts = xyz @ cv2.Rodrigues(rvec)[0].T + tvec
        q, ok = lens.project(pts)
        assert ok.all()
        ref, _ = cv2.omnidir.projectPoints(
            xyz.reshape(-1, 1, 3), rvec, tvec, np.array(data["K"]), data["xi"],
            np.array(data["D"]).reshape(1, 4),
        )  # fmt: skip
        assert np.abs(q - ref.reshape(-1, 2)).max() < 1e-9
        e = np.linalg.norm(q - np.array(v["corners_uv"]), axis=1)
        assert float(np.sqrt(np.mean(e**2))) == pytest.approx(v["reproj_rms_px"], rel=1e-9)
        errors.append(e)
    e = np.concatenate(errors)
    per_view = [float(np.sqrt(np.mean(x**2))) for x in errors]
    print(
        f"Mei paracatadioptric: {len(e)} corners, RMS {np.sqrt(np.mean(e**2)):.3f} px; "
        "per view " + " ".join(f"{r:.2f}" for r in per_view)
    )


def tumvi_lenses(camera: str) -> dict[str, Any]:
    return {
        "kb4": import_calibration(TUMVI / "tumvi_512_kb4_official.yaml", camera=camera).lens,
        "ds": import_calibration(TUMVI / "basalt_tumvi_512_ds_calib.json", camera=camera).lens,
        "eucm": import_calibration(TUMVI / "basalt_tumvi_512_eucm_calib.json", camera=camera).lens,
        "eucm-cim": import_calibration(TUMVI / f"camera-intrinsic-model_eucm{camera}.json").lens,
    }


def test_tumvi_files_load() -> None:
    for camera in ("0", "1"):
        lenses = tumvi_lenses(camera)
        assert isinstance(lenses["kb4"], KannalaBrandt)
        assert isinstance(lenses["ds"], DoubleSphere)
        assert isinstance(lenses["eucm"], EUCM) and isinstance(lenses["eucm-cim"], EUCM)
    # the TUM monoVO calibration is a FOV (Devernay-Faugeras) model omnidev does not have
    with pytest.raises(CalibrationError, match="model 'FovCamera' is not read"):
        import_calibration(TUMVI / "camera-intrinsic-model_fov_tum_mono.json")


@pytest.mark.parametrize("camera", ["0", "1"])
def test_tumvi_models_agree_on_rays(camera: str) -> None:
    """Unproject a pixel grid with one model, project with another: within 1 px up to 100
    degrees from the axis (the image corners beyond are outside the calibrated field)."""
    lenses = tumvi_lenses(camera)
    u, v = np.meshgrid(np.arange(0.0, 512, 8), np.arange(0.0, 512, 8))
    uv = np.stack([u.ravel(), v.ravel()], 1)
    for a, b in itertools.permutations(lenses, 2):
        rays, ok = lenses[a].unproject(uv)
        ok &= np.degrees(np.arccos(np.clip(rays[:, 2], -1.0, 1.0))) <= 100.0
        q, ok2 = lenses[b].project(rays[ok])
        assert ok2.all() and ok.sum() > 3900
        e = np.linalg.norm(q - uv[ok], axis=1)
        print(
            f"TUM-VI cam{camera} {a} -> {b}: {ok.sum()} pixels, max {e.max():.3f} px, "
            f"RMS {np.sqrt(np.mean(e**2)):.3f} px"
        )
        assert e.max() < 1.0

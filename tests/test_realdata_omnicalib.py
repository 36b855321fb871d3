"""Chessboard calibration of real omni-images from their pixels (../shared/realdata).

KaidanOmni (OCamCalib's catadioptric sample set): the board is detected in the six images
OCamCalib's published calibration used, the detected corners are compared with OCamCalib's
stored ones, and the Scaramuzza model is calibrated from them; its RMS is compared with the
published RMS of OCamCalib (0.325 px) and Urban's bundle adjustment (0.313 px) on the same
views. The Mei paracatadioptric set is calibrated with Mei's model. The other sets and
models: scripts/omni_realdata.py (docs/fisheye-calibration.md has the table).

Skipped, with the reason, when ../shared/realdata is absent.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from omnidev.fisheye.board_detect import detect_chessboard
from omnidev.fisheye.calibrate import calibrate_views, detect_corners
from omnidev.fisheye.pattern import Pattern
from tests.conftest import REALDATA

pytestmark = pytest.mark.skipif(
    not REALDATA.is_dir(), reason=f"{REALDATA} absent (shared/realdata not mounted)"
)

KAIDAN = REALDATA / "ocamcalib_urban_samples" / "KaidanOmni"


def kaidan() -> tuple[dict, list[str], dict[str, np.ndarray]]:
    data = json.loads((KAIDAN / "calibration_and_corners.json").read_text())
    views = data["methods"]["ocamcalib_subpixel"]["views"]
    stored = {
        v["image"]: np.stack([np.array(v["corner_col"]) - 1, np.array(v["corner_row"]) - 1], 1)
        for v in views
    }
    return data, [v["image"] for v in views], stored


def nearest(stored: np.ndarray, found: np.ndarray) -> np.ndarray:
    return np.linalg.norm(stored[:, None] - found[None], axis=-1).min(axis=1)


def test_kaidan_omni_calibrated_from_its_pixels() -> None:
    data, names, stored = kaidan()
    pattern = Pattern("chessboard", 7, 11, 30.0)  # 6 x 10 squares between the outer corners
    dets = [
        detect_corners(
            cv2.imread(str(KAIDAN / "images" / n), cv2.IMREAD_GRAYSCALE), pattern, name=n
        )
        for n in names
    ]
    assert all(d is not None for d in dets)
    d = np.concatenate([nearest(stored[x.name], x.image_points) for x in dets if x is not None])
    rms_vs_stored = float(np.sqrt(np.mean(d[d < 3] ** 2)))
    res = calibrate_views(dets, (640, 480), "scaramuzza", holdout=3)
    pub = data["methods"]
    ocam = pub["ocamcalib_subpixel"]["model"]["rms_point_px_recomputed"]
    urban = pub["urban_ba"]["model"]["rms_point_px_recomputed"]
    print(
        f"\nKaidanOmni, {len(dets)} views, {sum(len(x.image_points) for x in dets if x)} corners "
        f"detected: vs OCamCalib's stored corners RMS {rms_vs_stored:.3f} px (max {d.max():.2f});"
        f" scaramuzza train {res.train_rms_px:.3f} px, held-out {res.heldout_rms_px:.3f} px "
        f"(3-fold); published OCamCalib {ocam:.3f} px, Urban BA {urban:.3f} px"
    )
    assert np.all(d < 3.0) and rms_vs_stored < 0.15
    assert all(v.status == "used" for v in res.views)
    assert res.train_rms_px < ocam  # measured 0.306 against 0.325 and 0.313
    assert res.heldout_rms_px < 0.45
    lens = res.camera.lens
    ba = pub["urban_ba"]["model"]
    centre = (ba["yc_col_1based"] - 1, ba["xc_row_1based"] - 1)
    assert abs(lens.yc - centre[0]) < 3 and abs(lens.xc - centre[1]) < 3  # type: ignore[union-attr]


def test_grown_grid_alone_finds_kaidan_boards() -> None:
    """The saddle-point grid grower by itself on the same real mirror images."""
    _, names, stored = kaidan()
    got = [
        detect_chessboard(
            cv2.imread(str(KAIDAN / "images" / n), cv2.IMREAD_GRAYSCALE), (7, 11), methods=("grow",)
        )
        for n in names
    ]
    errs = [nearest(stored[n], g.uv) for n, g in zip(names, got, strict=True) if g is not None]
    med = [float(np.median(e)) for e in errs]
    print(f"\ngrown grids on KaidanOmni: {len(errs)} of {len(names)} boards, median distance to "
          f"the stored corners {np.median(med):.3f} px")  # fmt: skip
    assert len(errs) >= 4 and max(med) < 0.15

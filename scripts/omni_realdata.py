"""Calibrate the real omni-image sets of ../shared/realdata from their pixels.

For each set with chessboard images (OCamCalib's KaidanOmni, MiniOmni, Ladybug, Urban's
Fisheye1, Mei's paracatadioptric set): the board is detected in every image
(:func:`omnidev.fisheye.calibrate.detect_corners`, all detectors), the camera is calibrated
with each model (4-fold held-out RMS), and the figures are printed beside the published ones
(OCamCalib's standard method with subpixel corners and Urban's bundle adjustment, from
calibration_and_corners.json). The detected corners are compared with the stored ones
(nearest stored corner, same image).

Two calibrations per set and model: on every image where the board was found ("all found")
and on the images the published calibration used ("published views"), the like-for-like
comparison.

    .venv/bin/python scripts/omni_realdata.py [--sets KaidanOmni,...] [--models scaramuzza,mei]
        [--json out.json]

Run from the repository root; ../shared/realdata must exist.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev.errors import CalibrationError
from omnidev.fisheye.calibrate import Detection, calibrate_views, detect_corners
from omnidev.fisheye.pattern import Pattern

REALDATA = Path(__file__).resolve().parent.parent.parent / "shared" / "realdata"
OCAM = REALDATA / "ocamcalib_urban_samples"


def ocam_set(name: str) -> dict[str, Any]:
    """Images, pattern, published RMS and stored corners of an OCamCalib/Urban set."""
    data = json.loads((OCAM / name / "calibration_and_corners.json").read_text())
    b = data["board"]
    pattern = Pattern("chessboard", b["n_sq_x"] + 1, b["n_sq_y"] + 1, float(b["square_mm"]))
    stored = {}
    for v in data["methods"]["ocamcalib_subpixel"]["views"]:
        uv = np.stack([np.array(v["corner_col"]) - 1, np.array(v["corner_row"]) - 1], 1)
        stored[v["image"]] = uv
    pub = {
        "OCamCalib (subpixel)": data["methods"]["ocamcalib_subpixel"]["model"][
            "rms_point_px_recomputed"
        ],
        "Urban BA": data["methods"]["urban_ba"]["model"]["rms_point_px_recomputed"],
    }
    images = sorted(
        (OCAM / name / "images").glob("*.jpg"),
        key=lambda p: int("".join(ch for ch in p.stem.split("_")[-1] if ch.isdigit()) or 0),
    )
    return {"images": images, "pattern": pattern, "stored": stored, "published": pub}


def mei_set() -> dict[str, Any]:
    root = REALDATA / "mei_paracatadioptric"
    data = json.loads((root / "calibration_and_corners.json").read_text())
    stored = {v["image"]: np.array(v["corners_uv"], np.float64) for v in data["views"]}
    checks = [v.get("reproj_rms_px") for v in data["views"]]
    pub = {"cv2.omnidir (third party) per-view check, median": float(np.median(checks))}
    return {
        "images": sorted((root / "images").glob("*.pgm")),
        "pattern": Pattern("chessboard", 6, 8, 42.0),
        "stored": stored,
        "published": pub,
    }


def compare(det: Detection, stored: np.ndarray) -> dict[str, float]:
    d = np.linalg.norm(stored[:, None] - det.image_points[None], axis=-1).min(axis=1)
    m = d < 3.0
    return {
        "matched": int(m.sum()),
        "stored": len(stored),
        "median_px": float(np.median(d[m])) if m.any() else math.nan,
        "rms_px": float(np.sqrt(np.mean(d[m] ** 2))) if m.any() else math.nan,
        "max_px": float(d.max()),
    }


def run_set(name: str, spec: dict[str, Any], models: list[str]) -> dict[str, Any]:
    t0 = time.perf_counter()
    dets: list[Detection | None] = []
    size = None
    for path in spec["images"]:
        grey = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        size = (grey.shape[1], grey.shape[0])
        dets.append(detect_corners(grey, spec["pattern"], name=path.name))
    t_det = time.perf_counter() - t0
    assert size is not None
    found = [d for d in dets if d is not None]
    out: dict[str, Any] = {
        "set": name,
        "images": len(dets),
        "boards": len(found),
        "corners": int(sum(len(d.image_points) for d in found)),
        "methods": {d.name: d.method for d in found},
        "not_found": [p.name for p, d in zip(spec["images"], dets, strict=True) if d is None],
        "detect_s": t_det,
        "published": spec["published"],
    }
    cmp = [compare(d, spec["stored"][d.name]) for d in found if d.name in spec["stored"]]
    if cmp:
        allm = sum(c["matched"] for c in cmp)
        out["vs_stored"] = {
            "views": len(cmp),
            "matched": allm,
            "stored": sum(c["stored"] for c in cmp),
            "rms_px": float(
                np.sqrt(sum(c["rms_px"] ** 2 * c["matched"] for c in cmp) / max(allm, 1))
            ),
            "median_of_view_medians_px": float(np.median([c["median_px"] for c in cmp])),
            "worst_view_max_px": max(c["max_px"] for c in cmp),
        }
    out["calibrations"] = {}
    for model in models:
        for which in ("all found", "published views"):
            sel = (
                dets
                if which == "all found"
                else [d if d is not None and d.name in spec["stored"] else None for d in dets]
            )
            if which == "published views" and name == "mei":
                continue
            t1 = time.perf_counter()
            try:
                res = calibrate_views(sel, size, model, names=[p.name for p in spec["images"]])
            except CalibrationError as exc:
                out["calibrations"][f"{model}, {which}"] = {"error": str(exc)}
                continue
            used = [v for v in res.views if v.status == "used"]
            out["calibrations"][f"{model}, {which}"] = {
                "views_used": len(used),
                "corners_used": sum(v.n_points for v in used),
                "dropped": {v.name: v.note for v in res.views if v.status == "dropped"},
                "train_rms_px": res.train_rms_px,
                "heldout_rms_px": res.heldout_rms_px,
                "folds": res.folds,
                "params": res.params,
                "warnings": list(res.warnings),
                "seconds": time.perf_counter() - t1,
            }
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", default="KaidanOmni,MiniOmni,Fisheye1,Ladybug,mei")
    ap.add_argument("--models", default="scaramuzza,mei,kb4")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    if not REALDATA.is_dir():
        print(f"{REALDATA} absent", file=sys.stderr)
        return 2
    results = []
    for name in args.sets.split(","):
        spec = mei_set() if name == "mei" else ocam_set(name)
        models = args.models.split(",")
        r = run_set(name, spec, models)
        results.append(r)
        print(json.dumps(r, indent=1, default=float), flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

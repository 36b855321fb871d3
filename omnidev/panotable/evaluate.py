"""The dissertation's and the generalized pano-mapping tables measured on the same rendered data.

For a rendered case (:mod:`omnidev.sim.pano_cases`) and a landmark budget,
both tables are fitted to the same noisy landmark subset; every view is
unwarped three ways (exact maps = the ceiling, the dissertation's table, the
generalized table) and compared with the rendered truth by PSNR over the
pixels the camera sees whose exact source lies at least ``margin`` px inside
the omni-image's seen region (at the rim every unwarper blends in the dark
surround). A table that marks such a pixel invalid loses it (black), so a
table cannot win by refusing pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.camera import Maps, build_maps, unwarp
from omnidev.errors import CalibrationError
from omnidev.metrics import psnr
from omnidev.panotable.camfile import PanoTableCamera
from omnidev.panotable.table import calibrate, calibrate_general
from omnidev.sim.pano_cases import PanoCase

BoolArray = NDArray[np.bool_]


def interior_mask(case: PanoCase, maps: Maps, margin: int = 3) -> BoolArray:
    """View pixels whose exact source pixel lies ``margin`` px inside the seen omni region."""
    k = 2 * margin + 1
    inner = cv2.erode(case.omni_valid.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    h, w = inner.shape
    iu = np.clip(np.round(maps.map_x).astype(np.intp), 0, w - 1)
    iv = np.clip(np.round(maps.map_y).astype(np.intp), 0, h - 1)
    return np.asarray(maps.valid & inner[iv, iu], np.bool_)


@dataclass(frozen=True)
class CaseResult:
    """PSNR (dB) per view of the ceiling and of each table, and the fits' figures."""

    kind: str
    seed: int
    n_landmarks: int
    noise_px: float
    ceiling: dict[str, float]
    tables: dict[str, dict[str, float]]  # method -> view -> PSNR (nan when refused)
    coverage: dict[str, dict[str, float]]  # method -> view -> fraction of the mask it maps
    fit: dict[str, Any]  # per method: reprojection / held-out RMS, terms kept, refusal

    def gap(self, method: str) -> dict[str, float]:
        """Ceiling minus the method's PSNR per view, dB."""
        return {v: self.ceiling[v] - self.tables[method][v] for v in self.ceiling}


def evaluate_case(
    case: PanoCase,
    *,
    n_landmarks: int,
    noise_px: float = 0.3,
    seed: int = 0,
    start_offset_px: float = 3.0,
    max_heldout_px: float | None = 2.0,
) -> CaseResult:
    """Fit both tables to ``n_landmarks`` landmarks of ``case`` with Gaussian pixel noise.

    The dissertation's table gets the true image center (its best case); the
    generalized table starts ``start_offset_px`` away from it in a random
    direction (a detected center's error) and fits it.
    """
    rng = np.random.default_rng([seed, n_landmarks, 7])
    if n_landmarks > len(case.uv):
        raise ValueError(f"case has {len(case.uv)} landmarks, {n_landmarks} asked")
    pick = rng.choice(len(case.uv), n_landmarks, replace=False)
    uv = case.uv[pick] + rng.normal(0.0, noise_px, (n_landmarks, 2))
    xyz = case.dirs[pick] * case.distance[pick, None]
    a = rng.uniform(0, 2 * math.pi)
    start = (
        case.image_center[0] + start_offset_px * math.cos(a),
        case.image_center[1] + start_offset_px * math.sin(a),
    )
    fit: dict[str, Any] = {}
    cameras: dict[str, PanoTableCamera | None] = {}
    try:
        d = calibrate(uv, xyz, np.zeros(3), case.image_center, case.image_size)
        cameras["dissertation"] = PanoTableCamera(d.table)
        fit["dissertation"] = {
            "reprojection_rms_px": float(np.sqrt(np.mean(d.reprojection_px**2))),
            "radial_rms_px": d.fit.rms_px,
        }
    except CalibrationError as exc:
        cameras["dissertation"] = None
        fit["dissertation"] = {"refused": str(exc)}
    try:
        g = calibrate_general(
            uv, xyz, np.zeros(3), start, case.image_size, max_heldout_px=max_heldout_px
        )
        cameras["general"] = PanoTableCamera(g.table)
        m = g.fit.mapping
        fit["general"] = {
            "reprojection_rms_px": g.fit.rms_px,
            "heldout_rms_px": g.fit.heldout_rms_px,
            "terms": g.fit.terms.describe(),
            "center_error_px": math.hypot(
                m.image_center[0] - case.image_center[0], m.image_center[1] - case.image_center[1]
            ),
            "aspect": m.aspect,
            "tilt_deg": m.tilt_deg,
        }
    except CalibrationError as exc:
        cameras["general"] = None
        fit["general"] = {"refused": str(exc)}
    ceiling: dict[str, float] = {}
    tables: dict[str, dict[str, float]] = {k: {} for k in cameras}
    coverage: dict[str, dict[str, float]] = {k: {} for k in cameras}
    for name, tv in case.views.items():
        mask = tv.seen & interior_mask(case, tv.exact)
        ceiling[name] = psnr(unwarp(case.omni, tv.exact), tv.truth, mask)
        for method, cam in cameras.items():
            if cam is None:
                tables[method][name] = math.nan
                coverage[method][name] = 0.0
                continue
            maps = build_maps(cam, tv.view)
            tables[method][name] = psnr(unwarp(case.omni, maps), tv.truth, mask)
            coverage[method][name] = float(np.mean(maps.valid[mask]))
    return CaseResult(case.kind, case.seed, n_landmarks, noise_px, ceiling, tables, coverage, fit)

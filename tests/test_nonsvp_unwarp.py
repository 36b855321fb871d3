"""Unwarping the committed non-SVP fixtures onto the views of sec. 2.5.1, against the
renderer's exact truth views (omnidev.sim.nonsvp ray-traces the mirror by vector
reflection, independently of omnidev.nonsvp's equations)."""

from __future__ import annotations

import functools
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.nonsvp import interp
from omnidev.nonsvp.unwarp import (
    backprojected_edges,
    backprojected_view,
    dense_maps,
    svp_maps,
)
from omnidev.sim import nonsvp as sim_nonsvp

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "nonsvp"
CASES = [
    ("dissertation-textured-640x480", "dissertation", (640, 480)),
    ("large-textured-1280x960", "large", (1280, 960)),
]


def psnr(a: np.ndarray, b: np.ndarray, m: np.ndarray) -> float:
    d = (a.astype(np.float64) - b.astype(np.float64))[m]
    return float(10 * np.log10(255.0**2 / np.mean(d * d)))


def load(name: str, view: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    fx = FIX / name
    omni = cv2.imread(str(fx / "omni.png"), cv2.IMREAD_COLOR)
    truth = cv2.imread(str(fx / f"{view}.png"), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(fx / f"{view}_mask.png"), cv2.IMREAD_GRAYSCALE) > 0
    return omni, truth, mask


@pytest.mark.parametrize("name,pose,size", CASES, ids=[c[0] for c in CASES])
def test_dense_maps_reach_the_ceiling_and_beat_the_svp_assumption(name, pose, size):
    cam = sim_nonsvp.preset_camera(pose, size)
    for view_name in ("top", "side_0", "side_1", "side_2", "side_3"):
        omni, truth, mask = load(name, view_name)
        view = sim_nonsvp.dissertation_planes(truth.shape[1], truth.shape[0])[view_name]
        mx, my, ok = dense_maps(cam, view)
        cx, cy, cok = sim_nonsvp.view_plane_map(cam, view)  # the renderer's exact mapping
        m = mask & ok & cok
        assert m.mean() > 0.5
        gap = float(np.max(np.hypot(mx - cx, my - cy)[m]))
        dense = cv2.remap(omni, mx, my, cv2.INTER_LINEAR)
        ceiling = cv2.remap(omni, cx, cy, cv2.INTER_LINEAR)
        rim = cv2.imread(str(FIX / name / "mask.png"), cv2.IMREAD_GRAYSCALE) > 0
        vs, us = np.nonzero(rim)  # the SVP baseline centred on the imaged mirror
        sx, sy, sok = svp_maps(cam, view, (float(us.mean()), float(vs.mean())))
        svp = cv2.remap(omni, sx, sy, cv2.INTER_LINEAR)
        ms = m & sok
        p_dense, p_ceil, p_svp = (
            psnr(dense, truth, m),
            psnr(ceiling, truth, m),
            psnr(svp, truth, ms),
        )
        print(
            f"\n{name} {view_name}: dense maps {p_dense:.2f} dB, ceiling {p_ceil:.2f} dB, "
            f"SVP assumption {p_svp:.2f} dB; dense vs exact map max {gap:.2e} px"
        )
        assert gap < 1e-3  # the model's forward projection = the ray tracer's mapping
        assert p_dense >= p_ceil - 1.0
        assert p_dense >= p_svp + 3.0


def test_backprojected_view_and_chapter_3_interpolation():
    """The dissertation's chain: back-projected pixels land where the truth has them; the
    holes are filled by chapter 3's methods (figures printed, the ordering reported)."""
    name, pose, size = CASES[0]
    cam = sim_nonsvp.preset_camera(pose, size)
    omni, truth, mask = load(name, "side_0")
    view = sim_nonsvp.dissertation_planes(truth.shape[1], truth.shape[0])["side_0"]
    raw, filled = backprojected_view(cam, omni, view)
    m = mask & filled
    assert filled.mean() > 0.2  # measured 26 % (10 % with the earlier 29.4-degree-rim mirror)
    p_filled = psnr(raw, truth, m)
    edges = backprojected_edges(cam, omni, view)
    holes = mask & ~filled
    results = {
        "4NN": interp.interpolate_4nn(raw, filled),
        "two-layered": interp.interpolate_two_layered(raw, filled),
        "edge-preserving": interp.interpolate_edge_preserving(raw, filled, edges),
        "Telea": cv2.inpaint(raw, (~filled).astype(np.uint8), 3, cv2.INPAINT_TELEA),
    }
    line = ", ".join(f"{k} {psnr(v, truth, holes):.2f}" for k, v in results.items())
    print(f"\n{name} side_0: {100 * filled.mean():.0f} % filled, filled pixels {p_filled:.2f} dB;"
          f" unfilled pixels: {line} dB")  # fmt: skip
    for v in results.values():
        assert np.array_equal(v[filled], raw[filled])  # filled pixels untouched
    assert p_filled >= 26.0  # measured 28.33 dB


@functools.cache
def quality_rows(name: str, pose: str, size: tuple[int, int]) -> dict[str, dict[str, float]]:
    """PSNR / SSIM of every method on every view of one fixture (means over the views)."""
    from omnidev.metrics import psnr as m_psnr
    from omnidev.metrics import ssim as m_ssim

    cam = sim_nonsvp.preset_camera(pose, size)
    rim = cv2.imread(str(FIX / name / "mask.png"), cv2.IMREAD_GRAYSCALE) > 0
    vs, us = np.nonzero(rim)
    sums: dict[str, list[tuple[float, float]]] = {}
    edge_sums: dict[str, list[float]] = {}
    fills: dict[str, float] = {}
    for view_name in ("top", "side_0", "side_1", "side_2", "side_3"):
        omni, truth, mask = load(name, view_name)
        view = sim_nonsvp.dissertation_planes(truth.shape[1], truth.shape[0])[view_name]
        mx, my, ok = dense_maps(cam, view)
        sx, sy, sok = svp_maps(cam, view, (float(us.mean()), float(vs.mean())))
        raw, filled = backprojected_view(cam, omni, view)
        fills[view_name] = float(filled.mean())
        edges = backprojected_edges(cam, omni, view)
        out = {
            "SVP assumption (eq. 2.1)": cv2.remap(omni, sx, sy, cv2.INTER_LINEAR),
            "back-projection + 4NN": interp.interpolate_4nn(raw, filled),
            "+ two-layered": interp.interpolate_two_layered(raw, filled),
            "+ edge-preserving": interp.interpolate_edge_preserving(raw, filled, edges),
            "+ cv2.inpaint Telea": cv2.inpaint(
                raw, (~filled).astype(np.uint8), 3, cv2.INPAINT_TELEA
            ),
            "dense maps": cv2.remap(omni, mx, my, cv2.INTER_LINEAR),
        }
        m = mask & ok & sok
        # unfilled pixels on the truth's strong edges (edge value >= e_t, as in sec. 3.2.2)
        grey = cv2.cvtColor(truth, cv2.COLOR_BGR2GRAY)
        on_edge = m & ~filled & (interp.sobel_edge_value(grey) >= 0.35)
        for k, img in out.items():
            sums.setdefault(k, []).append((m_psnr(img, truth, m), m_ssim(img, truth, m)))
            if k.startswith(("back-projection", "+")):
                edge_sums.setdefault(k, []).append(psnr(img, truth, on_edge))
    rows = {
        k: {"psnr": float(np.mean([p for p, _ in v])), "ssim": float(np.mean([s for _, s in v]))}
        for k, v in sums.items()
    }
    for k, e in edge_sums.items():
        rows[k]["edge_psnr"] = float(np.mean(e))
    rows["back-projection fill"] = fills
    return rows


@pytest.mark.parametrize("name,pose,size", CASES, ids=[c[0] for c in CASES])
def test_quality_table(name, pose, size):
    """The issue's table (PSNR dB / SSIM against the rendered truth, mean over the top and
    four side views). Asserted: dense maps best; every back-projection variant beats the
    SVP assumption; edge-preserving vs 4NN is reported (over all pixels the dissertation's
    claim does not hold here: see docs/nonsvp-interpolation.md)."""
    rows = quality_rows(name, pose, size)
    rows = dict(rows)
    fills = rows.pop("back-projection fill")
    print(
        f"\n{name}: method, PSNR dB, SSIM (mean over top + 4 side views)"
        "[, PSNR dB over the unfilled pixels on edges]"
    )
    for k, v in rows.items():
        edge = f"  {v['edge_psnr']:6.2f}" if "edge_psnr" in v else ""
        print(f"  {k:<28} {v['psnr']:6.2f}  {v['ssim']:.3f}{edge}")
    print("  back-projection fills " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in fills.items()))
    dense = rows["dense maps"]
    assert all(dense["psnr"] >= v["psnr"] for v in rows.values())
    for k in ("back-projection + 4NN", "+ two-layered", "+ edge-preserving"):
        assert rows[k]["psnr"] > rows["SVP assumption (eq. 2.1)"]["psnr"] + 5.0  # measured >= 5.58
    # the mirror puts its rim 6 degrees above the horizon: measured 22.6-27.4 % per view
    assert all(0.2 < v < 0.3 for v in fills.values()), fills


@pytest.mark.xfail(
    strict=True,
    reason="measured on the fixtures' views: back-projection + 4NN leads + edge-preserving by "
    "1.22 dB / 0.043 SSIM (dissertation pose, 640x480) and 1.29 dB / 0.025 (large, 1280x960) "
    "in the mean over the five views, and on the unfilled pixels on edges by 0.73 / 0.44 dB; "
    "see docs/results.md and docs/nonsvp-interpolation.md",
)
@pytest.mark.parametrize("name,pose,size", CASES, ids=[c[0] for c in CASES])
def test_quality_edge_preserving_beats_4nn(name, pose, size):
    """The issue's acceptance (edge-preserving beats 4NN), on the view quality table."""
    rows = quality_rows(name, pose, size)
    assert rows["+ edge-preserving"]["psnr"] > rows["back-projection + 4NN"]["psnr"]

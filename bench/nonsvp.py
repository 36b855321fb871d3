"""Non-SVP hyperbolic-mirror pipeline speed at 1280x960, single-threaded (issue 6).

Input: the committed omni_room frame (fixtures/omni_room/omni_0000.png) resized
to 1280x960 BGR, with the back-projection-like hole pattern of
omnidev.nonsvp.interp.synthetic_unfilled_mask (~35 % unfilled, few on the left,
dense on the right); the edge-value image is sobel_edge_value of its grey image read
at the filled pixels. Figures (medians, ms):
- edge_preserving_ms: interpolate_edge_preserving (sec. 3.2.2; includes the
  two-layered values of the non-edge holes). Target <= 150 ms.
- two_layered_ms, nn4_ms: interpolate_two_layered, interpolate_4nn.
- sobel_ms: the edge-value image of a 1280x960 grey omni-image (its unwarping is
  part of back-projection, not timed here).
- inpaint_telea_ms: cv2.inpaint(raw, holes, 3, INPAINT_TELEA), the peer.
- edge_preserving_vs_telea: edge_preserving_ms / inpaint_telea_ms.
- dissertation_ms_320x240: the dissertation's figures (P4 3 GHz; Fig. 3.6).
- backprojection_ms: omnidev.nonsvp.unwarp.backprojected_view of a 1280x960
  omni-image (the larger-misalignment camera) onto a 1280x960 side view: every
  pixel back-projected by the dissertation's equations, rays cut with the plane.
- dense_map_ms: omnidev.nonsvp.unwarp.dense_maps for a 1280x960 view (numerical
  forward projection of every view pixel); dense_remap_ms: applying them.
- *_vs_telea: each of these over inpaint_telea_ms, measured in the same run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.nonsvp.interp import (
    interpolate_4nn,
    interpolate_edge_preserving,
    interpolate_two_layered,
    sobel_edge_value,
    synthetic_unfilled_mask,
)

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "omni_room" / "omni_0000.png"
SIZE = (1280, 960)


def _median_ms(fn: Callable[[], object], reps: int) -> float:
    fn()  # warm-up
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter_ns()
        fn()
        ts.append((time.perf_counter_ns() - t0) / 1e6)
    return float(np.median(ts))


def raw_unwarped_input() -> tuple[NDArray[np.uint8], NDArray[np.bool_], NDArray[np.float32]]:
    """(raw 960x1280x3 uint8 with holes zeroed, filled mask, unwarped edge-value image)."""
    img = cv2.imread(str(FIXTURE))
    if img is None:
        raise FileNotFoundError(f"benchmark fixture {FIXTURE} missing")
    img = np.asarray(cv2.resize(img, SIZE, interpolation=cv2.INTER_CUBIC), np.uint8)
    filled = synthetic_unfilled_mask(img.shape[:2])
    raw = (img * filled[:, :, None]).astype(np.uint8)
    gray = np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), np.uint8)
    edges = (sobel_edge_value(gray) * filled).astype(np.float32)
    return raw, filled, edges


def bench_interpolation(reps: int) -> dict[str, Any]:
    """Chapter 3 interpolation of a 1280x960 raw unwarped image, and the Telea peer."""
    raw, filled, edges = raw_unwarped_input()
    holes = (~filled).astype(np.uint8)
    gray = np.asarray(cv2.cvtColor(raw, cv2.COLOR_BGR2GRAY), np.uint8)
    edge_ms = _median_ms(lambda: interpolate_edge_preserving(raw, filled, edges), reps)
    two_ms = _median_ms(lambda: interpolate_two_layered(raw, filled), reps)
    nn4_ms = _median_ms(lambda: interpolate_4nn(raw, filled), max(1, reps // 2))
    sobel_ms = _median_ms(lambda: sobel_edge_value(gray), reps)
    telea_ms = _median_ms(lambda: cv2.inpaint(raw, holes, 3, cv2.INPAINT_TELEA), reps)
    return {
        "interp_input": f"{SIZE[0]}x{SIZE[1]} BGR, {float(holes.mean()) * 100:.1f} % unfilled",
        "edge_preserving_ms": round(edge_ms, 1),
        "two_layered_ms": round(two_ms, 1),
        "nn4_ms": round(nn4_ms, 1),
        "sobel_ms": round(sobel_ms, 2),
        "inpaint_telea_ms": round(telea_ms, 1),
        "edge_preserving_vs_telea": round(edge_ms / telea_ms, 3),
        "dissertation_ms_320x240": "4NN 90, edge-preserving 218, two-layered 94 (P4 3 GHz)",
    }


def bench_unwarp(reps: int) -> dict[str, Any]:
    """Back-projection and dense-map timings on the larger-misalignment camera."""
    import dataclasses

    from omnidev.nonsvp.unwarp import backprojected_view, dense_maps
    from omnidev.sim.nonsvp import dissertation_planes, preset_camera

    cam = preset_camera("large", SIZE)
    view = dataclasses.replace(dissertation_planes()["side_0"], width=SIZE[0], height=SIZE[1])
    omni = cv2.resize(cv2.imread(str(FIXTURE), cv2.IMREAD_COLOR), SIZE)
    maps: list[Any] = []
    back = _median_ms(lambda: backprojected_view(cam, omni, view), max(1, reps // 3))
    dense = _median_ms(lambda: maps.append(dense_maps(cam, view)), max(1, reps // 3))
    mx, my, _ = maps[-1]
    remap = _median_ms(lambda: cv2.remap(omni, mx, my, cv2.INTER_LINEAR), reps)
    return {
        "backprojection_ms": round(back, 1),
        "dense_map_ms": round(dense, 1),
        "dense_remap_ms": round(remap, 2),
    }


def run(quick: bool = False) -> dict[str, Any]:
    cv2.setNumThreads(1)
    reps = 3 if quick else 9
    result: dict[str, Any] = {"threads": 1}
    result.update(bench_interpolation(reps))
    result.update(bench_unwarp(reps))
    telea = result["inpaint_telea_ms"]
    for key in ("backprojection_ms", "dense_map_ms", "dense_remap_ms"):
        result[key.replace("_ms", "_vs_telea")] = round(result[key] / telea, 3)
    return result

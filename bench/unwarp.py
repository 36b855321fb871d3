"""Pano-table camera of a 1920x1920 omni-image to a 2048x512 panorama: load, maps, per frame.

Single-threaded OpenCV; medians over interleaved repetitions (machine noise hits
both sides of a ratio alike). Two tables of the same camera are timed: the
dissertation's (``diss_*``) and a generalized one with tilt, aspect and
harmonics (``gen_*``), both learned from exact landmarks of a rendered SVP mirror.

Figures:
- file_bytes: size of the table file (format 2: the table's definition).
- load_ms: ``omnidev.load_camera`` of the file (one parse of the table's definition).
- build_ms: ``omnidev.build_maps`` for the panorama (the table's mapping at the
  view's rays, :mod:`omnidev.panotable.maps`).
- load_plus_build_ms: what a user waits before the first frame.
- build_peak_bytes_per_px: peak memory allocated while building the maps
  (tracemalloc, numpy's allocations included), per output pixel.
- load_peak_mb: the same for load_camera.
- perspective_peak_bytes_per_px, top_peak_bytes_per_px: the build peak for a
  1920x1080 perspective view and a 1024x1024 top view (no 3-D points either).
- load_plus_build_vs_bare_fixed: load_plus_build_ms over bare_fixed_ms, the
  machine's load seen by both (at idle a bare remap here takes about 5 ms).
- v1_load_ms (full runs only): load_camera of the same table in format 1
  (the table stored as YAML text), for comparison; v1_file_bytes.
- per frame (the dissertation's table's maps), anchors measured in the same run:
  remapper_ms (``omnidev.Remapper``, fixed-point maps), unwarp_ms
  (``omnidev.unwarp``, float maps), bare_fixed_ms (bare ``cv2.remap`` with
  fixed-point maps), bare_float_ms (bare ``cv2.remap`` with float32 maps);
  ratio_remapper_vs_fixed, ratio_remapper_vs_float, ratio_unwarp_vs_fixed.
"""

from __future__ import annotations

import math
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

import omnidev
from omnidev.calibfile import write_storage
from omnidev.camera import Remapper, build_maps, unwarp
from omnidev.panotable.camfile import save_table
from omnidev.panotable.table import calibrate, calibrate_general
from omnidev.views import Panorama, Perspective, TopView

SIZE = 1920
PANO = (2048, 512)


def _landmarks() -> tuple[np.ndarray, np.ndarray]:
    """Exact landmarks of an SVP hyperbolic mirror (eq. 2.1), tilted 2 degrees, aspect 0.98."""
    a, b = 28.1, 23.4
    c = math.hypot(a, b)
    f = 0.48 * SIZE / (a * a * math.cos(0.2) / (2 * b * c - (b * b + c * c) * math.sin(0.2)))
    rng = np.random.default_rng(0)
    rho = np.radians(rng.uniform(-75, 11, 300))
    theta = rng.uniform(0, 2 * np.pi, 300)
    r = f * a * a * np.cos(rho) / (2 * b * c - (b * b + c * c) * np.sin(rho))
    uv = np.stack([SIZE / 2 + r * np.cos(theta), SIZE / 2 + r * np.sin(theta)], axis=1)
    xyz = np.stack([np.cos(theta), np.sin(theta), np.tan(rho)], axis=1) * 2.0
    return uv, xyz


def _median_ms(fn: Callable[[], object], reps: int) -> float:
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times) * 1e3)


def _peak_bytes(fn: Callable[[], object]) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    keep = fn()
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    del keep
    return int(peak)


def _write_v1(path: Path, calib: object) -> None:
    """The same table in format 1 (table entries stored), as omnidev wrote it before."""
    t = calib.table  # type: ignore[attr-defined]
    nodes: dict[str, object] = {
        "image_width": t.image_size[0],
        "image_height": t.image_size[1],
        "image_center": np.array(t.image_center, np.float64).reshape(1, 2),
        "radial_coeffs": np.asarray(t.coeffs, np.float64).reshape(1, -1),
        "rho_start_deg": math.degrees(t.rho_range[0]),
        "rho_end_deg": math.degrees(t.rho_range[1]),
        "M": t.M,
        "N": t.N,
        "azimuth_sign": t.azimuth_sign,
        "azimuth_offset_deg": math.degrees(t.azimuth_offset),
        "cutoff_radius": float(t.cutoff_radius),
        "table": np.ascontiguousarray(t.table, np.float32),
    }
    write_storage(path, "pano-table", 1, nodes)


def run(quick: bool = False) -> dict[str, object]:
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    out: dict[str, object] = {
        "omni_size_px": f"{SIZE}x{SIZE}",
        "view": f"panorama {PANO[0]}x{PANO[1]}",
        "threads": 1,
    }
    try:
        uv, xyz = _landmarks()
        diss = calibrate(uv, xyz, np.zeros(3), (SIZE / 2, SIZE / 2), (SIZE, SIZE))
        # the generalized table: the same camera seen with non-square pixels and a tilt
        g_uv = uv.copy()
        g_uv[:, 1] = SIZE / 2 + 0.98 * (uv[:, 1] - SIZE / 2)
        rot = cv2.Rodrigues(np.array([0.03, -0.015, 0.0]))[0]
        gen = calibrate_general(g_uv, xyz @ rot, np.zeros(3), (SIZE / 2, SIZE / 2), (SIZE, SIZE))
        view = Panorama(*PANO)
        reps = 3 if quick else 9
        with tempfile.TemporaryDirectory() as tmp:
            maps_d = None
            for tag, calib in (("diss", diss), ("gen", gen)):
                path = Path(tmp) / f"{tag}.yml.gz"
                save_table(path, calib)  # type: ignore[arg-type]
                out[f"{tag}_method"] = calib.table.method
                out[f"{tag}_table_MxN"] = f"{calib.table.M}x{calib.table.N}"
                out[f"{tag}_file_bytes"] = path.stat().st_size
                out[f"{tag}_load_ms"] = round(
                    _median_ms(lambda p=path: omnidev.load_camera(p), reps), 2
                )
                cam = omnidev.load_camera(path)
                build_map = lambda c=cam: build_maps(c, view)  # noqa: E731
                out[f"{tag}_build_ms"] = round(_median_ms(build_map, reps), 2)
                out[f"{tag}_load_plus_build_ms"] = round(
                    _median_ms(lambda p=path: build_maps(omnidev.load_camera(p), view), reps), 2
                )
                out[f"{tag}_build_peak_bytes_per_px"] = round(
                    _peak_bytes(build_map) / (PANO[0] * PANO[1]), 2
                )
                out[f"{tag}_load_peak_mb"] = round(
                    _peak_bytes(lambda p=path: omnidev.load_camera(p)) / 2**20, 1
                )
                for name, other in (
                    ("perspective", Perspective(1920, 1080, 90.0, 30.0, -30.0)),
                    ("top", TopView(1024, 1024, 4.0, 4.0, -1.0)),
                ):
                    peak = _peak_bytes(lambda c=cam, v=other: build_maps(c, v))
                    out[f"{tag}_{name}_peak_bytes_per_px"] = round(
                        peak / (other.width * other.height), 2
                    )
                if tag == "diss":
                    maps_d = build_maps(cam, view)
            if not quick:
                v1 = Path(tmp) / "v1.yml.gz"
                _write_v1(v1, diss)
                out["v1_file_bytes"] = v1.stat().st_size
                out["v1_load_ms"] = round(_median_ms(lambda: omnidev.load_camera(v1), 1), 1)
        assert maps_d is not None
        frame = np.random.default_rng(0).integers(0, 256, (SIZE, SIZE, 3), dtype=np.uint8)
        remapper = Remapper(maps_d)
        m1, m2 = maps_d.fixed_point()
        fx, fy = maps_d.map_x, maps_d.map_y

        def bare_fixed() -> object:
            return cv2.remap(frame, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

        def bare_float() -> object:
            return cv2.remap(frame, fx, fy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

        fns = {
            "remapper_ms": lambda: remapper(frame),
            "unwarp_ms": lambda: unwarp(frame, maps_d),
            "bare_fixed_ms": bare_fixed,
            "bare_float_ms": bare_float,
        }
        for fn in fns.values():
            fn()
        times: dict[str, list[float]] = {k: [] for k in fns}
        for _ in range(5 if quick else 40):  # interleaved
            for k, fn in fns.items():
                times[k].append(_median_ms(fn, 1))
        med = {k: float(np.median(v)) for k, v in times.items()}
        for k, v in med.items():
            out[k] = round(v, 4)
        out["ratio_remapper_vs_fixed"] = round(med["remapper_ms"] / med["bare_fixed_ms"], 4)
        out["ratio_remapper_vs_float"] = round(med["remapper_ms"] / med["bare_float_ms"], 4)
        out["ratio_unwarp_vs_fixed"] = round(med["unwarp_ms"] / med["bare_fixed_ms"], 4)
        for tag in ("diss", "gen"):
            total = float(out[f"{tag}_load_plus_build_ms"])  # type: ignore[arg-type]
            out[f"{tag}_load_plus_build_vs_bare_fixed"] = round(total / med["bare_fixed_ms"], 3)
        return out
    finally:
        cv2.setNumThreads(threads)

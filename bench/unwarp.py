"""Pano-table unwarp of a 1920x1920 omni frame into a 2048x512 panorama, single-threaded.

Figures (one run, medians over interleaved repetitions):
- build_ms: building the maps (table lookup for every output pixel, fixed-point conversion).
- unwarp_ms_per_frame: omnidev's per-frame unwarp (``omnidev.camera.Remapper``).
- bare_remap_ms_per_frame: bare ``cv2.remap`` with the same maps (the anchor).
- ratio_vs_remap: unwarp / bare (target <= 1.10).
"""

from __future__ import annotations

import math
import time

import cv2
import numpy as np

from omnidev.camera import Remapper, build_maps
from omnidev.panotable.camfile import PanoTableCamera
from omnidev.panotable.table import calibrate
from omnidev.views import Panorama

SIZE = 1920
PANO = (2048, 512)


def _camera() -> PanoTableCamera:
    """A pano-table learned from exact landmarks of an SVP hyperbolic mirror (eq. 2.1)."""
    a, b = 28.1, 23.4
    c = math.hypot(a, b)
    f = 0.48 * SIZE / (a * a * math.cos(0.2) / (2 * b * c - (b * b + c * c) * math.sin(0.2)))
    rho = np.radians(np.linspace(-75, 11, 24))
    theta = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    r = f * a * a * np.cos(rho) / (2 * b * c - (b * b + c * c) * np.sin(rho))
    uv = np.stack([SIZE / 2 + r * np.cos(theta), SIZE / 2 + r * np.sin(theta)], axis=1)
    xyz = np.stack([np.cos(theta), np.sin(theta), np.tan(rho)], axis=1) * 2.0
    calib = calibrate(uv, xyz, np.zeros(3), (SIZE / 2, SIZE / 2), (SIZE, SIZE))
    return PanoTableCamera(calib.table)


def _median_ms(fn, reps: int) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times) * 1e3)


def run(quick: bool = False) -> dict[str, object]:
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        camera = _camera()
        rng = np.random.default_rng(0)
        frame = rng.integers(0, 256, (SIZE, SIZE, 3), dtype=np.uint8)
        view = Panorama(*PANO)
        holder: dict[str, Remapper] = {}

        def build() -> None:
            holder["r"] = Remapper(build_maps(camera, view))

        build_ms = _median_ms(build, 2 if quick else 5)
        remapper = holder["r"]
        m1, m2 = remapper.maps.fixed_point()
        remapper(frame)
        reps = 5 if quick else 40
        ours, bare = [], []
        for _ in range(reps):  # interleaved so that machine noise hits both alike
            ours.append(_median_ms(lambda: remapper(frame), 1))
            bare.append(
                _median_ms(
                    lambda: cv2.remap(
                        frame,
                        m1,
                        m2,
                        cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT,
                        borderValue=0,
                    ),
                    1,
                )
            )
        u, b = float(np.median(ours)), float(np.median(bare))
        return {
            "omni_size_px": f"{SIZE}x{SIZE}",
            "view": f"panorama {PANO[0]}x{PANO[1]}",
            "threads": 1,
            "build_ms": round(build_ms, 3),
            "unwarp_ms_per_frame": round(u, 4),
            "bare_remap_ms_per_frame": round(b, 4),
            "ratio_vs_remap": round(u / b, 4),
        }
    finally:
        cv2.setNumThreads(threads)

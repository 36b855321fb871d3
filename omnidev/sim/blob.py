"""A bright spot moving over a dark, noisy picture: the pointer daemon's fixture.

The stand-in for a laser spot or a camera-mouse cursor until those trackers
exist: a white disc follows a Lissajous path over a dim textured background;
"clicks" are stretches where the disc is twice as large. Truth per frame: the
disc centre normalized to the image (x = u / (W - 1), y = v / (H - 1), the same
convention as :class:`~omnidev.frame.PointerSample`) and whether it is a click.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.atomic import atomic_dir, check_output_dir

RADIUS = 10  # px, disc radius at rest; a click doubles it


@dataclass(frozen=True)
class BlobTruth:
    """The disc in one frame: centre in px and normalized, and whether it is a click."""

    u: float
    v: float
    x: float
    y: float
    pressed: bool


def blob_path(index: int, frames: int, width: int, height: int) -> BlobTruth:
    """Where the disc is in frame ``index`` of ``frames`` (a closed Lissajous loop)."""
    t = 2 * math.pi * index / frames
    margin = 3 * RADIUS
    u = width / 2 + (width / 2 - margin) * math.sin(t)
    v = height / 2 + (height / 2 - margin) * math.sin(2 * t + 0.5)
    # two clicks per loop, each a tenth of it long
    pressed = (index % (frames // 2)) in range(frames // 8, frames // 8 + max(frames // 10, 2))
    return BlobTruth(u, v, u / (width - 1), v / (height - 1), pressed)


def render_blob_frame(
    truth: BlobTruth, width: int, height: int, rng: np.random.Generator, supersample: int = 4
) -> NDArray[np.uint8]:
    """One gray frame: a soft-edged white disc over dim noise (antialiased by supersampling)."""
    s = supersample
    big = np.zeros((height * s, width * s), np.uint8)
    radius = RADIUS * (2 if truth.pressed else 1)
    # pixel centers at integer coordinates: supersampled center of pixel u is u*s + (s-1)/2
    center = ((truth.u + 0.5) * s - 0.5, (truth.v + 0.5) * s - 0.5)
    shift = 4
    cv2.circle(
        big,
        (round(center[0] * (1 << shift)), round(center[1] * (1 << shift))),
        round(radius * s * (1 << shift)),
        255,
        -1,
        cv2.LINE_AA,
        shift,
    )
    disc = cv2.resize(big, (width, height), interpolation=cv2.INTER_AREA).astype(np.float32)
    yy, xx = np.mgrid[0:height, 0:width]
    background = 40 + 20 * np.sin(xx / 37.0) * np.cos(yy / 23.0)  # dim, uneven room light
    noise = rng.normal(0, 2, (height, width))
    out = np.maximum(background + noise, disc)
    result: NDArray[np.uint8] = np.clip(out, 0, 255).astype(np.uint8)
    return result


def render_blob_video(
    frames: int = 120, width: int = 640, height: int = 480, seed: int = 0
) -> tuple[list[NDArray[np.uint8]], list[BlobTruth]]:
    """Frames and truth of the whole loop; deterministic from ``seed``."""
    rng = np.random.default_rng(seed)
    truth = [blob_path(i, frames, width, height) for i in range(frames)]
    images = [render_blob_frame(t, width, height, rng) for t in truth]
    return images, truth


def make_blob_fixture(
    outdir: Path,
    *,
    frames: int = 120,
    width: int = 640,
    height: int = 480,
    fps: float = 60.0,
    seed: int = 0,
    force: bool = False,
) -> dict[str, Any]:
    """Write blob.avi (MJPG) and truth.json into ``outdir``; returns the truth."""
    outdir = Path(outdir)
    check_output_dir(outdir, force=force)  # before the rendering, not after
    images, truth = render_blob_video(frames, width, height, seed)
    with atomic_dir(outdir, force=force) as tmp:
        video = cv2.VideoWriter(
            str(tmp / "blob.avi"), cv2.VideoWriter.fourcc(*"MJPG"), fps, (width, height)
        )
        video.set(cv2.VIDEOWRITER_PROP_QUALITY, 85)
        for img in images:
            video.write(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
        video.release()
        doc = {
            "what": "a white disc on a dim noisy background; a click doubles its radius",
            "size": [width, height],
            "fps": fps,
            "frames": frames,
            "seed": seed,
            "radius_px": RADIUS,
            "convention": "x = u / (W - 1), y = v / (H - 1): pixel centres, origin top-left",
            "truth": [
                {"u": round(t.u, 4), "v": round(t.v, 4), "x": t.x, "y": t.y, "pressed": t.pressed}
                for t in truth
            ],
            "regenerate": f"omnidev sim blob {outdir} --frames {frames} --size {width}x{height} "
            f"--fps {fps:g} --seed {seed} --force",
        }
        (tmp / "truth.json").write_text(json.dumps(doc, indent=1) + "\n")
    return doc


def load_blob_truth(path: Path) -> list[BlobTruth]:
    """The per-frame truth of a blob fixture's truth.json."""
    doc = json.loads(Path(path).read_text())
    return [BlobTruth(t["u"], t["v"], t["x"], t["y"], t["pressed"]) for t in doc["truth"]]

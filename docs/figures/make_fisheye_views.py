"""Draw docs/figures/fisheye_views.png, the figure of docs/fisheye-views.md.

Run from the repository root (needs ../shared/realdata)::

    .venv/bin/python docs/figures/make_fisheye_views.py

The image and its OCamCalib calibration are matsuren/ocamcalib_undistort's
img0.jpg and calib_results_0.txt (MIT licence, Copyright (c) 2021 Ren Komatsu),
read from shared/realdata/ocamcalib_matsuren_fisheye1600. The camera uses the
image circle, 86 degrees from the axis (``max_angle_deg=86``; the polynomial itself
would go on into the lens barrel). Panels (grey: pixels the camera does not see):
(a) the fisheye frame; (b) the equirectangular view of the whole field
(lon -100..100); (c) and (d) perspective views at pan 0 and pan 75 degrees (the
second reaches 125 degrees from the axis, so a part is masked).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import cv2
import matplotlib.pyplot as plt
import numpy as np

from omnidev.camera import unwarp
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.formats import parse_ocamcalib, read_text
from omnidev.fisheye.maps import view_maps
from omnidev.views import Equirectangular, Perspective, View

REPO = Path(__file__).resolve().parents[2]
DATA = (
    Path(os.environ.get("OMNIDEV_SHARED", REPO.parent / "shared"))
    / "realdata"
    / "ocamcalib_matsuren_fisheye1600"
)
OUT = REPO / "docs" / "figures" / "fisheye_views.png"


def main() -> None:
    imported = parse_ocamcalib(read_text(DATA / "calib_results_0.txt"), "calib_results_0.txt")
    assert imported.image_size is not None
    camera = FisheyeCamera(
        imported.lens, imported.image_size, MOUNTS["forward"], max_angle_deg=86.0
    )
    read = cv2.imread(str(DATA / "img0.jpg"), cv2.IMREAD_GRAYSCALE)
    if read is None:
        raise SystemExit(f"{DATA / 'img0.jpg'} not found")
    image = np.asarray(read, np.uint8)
    views: dict[str, View] = {
        "(b) equirect:480x360,lon=-100:100": Equirectangular(480, 360, (-100.0, 100.0)),
        "(c) perspective:480x360,fov=100": Perspective(480, 360, 100.0),
        "(d) perspective:480x360,fov=100,pan=75": Perspective(480, 360, 100.0, pan_deg=75.0),
    }
    fig, axes = plt.subplots(2, 2, figsize=(8.0, 6.4))
    small = cv2.resize(image, (480, 480), interpolation=cv2.INTER_AREA)
    axes[0, 0].imshow(small, cmap="gray", vmin=0, vmax=255)
    fov = 2 * math.degrees(camera.max_angle)
    axes[0, 0].set_title(f"(a) fisheye 1600x1600, OCamCalib model, {fov:.0f} deg used", fontsize=9)
    for ax, (title, view) in zip(axes.flat[1:], views.items(), strict=True):
        maps = view_maps(camera, view)
        out = unwarp(image, maps, border_value=128)
        ax.imshow(out, cmap="gray", vmin=0, vmax=255)
        ax.set_title(f"{title}\n{100 * maps.valid.mean():.0f} % of the view seen", fontsize=9)
    for ax in axes.flat:
        ax.set_axis_off()
    fig.text(
        0.5,
        0.01,
        "image: matsuren/ocamcalib_undistort img0.jpg (MIT, (c) 2021 Ren Komatsu)",
        ha="center",
        fontsize=8,
    )
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(OUT, dpi=72)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()

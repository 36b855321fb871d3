"""The committed omni fixture: a short rendered video with its ground truth."""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import cv2
from tqdm import tqdm

from omnidev.atomic import atomic_dir, check_output_dir
from omnidev.errors import OutputError
from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.landmarks import make_landmarks, write_landmarks_csv
from omnidev.sim.mirrors import SvpHyperbolicCamera
from omnidev.sim.render import render_omni, render_view
from omnidev.sim.scene import RoomScene
from omnidev.views import Panorama, PlaneView, View

PANORAMA = Panorama(1024, 256)
PERSPECTIVE = PlaneView(320, 240, distance=1.8, plane_width=2.4, z_bottom=-1.2, z_top=0.6)


def make_omni_fixture(
    outdir: Path,
    *,
    size: int = 640,
    frames: int = 36,
    fps: float = 12.0,
    seed: int = 0,
    camera: str = "svp-hyperbolic",
    force: bool = False,
) -> dict[str, Any]:
    """Render the fixture folder; returns what truth.json holds.

    Files: omni.avi (MJPG), omni_0000.png (frame 0, lossless), landmarks.csv,
    truth_panorama.png and truth_perspective.png (true views of frame 0),
    truth.json (camera, scene and view parameters, and the command).
    """
    outdir = Path(outdir)
    check_output_dir(outdir, force=force)  # before the rendering, not after
    cam: SvpHyperbolicCamera | EquidistantFisheyeCamera
    if camera == "svp-hyperbolic":
        cam = SvpHyperbolicCamera.default(size)
    elif camera == "equidistant":
        cam = EquidistantFisheyeCamera.default(size)
    else:
        raise OutputError(f"unknown fixture camera {camera!r} (svp-hyperbolic, equidistant)")
    scene = RoomScene(seed)
    with atomic_dir(outdir, force=force) as tmp:
        video = cv2.VideoWriter(
            str(tmp / "omni.avi"), cv2.VideoWriter.fourcc(*"MJPG"), fps, (size, size)
        )
        video.set(cv2.VIDEOWRITER_PROP_QUALITY, 90)
        for i in tqdm(range(frames), desc="rendering", unit="frame", file=sys.stderr):
            img = render_omni(cam, scene, t=i / fps, noise_sigma=1.0, seed=seed + i)
            if i == 0:
                cv2.imwrite(str(tmp / "omni_0000.png"), img)
            video.write(img)
        video.release()
        write_landmarks_csv(tmp / "landmarks.csv", make_landmarks(cam, scene, n=16, seed=seed))
        views: list[tuple[str, View]] = [("panorama", PANORAMA), ("perspective", PERSPECTIVE)]
        for name, view in views:
            img, _ = render_view(view, scene, camera=cam)
            cv2.imwrite(str(tmp / f"truth_{name}.png"), img)
        truth = {
            "camera": {"type": camera, **dataclasses.asdict(cam)},
            "image_center": list(cam.center),
            "elevation_band_deg": list(cam.default_elevation_deg()),
            "mirror_center_world": list(scene.mirror_center_world),
            "scene": {"type": "room", "seed": seed},
            "frames": frames,
            "fps": fps,
            "noise_sigma": 1.0,
            "frame_time": "t = index / fps seconds (the blue disc on the +x wall moves)",
            "views": {
                "panorama": {
                    "type": "Panorama",
                    **dataclasses.asdict(PANORAMA),
                    "elevation_deg": list(cam.default_elevation_deg()),
                },
                "perspective": {"type": "PlaneView", **dataclasses.asdict(PERSPECTIVE)},
            },
            "regenerate": f"omnidev sim omni {outdir} --size {size} --frames {frames} "
            f"--fps {fps:g} --seed {seed} --camera {camera} --force",
        }
        (tmp / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")
    return truth

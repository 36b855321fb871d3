"""Why DISSERTATION_CAMERA has the mirror it has (docs/nonsvp.md, "The mirror of the fixtures").

For the chosen mirror and three alternatives, at the dissertation's pose (640x480) and at the
larger misalignment (omnidev.sim.nonsvp.LARGE_POSE, same sensor at 640x480): where the rim and
the calibration ring's marks image in the frame, how far above the horizon the incident rays at
the rim go, and how much of each 320x240 view of sec. 2.5.1 back-projection fills. Run with -s
for the table.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.nonsvp.backproject import backproject
from omnidev.nonsvp.model import (
    DISSERTATION_CAMERA,
    Mirror,
    NonSvpCamera,
    ideal_to_pixel,
    mirror_for_aligned_lens,
    mirror_to_camera,
)
from omnidev.nonsvp.ring_pattern import RingLayout
from omnidev.nonsvp.unwarp import backprojected_view
from omnidev.sim.nonsvp import LARGE_POSE, dissertation_planes

MIRRORS = {
    "chosen: m 29, rim +6 deg": DISSERTATION_CAMERA.mirror,
    "earlier: a 20.187, b 30, m 29": Mirror.from_rim(20.18708377370789, 30.0, 29.0),
    "proposed: m 28, rim +5 deg": mirror_for_aligned_lens(88.67, 28.0, 5.0),
    "m 32, rim +6 deg": mirror_for_aligned_lens(88.67, 32.0, 6.0),
}
POSES = {"dissertation": DISSERTATION_CAMERA.pose, "large": LARGE_POSE}


def circle_px(cam: NonSvpCamera, radius: float, z: float) -> np.ndarray:
    """Pixels of the circle of ``radius`` mm at height z (O_m) around the mirror axis."""
    th = np.linspace(0.0, 2.0 * np.pi, 720, endpoint=False)
    pts = np.column_stack([radius * np.cos(th), radius * np.sin(th), np.full_like(th, z)])
    pc = mirror_to_camera(cam, pts)
    px, ok = ideal_to_pixel(cam.lens, cam.lens.f * pc[:, :2] / pc[:, 2:])
    assert ok.all()
    return px


def margin_px(cam: NonSvpCamera, px: np.ndarray) -> float:
    """Smallest distance (px) from the curve to the frame's edge; negative: cut off."""
    w, h = cam.lens.size
    return float(min(px[:, 0].min() + 0.5, w - 0.5 - px[:, 0].max(), px[:, 1].min() + 0.5,
                     h - 0.5 - px[:, 1].max()))  # fmt: skip


def rim_ray_elevations_deg(cam: NonSvpCamera) -> np.ndarray:
    """Per 10-degree azimuth bin of mirror points, the highest incident-ray elevation (deg)."""
    w, h = cam.lens.size
    vv, uu = np.mgrid[0:h, 0:w]
    M, d, ok = backproject(cam, np.column_stack([uu.ravel(), vv.ravel()]).astype(float))
    el = np.degrees(np.arctan2(d[ok, 2], np.hypot(d[ok, 0], d[ok, 1])))
    az = np.floor((np.degrees(np.arctan2(M[ok, 1], M[ok, 0])) + 180.0) / 10.0).astype(int)
    return np.array([el[az == k].max() for k in range(36)])


def fills(cam: NonSvpCamera) -> dict[str, float]:
    omni = np.zeros(cam.lens.size[::-1], np.uint8)
    return {
        name: float(backprojected_view(cam, omni, view)[1].mean())
        for name, view in dissertation_planes(320, 240).items()
    }


@pytest.fixture(scope="module")
def table() -> dict[str, dict[str, float]]:
    rows: dict[str, dict[str, float]] = {}
    for label, mirror in MIRRORS.items():
        row = {"elev_O_m": math.degrees(math.atan2(mirror.d, mirror.m))}
        for pose_name, pose in POSES.items():
            cam = NonSvpCamera(mirror, DISSERTATION_CAMERA.lens, pose)
            rim = circle_px(cam, mirror.m, mirror.d)
            marks = circle_px(cam, mirror.m + RingLayout(mirror.m).mark_length_mm, mirror.d)
            row[f"{pose_name}_rim_radius"] = float(np.hypot(*(rim - rim.mean(0)).T).mean())
            row[f"{pose_name}_rim_margin"] = margin_px(cam, rim)
            row[f"{pose_name}_marks_margin"] = margin_px(cam, marks)
            els = rim_ray_elevations_deg(cam)
            row[f"{pose_name}_rim_rays_min"], row[f"{pose_name}_rim_rays_max"] = (
                els.min(),
                els.max(),
            )
            if pose_name == "dissertation":
                f = fills(cam)
                row["fill_min"], row["fill_max"] = min(f.values()), max(f.values())
        rows[label] = row
    print(
        "\nmirror; rim elevation from O_m; per pose (640x480): rim radius px, rim / ring-mark "
        "margin to the frame px, incident rays at the rim deg; back-projection fill of the "
        "320x240 views at the dissertation pose"
    )
    for label, r in rows.items():
        poses = "; ".join(
            f"{p} {r[p + '_rim_radius']:.1f} px, margins {r[p + '_rim_margin']:.1f} / "
            f"{r[p + '_marks_margin']:.1f} px, "
            f"rays {r[p + '_rim_rays_min']:.1f}..{r[p + '_rim_rays_max']:.1f}"
            for p in POSES
        )
        print(
            f"  {label:<30} {r['elev_O_m']:5.1f} deg; {poses}; "
            f"fill {100 * r['fill_min']:.1f}-{100 * r['fill_max']:.1f} %"
        )
    return rows


def test_chosen_mirror_meets_the_constraints(table):
    r = table["chosen: m 29, rim +6 deg"]
    assert r["elev_O_m"] == pytest.approx(6.0, abs=1e-9)
    for p in POSES:
        assert r[f"{p}_rim_margin"] > 40.0  # measured 48.4 (dissertation), 49.5 (large)
        assert r[f"{p}_marks_margin"] > 10.0  # the ring's marks: measured 15.4 and 16.3
    assert r["dissertation_rim_rays_min"] > 3.0  # measured 4.1
    assert r["large_rim_rays_min"] > 1.0  # measured 1.4: the side views' top rows are seen
    assert r["fill_min"] > 0.2 and r["fill_max"] < 0.3  # measured 22.9-27.0 %


def test_the_alternatives_fall_short(table):
    chosen, earlier = table["chosen: m 29, rim +6 deg"], table["earlier: a 20.187, b 30, m 29"]
    # the earlier mirror spends most of the image above the horizon: fill 9.6-11.3 %
    assert earlier["elev_O_m"] > 29.0 and earlier["fill_max"] < 0.12
    assert chosen["fill_min"] > 2.0 * earlier["fill_max"]
    # the proposed m = 28 mm, +5 deg: less fill, and at the large pose the rim's rays come
    # within 0.4 deg of the horizon
    proposed = table["proposed: m 28, rim +5 deg"]
    assert proposed["fill_max"] < chosen["fill_max"] and proposed["large_rim_rays_min"] < 1.0
    # a larger rim fills more of the views but cuts the calibration ring's marks
    assert table["m 32, rim +6 deg"]["dissertation_marks_margin"] < 0.0

"""The non-SVP renderer against known truth: rim position, eq. 2.1, reflection law, fixtures."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.nonsvp.model import (
    DISSERTATION_CAMERA,
    ideal_to_pixel,
    image_point_in_mirror,
    mirror_to_camera,
    pixel_to_ideal,
)
from omnidev.sim.mirrors import SvpHyperbolicCamera
from omnidev.sim.nonsvp import (
    TracedCamera,
    camera_in_mirror,
    dissertation_planes,
    make_nonsvp_fixture,
    mirror_points_towards,
    pixel_rays,
    preset_camera,
    project_to_pixels,
    reflect,
    render_omni,
    render_view_plane,
    trace_mirror,
    view_plane_map,
)
from omnidev.sim.pseudo_target import GROUND_Z, PseudoTarget, TexturedRoom
from tests.conftest import REPO, psnr

FIXTURES = REPO / "fixtures" / "nonsvp"


def _pixels(tc: TracedCamera, step: float) -> tuple[np.ndarray, np.ndarray]:
    v, u = np.mgrid[0 : tc.size[1] : step, 0 : tc.size[0] : step]
    return u.ravel().astype(np.float64), v.ravel().astype(np.float64)


def test_frames_agree_with_the_model():
    """Lens centre, rotation and pixel rays read the pose exactly as omnidev.nonsvp.model."""
    for pose in ("dissertation", "large", "svp"):
        cam = preset_camera(pose)
        tc = TracedCamera.from_camera(cam)
        C, Q = camera_in_mirror(tc)
        np.testing.assert_allclose(C, cam.center_in_mirror(), atol=1e-12)
        np.testing.assert_allclose(Q, cam.rotation_camera_to_mirror(), atol=1e-15)
        u, v = _pixels(tc, 37.0)
        d = pixel_rays(tc, u, v)
        img = image_point_in_mirror(cam, pixel_to_ideal(cam.lens, np.stack([u, v], 1)))
        e = img - C
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        assert np.max(np.abs(d - e)) < 1e-14
    # the other reading of T (eq. 2.4, Tsai's) moves the dissertation's lens centre by ~3 mm
    tc4 = TracedCamera.from_camera(DISSERTATION_CAMERA, convention="eq2.4")
    shift = np.linalg.norm(camera_in_mirror(tc4)[0] - DISSERTATION_CAMERA.center_in_mirror())
    assert 2.5 < shift < 3.5


@pytest.mark.parametrize("pose", ["svp", "dissertation", "large"])
def test_rim_sits_where_the_geometry_says(pose: str):
    """Pixels 1.5 px inside the imaged rim see the mirror; 1.5 px outside do not."""
    size = (1280, 960) if pose == "large" else (640, 480)
    cam = preset_camera(pose, size)
    tc = TracedCamera.from_camera(cam)
    img, mask = render_omni(cam, PseudoTarget(), supersample=2)
    phi = np.linspace(0, 2 * math.pi, 720, endpoint=False)
    m = cam.mirror
    rim = np.stack([m.m * np.cos(phi), m.m * np.sin(phi), np.full_like(phi, m.d)], 1)
    pc = mirror_to_camera(cam, rim)  # model's frame conversion, then eq. 2.5 by hand
    uv, ok = ideal_to_pixel(cam.lens, cam.lens.f * pc[:, :2] / pc[:, 2:3])
    assert ok.all()
    centre = uv.mean(axis=0)
    radial = (uv - centre) / np.linalg.norm(uv - centre, axis=1, keepdims=True)
    for sign, want in ((-1.5, True), (1.5, False)):
        q = np.rint(uv + sign * radial).astype(int)
        assert (mask[q[:, 1], q[:, 0]] == want).all(), (pose, sign)
    # the rim fits in the frame with a margin
    assert uv[:, 0].min() > 20 and uv[:, 0].max() < size[0] - 20
    assert uv[:, 1].min() > 20 and uv[:, 1].max() < size[1] - 20
    if pose == "svp":  # a circle of radius f m / (d + 2c) around the principal point
        r = cam.lens.f * m.m / (m.d + 2 * m.c) * tc.scale[0]
        np.testing.assert_allclose(np.linalg.norm(uv - tc.center_px, axis=1), r, atol=1e-9)
    assert img[0, 0].tolist() == [10, 10, 10]  # outside the mirror


def test_svp_pose_reproduces_eq_2_1_on_the_ground():
    """Aligned, a pixel's traced ray hits the ground where eq. 2.1 (inverted) says, < 1e-6 mm."""
    cam = preset_camera("svp")
    tc = TracedCamera.from_camera(cam)
    C, _ = camera_in_mirror(tc)
    np.testing.assert_allclose(C, [0, 0, -2 * tc.c], atol=1e-12)
    u, v = _pixels(tc, 1.3)
    d = pixel_rays(tc, u, v)
    p, n, hit = trace_mirror(tc, C, d)
    r = reflect(d[hit], n[hit])
    down = r[:, 2] < -0.19  # rays that reach the 20 x 20 m ground
    p, r = p[hit][down], r[down]
    ground = p + ((GROUND_Z - p[:, 2]) / r[:, 2])[:, None] * r
    on = (np.abs(ground[:, 0]) <= 10000) & (np.abs(ground[:, 1]) <= 10000)
    p, r, ground = p[on], r[on], ground[on]
    assert len(ground) > 5000
    # the reflected ray passes through the focus O_m (the single viewpoint)
    dist = np.linalg.norm(np.cross(p, r), axis=1)
    assert dist.max() < 1e-10
    # eq. 2.1, by an independent implementation (omnidev.sim.mirrors), inverted per pixel
    svp = SvpHyperbolicCamera(tc.a, tc.b, tc.f * tc.scale[0], tc.size, tc.center_px, tc.m, 0.0)
    uv = np.stack([u, v], 1)[hit][down][on]
    w = svp.back_project(uv)
    pred = w * (GROUND_Z / w[:, 2])[:, None]
    err = np.linalg.norm(ground - pred, axis=1)
    assert err.max() < 1e-6, err.max()
    uv2, ok = svp.project(ground)
    assert ok.all() and np.abs(uv2 - uv).max() < 1e-9


@pytest.mark.parametrize("pose", ["dissertation", "large"])
def test_mirror_point_obeys_reflection_both_ways(pose: str):
    """A view-plane point's mirror point, projected to a pixel and traced back, reflects to it."""
    cam = preset_camera(pose)
    tc = TracedCamera.from_camera(cam)
    C, _ = camera_in_mirror(tc)
    pts = np.concatenate(
        [v.points(None).reshape(-1, 3) for v in dissertation_planes(40, 30).values()]
    )
    M, ok = mirror_points_towards(tc, pts)
    uv, ok2 = project_to_pixels(tc, M)
    assert (ok & ok2).mean() > 0.99
    d = pixel_rays(tc, uv[:, 0], uv[:, 1])
    p, n, hit = trace_mirror(tc, C, d)
    assert hit[ok].all()
    np.testing.assert_allclose(p[ok], M[ok], atol=1e-7)
    r = reflect(d, n)
    miss = np.linalg.norm(np.cross(pts - p, r), axis=1)  # distance of X from the reflected ray
    assert miss[ok].max() < 1e-6
    assert (np.sum((pts - p) * r, axis=1)[ok] > 0).all()  # X lies ahead, not behind


def test_truth_of_a_textured_plane_does_not_depend_on_the_camera():
    """Where the floor is the top view plane, the truth is its texture whatever the pose."""
    scene = TexturedRoom(0)
    top = dissertation_planes(160, 120)["top"]
    a, ma = render_view_plane(preset_camera("svp"), scene, top)
    b, mb = render_view_plane(preset_camera("large"), scene, top)
    x, y = np.meshgrid(
        np.linspace(-2000, 2000, 161)[:-1] + 12.5, np.linspace(2000, -2000, 121)[:-1] - 16.7
    )
    floor = np.abs(x) + np.abs(y) < 1900  # well inside the room (the walls are |x| + |y| = 2000)
    assert ma[floor].all() and mb[floor].all()
    assert np.abs(a.astype(int) - b.astype(int))[floor].max() <= 1


def test_exact_map_unwarps_to_truth():
    """cv2.remap with the renderer's own map matches the truth views best at zero shift.

    The omni-image resolves the views only coarsely (the 4 x 4 m top view spans
    ~90 omni pixels at 640 x 480), so the PSNR is resolution-bound; a map half a
    pixel off in any direction loses more than 2 dB.
    """
    cam = preset_camera("dissertation")
    scene = TexturedRoom(0)
    omni, _ = render_omni(cam, scene)
    for name in ("top", "side_1"):
        plane = dissertation_planes(160, 120)[name]
        truth, mask = render_view_plane(cam, scene, plane)
        mx, my, ok = view_plane_map(cam, plane)
        sel = mask & ok
        assert sel.mean() > 0.99
        best = psnr(cv2.remap(omni, mx, my, cv2.INTER_LINEAR), truth, sel)
        assert best > 22.0, (name, best)
        for dx, dy in ((0.5, 0), (-0.5, 0), (0, 0.5), (0, -0.5)):
            off = psnr(cv2.remap(omni, mx + dx, my + dy, cv2.INTER_LINEAR), truth, sel)
            assert best > off + 2.0, (name, dx, dy, best, off)


def test_render_is_deterministic(tmp_path: Path):
    cam = preset_camera("large", (320, 240))
    a, ma = render_omni(cam, TexturedRoom(3), supersample=2)
    b, mb = render_omni(cam, TexturedRoom(3), supersample=2)
    c, _ = render_omni(cam, TexturedRoom(4), supersample=2)
    assert np.array_equal(a, b) and np.array_equal(ma, mb)
    assert not np.array_equal(a, c)
    n1, _ = render_omni(cam, PseudoTarget(), supersample=1, noise_sigma=2.0, seed=5)
    n2, _ = render_omni(cam, PseudoTarget(), supersample=1, noise_sigma=2.0, seed=5)
    assert np.array_equal(n1, n2)


def test_fixture_writer(tmp_path: Path):
    cam = preset_camera("dissertation", (160, 120))
    out = tmp_path / "fx"
    truth = make_nonsvp_fixture(out, cam, "pseudo-target", view_size=(40, 30), supersample=1)
    names = {"omni.png", "mask.png", "truth.json"}
    for v in ("top", "side_0", "side_1", "side_2", "side_3"):
        names |= {f"{v}.png", f"{v}_mask.png"}
    assert {p.name for p in out.iterdir()} == names
    assert json.loads((out / "truth.json").read_text()) == json.loads(json.dumps(truth))
    assert truth["camera"]["pose"]["T"] == [-2.99, 0.96, 88.67]
    with pytest.raises(Exception, match="exists"):
        make_nonsvp_fixture(out, cam, "pseudo-target", view_size=(40, 30), supersample=1)


@pytest.mark.parametrize(
    "folder",
    [
        "dissertation-pseudo-640x480",
        "dissertation-textured-640x480",
        "large-textured-1280x960",
        "large-pseudo-1280x960",
    ],
)
def test_committed_fixtures_match_a_fresh_render(folder: str):
    """The committed omni-image is what the renderer makes from truth.json's parameters."""
    d = FIXTURES / folder
    truth = json.loads((d / "truth.json").read_text())
    from omnidev.nonsvp.model import NonSvpCamera
    from omnidev.sim.pseudo_target import make_scene

    cam = NonSvpCamera.from_dict(truth["camera"])
    kind = "pseudo-target" if truth["scene"]["type"] == "pseudo-target" else "textured"
    scene = make_scene(kind, truth["scene"].get("seed", 0))
    img, mask = render_omni(cam, scene, supersample=truth["omni"]["supersample"])
    ref = cv2.imread(str(d / "omni.png"))
    assert ref is not None and ref.shape == img.shape
    diff = np.abs(ref.astype(int) - img.astype(int))
    assert diff.max() <= 1 and (diff > 0).mean() < 1e-3
    assert np.array_equal(cv2.imread(str(d / "mask.png"), cv2.IMREAD_GRAYSCALE) > 0, mask)
    assert truth["regenerate"].startswith("omnidev sim nonsvp ")
    for name in ("top", "side_0", "side_1", "side_2", "side_3"):
        v = cv2.imread(str(d / truth["views"][name]["file"]))
        assert v is not None and v.shape[:2] == (
            truth["views"][name]["height"],
            truth["views"][name]["width"],
        )


def test_cli_registers_and_writes(tmp_path: Path):
    import argparse

    from omnidev.cli.sim_nonsvp_cmd import register_nonsvp
    from omnidev.errors import OmnidevError

    parser = argparse.ArgumentParser()
    register_nonsvp(parser.add_subparsers(dest="what", required=True))
    out = tmp_path / "n"
    argv = ["nonsvp", str(out), "--scene", "pseudo-target", "--size", "96x72"]
    argv += ["--view-size", "48x36", "--supersample", "1", "--T=-1,0.5,88.67"]
    args = parser.parse_args(argv)
    assert args.func(args) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["camera"]["pose"]["T"] == [-1.0, 0.5, 88.67]
    assert truth["camera"]["lens"]["size"] == [96, 72]
    assert "--T=-1,0.5,88.67 --force" in truth["regenerate"]
    bad = parser.parse_args(["nonsvp", str(tmp_path / "m"), "--size", "96"])
    with pytest.raises(OmnidevError, match="WxH"):
        bad.func(bad)

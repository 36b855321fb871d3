"""``nonsvp-hyper`` calibration files through the common camera API: ``omnidev unwarp``
with such a file gives the dense-map view, checked against the renderer's truth."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from omnidev.calibfile import load_camera
from omnidev.cli.main import main
from omnidev.errors import CalibrationError
from omnidev.metrics import psnr
from omnidev.nonsvp.camfile import NonSvpCameraModel, read_camera_file, write_camera_file
from omnidev.sim import nonsvp as sim_nonsvp

FX = Path(__file__).resolve().parents[1] / "fixtures" / "nonsvp" / "dissertation-textured-640x480"


def test_round_trip_and_load_camera(tmp_path):
    cam = sim_nonsvp.preset_camera("dissertation", (640, 480))
    path = tmp_path / "cam.yml.gz"
    write_camera_file(path, cam)
    back = read_camera_file(path)
    assert back.to_dict() == cam.to_dict()
    model = load_camera(path)
    assert model.kind == "nonsvp-hyper" and model.image_size == (640, 480)


def test_omnidev_unwarp_with_a_nonsvp_file(tmp_path, capsys):
    cam = sim_nonsvp.preset_camera("dissertation", (640, 480))
    path = tmp_path / "cam.yml"
    write_camera_file(path, cam)
    out = tmp_path / "top.png"
    argv = [
        "unwarp", str(FX / "omni.png"), "--camera", str(path),
        "--view", "top:320x240,x=4000,y=4000,z=-2000", "-o", str(out),
    ]  # fmt: skip
    assert main(argv) == 0
    got = cv2.imread(str(out), cv2.IMREAD_COLOR)
    truth = cv2.imread(str(FX / "top.png"), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(FX / "top_mask.png"), cv2.IMREAD_GRAYSCALE) > 0
    view = sim_nonsvp.dissertation_planes()["top"]
    cx, cy, ok = sim_nonsvp.view_plane_map(cam, view)
    omni = cv2.imread(str(FX / "omni.png"), cv2.IMREAD_COLOR)
    ceiling = cv2.remap(omni, cx, cy, cv2.INTER_LINEAR)
    m = mask & ok
    p, c = psnr(got, truth, m), psnr(ceiling, truth, m)
    print(f"\nomnidev unwarp, nonsvp-hyper file, top view: {p:.2f} dB (ceiling {c:.2f} dB)")
    assert p >= c - 0.1


def test_bad_files_name_the_file(tmp_path):
    cam = sim_nonsvp.preset_camera("dissertation", (640, 480))
    good = tmp_path / "good.yml"
    write_camera_file(good, cam)
    text = good.read_text()
    inside = tmp_path / "inside.yml"  # the lens moved into the mirror
    inside.write_text(
        "\n".join(
            "pose_tz: 10." if line.startswith("pose_tz:") else line for line in text.splitlines()
        )
    )
    with pytest.raises(CalibrationError, match="inside.yml: pose puts the lens centre inside"):
        read_camera_file(inside)
    short = tmp_path / "short.yml"
    short.write_text("%YAML:1.0\nkind: nonsvp-hyper\nformat_version: 1\nmirror_a: 20\n")
    with pytest.raises(CalibrationError, match="short.yml.*mirror_b"):
        read_camera_file(short)
    huge = tmp_path / "huge.yml"  # finite, but overflows in the mirror's squares
    huge.write_text(
        "\n".join(
            "mirror_a: 1e308" if ln.startswith("mirror_a:") else ln for ln in text.splitlines()
        )
    )
    with pytest.raises(CalibrationError, match=r"huge.yml: key 'mirror_a' is 1e\+308, beyond"):
        read_camera_file(huge)
    tsai = tmp_path / "tsai.yml"
    head, tail = _with_tsai(text, cam).rsplit("data: [", 1)  # tail: tsai_T's data
    tsai.write_text(head + "data: [ -1e300," + tail.split(",", 1)[1])
    with pytest.raises(CalibrationError, match=r"tsai.yml: matrix 'tsai_T' has a value of 1e\+300"):
        read_camera_file(tsai)
    argv = [
        "unwarp", str(FX / "omni.png"), "--camera", str(inside),
        "--view", "top:32x24,x=4000,y=4000,z=-2000", "-o", str(tmp_path / "x.png"),
    ]  # fmt: skip
    assert main(argv) == 2


def _with_tsai(text: str, cam, *, kappa: bool = False) -> str:
    """The file text with the pose_* lines replaced by Tsai's tsai_R, tsai_T."""
    import numpy as np

    r, t = cam.pose.tsai()
    lines = [ln for ln in text.splitlines() if not ln.startswith("pose_")]
    if kappa:
        lines = [
            f"tsai_kappa: {-cam.lens.kappa!r}" if ln.startswith("lens_kappa") else ln
            for ln in lines
        ]

    def mat(name: str, m) -> list[str]:
        m = np.asarray(m, np.float64).reshape(-1, m.shape[-1] if m.ndim > 1 else 1)
        data = ", ".join(repr(float(v)) for v in m.ravel())
        return [f"{name}: !!opencv-matrix", f"   rows: {m.shape[0]}", f"   cols: {m.shape[1]}",
                "   dt: d", f"   data: [ {data} ]"]  # fmt: skip

    return "\n".join(lines + mat("tsai_R", r) + mat("tsai_T", t)) + "\n"


def test_tsai_extrinsics_and_kappa_sign(tmp_path):
    """Tsai's R, T (x_c = R x_b + T, the ring calibration's output) and Tsai's kappa (the
    opposite sign of lens_kappa) load as the same camera as the pose_* / lens_kappa form."""
    import dataclasses

    import numpy as np

    from omnidev.nonsvp.forward import project

    cam = sim_nonsvp.preset_camera("large", (640, 480))
    cam = dataclasses.replace(cam, lens=dataclasses.replace(cam.lens, kappa=1e-2))
    ref = tmp_path / "ref.yml"
    write_camera_file(ref, cam)
    tsai = tmp_path / "tsai.yml"
    tsai.write_text(_with_tsai(ref.read_text(), cam, kappa=True))
    back = read_camera_file(tsai)
    assert back.lens.kappa == cam.lens.kappa
    assert np.allclose(back.pose.R(), cam.pose.R(), atol=1e-12)
    assert np.allclose(back.pose.T, cam.pose.T, atol=1e-9)
    pts = np.random.default_rng(0).uniform([-3000, -3000, -2000], [3000, 3000, -500], (200, 3))
    a, oka = project(cam, pts)
    b, okb = project(back, pts)
    assert np.array_equal(oka, okb) and np.abs(a[oka] - b[okb]).max() < 1e-9
    # a kappa of the wrong sign is a different camera: the file says which one it holds
    wrong = tmp_path / "wrong.yml"
    wrong.write_text(_with_tsai(ref.read_text(), cam).replace("lens_kappa", "tsai_kappa"))
    c, okc = project(read_camera_file(wrong), pts)
    ok = oka & okc
    print(f"\nkappa sign swapped: {np.abs(a[ok] - c[ok]).max():.2f} px off")
    assert np.abs(a[ok] - c[ok]).max() > 1.0


def test_tsai_and_pose_errors_name_the_file(tmp_path):
    cam = sim_nonsvp.preset_camera("dissertation", (640, 480))
    good = tmp_path / "good.yml"
    write_camera_file(good, cam)
    text = good.read_text()
    both = tmp_path / "both.yml"
    both.write_text(_with_tsai(text, cam) + "pose_pitch: 0.0\n")
    with pytest.raises(CalibrationError, match=r"both.yml: give the pose as pose_\* or as tsai"):
        read_camera_file(both)
    kap = tmp_path / "kap.yml"
    kap.write_text(text + "tsai_kappa: 0.0\n")
    with pytest.raises(CalibrationError, match="kap.yml: give lens_kappa or tsai_kappa"):
        read_camera_file(kap)
    bad = tmp_path / "bad.yml"
    bad.write_text(
        _with_tsai(text, cam).replace("tsai_R: !!opencv-matrix", "tsai_Q: 1\nx: !!opencv-matrix")
    )
    with pytest.raises(CalibrationError, match="bad.yml: missing matrix key 'tsai_R'"):
        read_camera_file(bad)
    hs = tmp_path / "hs.yml"
    hs.write_text(text + "housing_radius: -3.0\n")
    with pytest.raises(CalibrationError, match="hs.yml: housing_radius must be > 0"):
        load_camera(hs)


def test_housing_radius_masks_what_the_housing_hides(tmp_path):
    """The top view's pixels whose light passes through the camera body (a cylinder about the
    optical axis behind the lens plane) are masked; checked against a brute-force walk along
    each pixel's light path, from its mirror point to its plane point."""
    import numpy as np

    from omnidev.camera import build_maps
    from omnidev.nonsvp.backproject import backproject

    cam = sim_nonsvp.preset_camera("large", (640, 480))
    view = sim_nonsvp.dissertation_planes(160, 120)["top"]
    path = tmp_path / "cam.yml"
    write_camera_file(path, cam, housing_radius=30.0)
    plain = build_maps(NonSvpCameraModel(cam), view)
    masked = build_maps(load_camera(path), view)
    assert not np.any(masked.valid & ~plain.valid)
    hidden = plain.valid & ~masked.valid
    frac = hidden.sum() / plain.valid.sum()
    # brute force: 4000 samples along each light path beyond the lens plane
    pts = view.points(None)[plain.valid]
    px = np.stack([plain.map_x[plain.valid], plain.map_y[plain.valid]], 1).astype(np.float64)
    m, _, _ = backproject(cam, px)
    o = cam.center_in_mirror()
    axis = cam.rotation_camera_to_mirror() @ np.array([0.0, 0.0, 1.0])
    t = np.linspace(0.0, 1.0, 4000)
    seg = m[:, None] + (pts - m)[:, None] * t[None, :, None]
    rel = seg - o
    h = rel @ axis
    r = np.linalg.norm(rel - h[..., None] * axis, axis=-1)
    brute = np.any((h <= 0) & (r < 30.0), axis=1)
    agree = brute == hidden[plain.valid]
    print(f"\nhousing 30 mm: {100 * frac:.2f} % of the top view's seen pixels masked; "
          f"brute force agrees on {agree.mean():.4f} of them")  # fmt: skip
    assert 0.005 < frac < 0.2 and agree.mean() > 0.995
    # the hidden pixels are the middle of the top view, below the camera
    vv, uu = np.nonzero(hidden)
    assert np.hypot(uu.mean() - 80, vv.mean() - 60) < 15

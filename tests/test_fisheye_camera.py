"""FisheyeCamera, its calibration file and the fisheye unwarper plugin, end to end."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from omnidev import build_maps, load_camera
from omnidev.cli.main import main
from omnidev.errors import CalibrationError
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.camfile import camera_from_file, read_camera_file, write_camera_file
from omnidev.fisheye.models import IdealFisheye, KannalaBrandt, Scaramuzza, Unified
from omnidev.sim import RoomScene, SvpHyperbolicCamera, render_omni, render_view
from omnidev.viewspec import parse_view
from tests.conftest import psnr
from tests.test_fisheye_models import MODELS, SS


class _Renderable:
    """A FisheyeCamera as omnidev.sim.render_omni wants it (centre + back_project)."""

    def __init__(self, camera: FisheyeCamera) -> None:
        self.camera = camera
        self.kind = camera.kind
        self.image_size = camera.image_size
        uv, _ = camera.lens.project(np.array([0.0, 0.0, 1.0]))
        self.center = (float(uv[0]), float(uv[1]))

    def default_elevation_deg(self) -> tuple[float, float] | None:
        return self.camera.default_elevation_deg()

    def project(self, points: np.ndarray, *, finite: bool = True):
        return self.camera.project(points, finite=finite)

    def back_project(self, uv: np.ndarray) -> np.ndarray:
        return self.camera.unproject(uv)[0]


# a 200-degree KB4 lens looking up (its polynomial stays monotonic to 124 deg; used to 100)
SKY = FisheyeCamera(
    KannalaBrandt(200.0, 200.0, 319.5, 321.0, (-0.04, -0.004, 0.0, 0.0)),
    (640, 640),
    max_angle_deg=100,
)
# an equisolid lens on its side, looking along +x
SIDE = FisheyeCamera(IdealFisheye("equisolid", 110.0, 239.5, 179.5), (480, 360), MOUNTS["forward"])
SCENE = RoomScene(seed=3)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    d = tmp_path_factory.mktemp("fisheye")
    out = {}
    for name, cam in (("sky", SKY), ("side", SIDE)):
        img = render_omni(_Renderable(cam), SCENE, supersample=2)  # type: ignore[arg-type]
        cv2.imwrite(str(d / f"{name}.png"), img)
        write_camera_file(d / f"{name}.yml", cam)
        out[name] = (d / f"{name}.png", d / f"{name}.yml", cam)
    return out


@pytest.mark.parametrize(
    ("name", "spec", "min_psnr"),
    [
        ("sky", "perspective:320x240,fov=90,pan=30,tilt=0", 35.0),  # rays to 100 deg off axis
        ("sky", "perspective:320x240,fov=70,pan=200,tilt=60", 45.0),
        ("side", "perspective:320x240,fov=100,pan=10,tilt=-10,roll=5", 36.0),
        ("sky", "panorama:720x200", 40.0),  # the default band: -10 .. 90 deg
    ],
)
def test_unwarp_cli_matches_the_true_view(rendered, tmp_path, name, spec, min_psnr) -> None:
    image, calib, cam = rendered[name]
    out = tmp_path / "view.png"
    argv = ["unwarp", str(image), "--camera", str(calib), "--view", spec, "-o", str(out)]
    assert main(argv) == 0
    got = cv2.imread(str(out))
    view = parse_view(spec)
    truth, _ = render_view(view, SCENE, camera=cam)
    maps = build_maps(cam, view)
    assert maps.valid.mean() > 0.6
    value = psnr(got, truth, maps.valid)
    print(f"{name} {spec}: PSNR {value:.2f} dB over {maps.valid.mean():.0%} of the view")
    assert value >= min_psnr, (spec, value)


def test_rays_beyond_90_degrees_land_on_the_image() -> None:
    # the horizon (90 deg from the up axis) and 10 deg below it are seen; 11 deg below is not
    elev = np.radians([0.0, -10.0, -10.5, -30.0])
    rays = np.stack([np.cos(elev), 0 * elev, np.sin(elev)], -1)
    uv, ok = SKY.project(rays, finite=False)
    assert ok.tolist() == [True, True, False, False]
    assert np.all(np.isfinite(uv[ok])) and np.isnan(uv[~ok]).all()
    assert SKY.default_elevation_deg() == pytest.approx((-10.0, 90.0))


def test_mounts_follow_the_conventions() -> None:
    lens = IdealFisheye("equidistant", 100.0, 319.5, 239.5)
    up = FisheyeCamera(lens, (640, 480))
    down = FisheyeCamera(lens, (640, 480), MOUNTS["down"])
    fwd = FisheyeCamera(lens, (640, 480), MOUNTS["forward"])
    c = np.array([319.5, 239.5])
    d = 0.3  # a small step off the axis, rad
    s, co = math.sin(d), math.cos(d)
    # up: +x to the right, +y down in the image (azimuth sign +1, as a mirror camera)
    uv, ok = up.project(np.array([[0, 0, 1.0], [s, 0, co], [0, s, co]]), finite=False)
    assert ok.all()
    assert np.allclose(uv - c, [[0, 0], [100 * d, 0], [0, 100 * d]])
    # down: +x to the right, +y up in the image (azimuth sign -1)
    uv, ok = down.project(np.array([[0, 0, -1.0], [s, 0, -co], [0, s, -co]]), finite=False)
    assert ok.all()
    assert np.allclose(uv - c, [[0, 0], [100 * d, 0], [0, -100 * d]])
    # forward: looks along +x, upright: +z up in the image, -y to the right
    uv, ok = fwd.project(np.array([[1.0, 0, 0], [co, 0, s], [co, -s, 0]]), finite=False)
    assert ok.all()
    assert np.allclose(uv - c, [[0, 0], [0, -100 * d], [100 * d, 0]])
    # unproject is the inverse, in the camera frame
    rays, ok = fwd.unproject(np.array([[319.5, 239.5 - 100 * d]]))
    assert ok.all() and np.allclose(rays, [[co, 0, s]])
    # default elevation bands: the field of view around the axis, capped by the image
    assert up.default_elevation_deg()[1] == 90.0
    assert down.default_elevation_deg()[0] == -90.0
    assert fwd.default_elevation_deg() == (-90.0, 90.0)  # the image holds the whole 360 deg disc
    narrow = FisheyeCamera(IdealFisheye("equidistant", 300.0, 319.5, 239.5), (640, 480), fwd.mount)
    corner = math.degrees(math.hypot(320.0, 240.0) / 300.0)  # the farthest border pixel
    assert narrow.default_elevation_deg() == pytest.approx((-corner, corner), abs=0.01)


def test_mirror_mount_makes_the_unified_model_the_sim_mirror_camera() -> None:
    """The SVP hyperbolic-mirror camera of omnidev.sim (eq. 2.1) is exactly a unified model,
    xi = 2bc / (b^2 + c^2) and focal f a^2 / (b^2 + c^2), seen through the mirror-up mount:
    the image centre sees the camera (down) and the image keeps azimuth sign +1."""
    sim = SvpHyperbolicCamera.default()
    a, b, c = sim.a, sim.b, sim.c
    g = sim.f * a * a / (b * b + c * c)
    lens = Unified(g, g, sim.center[0], sim.center[1], xi=2 * b * c / (b * b + c * c))
    cam = FisheyeCamera(lens, sim.image_size, MOUNTS["mirror-up"])
    rng = np.random.default_rng(4)
    pts = rng.normal(size=(5000, 3)) * 3.0
    want, ok_sim = sim.project(pts, finite=True)
    got, ok = cam.project(pts, finite=True)
    both = ok_sim & ok
    assert both.sum() > 1000 and np.array_equal(ok_sim, both)  # (ours has no rim or cut-off)
    assert np.abs(got[both] - want[both]).max() < 1e-9
    with pytest.raises(ValueError, match="orthonormal"):
        FisheyeCamera(lens, sim.image_size, 1.1 * np.eye(3))


def all_cameras() -> list[tuple[str, FisheyeCamera]]:
    cams = [(key, FisheyeCamera(lens, (640, 480))) for key, (lens, _) in MODELS.items()]
    tilted = cv2.Rodrigues(np.array([0.1, -0.2, 0.3]))[0] @ MOUNTS["down"]
    inv = tuple(np.linspace(400, -3, 9))
    cams += [
        ("kb4-tilted-95", FisheyeCamera(MODELS["kb4"][0], (640, 480), tilted, 95.0)),
        ("mei-mirror-up", FisheyeCamera(MODELS["mei"][0], (640, 480), MOUNTS["mirror-up"])),
        ("scaramuzza-invpol", FisheyeCamera(Scaramuzza(SS, 240.3, 319.1, invpol=inv), (640, 480))),
    ]
    return cams


@pytest.mark.parametrize("suffix", [".yml", ".yml.gz", ".json", ".xml"])
def test_file_round_trip_for_every_model(tmp_path, suffix) -> None:
    rng = np.random.default_rng(0)
    rays = rng.normal(size=(500, 3))
    for key, cam in all_cameras():
        path = tmp_path / f"{key}{suffix}"
        write_camera_file(path, cam)
        back = read_camera_file(path)
        assert back.lens == cam.lens, key
        assert back.image_size == cam.image_size and back.max_angle_deg == cam.max_angle_deg
        assert np.array_equal(back.mount, cam.mount)
        a, oka = cam.project(rays, finite=False)
        b, okb = back.project(rays, finite=False)
        assert np.array_equal(oka, okb) and np.array_equal(a[oka], b[okb])
        assert load_camera(path).kind == "fisheye"


def test_options_mount_and_max_angle(tmp_path) -> None:
    path = tmp_path / "cam.yml"
    write_camera_file(path, SKY)
    cam = camera_from_file(path, {"mount": "down", "max_angle_deg": "80"})
    assert np.array_equal(cam.mount, MOUNTS["down"]) and cam.max_angle_deg == 80.0
    assert cam.default_elevation_deg() == pytest.approx((-90.0, -10.0))
    with pytest.raises(CalibrationError, match="no option 'lookup'"):
        camera_from_file(path, {"lookup": "nearest"})
    with pytest.raises(CalibrationError, match="mount='sideways'"):
        camera_from_file(path, {"mount": "sideways"})
    with pytest.raises(CalibrationError, match="max_angle_deg='wide'"):
        camera_from_file(path, {"max_angle_deg": "wide"})


def _one_line_error(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


def test_bad_files_give_one_line_errors(tmp_path, capsys) -> None:
    good = tmp_path / "good.yml"
    write_camera_file(good, SKY)
    text = good.read_text()
    image = tmp_path / "img.png"
    cv2.imwrite(str(image), np.zeros((640, 640, 3), np.uint8))
    cases = {
        "no-fx.yml": (text.replace("fx: 200.\n", ""), "'fx'"),
        "no-k.yml": (text.split("k: !!opencv-matrix")[0] + "image_width: 640\n", "'k'"),
        "no-width.yml": (text.replace("image_width: 640\n", ""), "'image_width'"),
        "negative-fx.yml": (text.replace("fx: 200.", "fx: -200."), "parameter fx must be > 0"),
        "model.yml": (text.replace("model: kb4", "model: pinhole"), "'model'"),
        "mount.yml": (text.replace("data: [ 1., 0., 0.,", "data: [ 2., 0., 0.,"), "'mount'"),
        "garbage.yml": ("%YAML 1.2\n---\nkind: [fisheye\n", "not a readable"),
        "cut-in-k.yml": (
            text.split("k: !!opencv-matrix")[0] + "k: !!opencv-matrix\n"
            "   rows: 1\n   cols: 4\n   dt: d\n",
            "matrix key 'k' is incomplete",
        ),
        "version.yml": (text.replace("format_version: 1", "format_version: 7"), "version 7"),
    }
    for name, (content, needle) in cases.items():
        path = tmp_path / name
        path.write_text(content)
        with pytest.raises(CalibrationError) as exc:
            read_camera_file(path)
        msg = str(exc.value)
        assert str(path) in msg and needle in msg, (name, msg)
        err = _one_line_error(
            capsys,
            ["unwarp", str(image), "--camera", str(path), "--view", "perspective:64x48", "-o",
             str(tmp_path / "o.png")],
        )  # fmt: skip
        assert str(path) in err and needle in err, (name, err)


def test_plugin_is_registered(capsys) -> None:
    assert main(["plugins"]) == 0
    lines = [ln.split() for ln in capsys.readouterr().out.splitlines()]
    assert ["fisheye", "omnidev-fisheye", "0.1.0"] in lines

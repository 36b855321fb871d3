"""Import/export of other tools' calibrations (omnidev.fisheye.formats, .miniyaml).

Each format round-trips: a model written in the format is read back with identical
parameters, and then through omnidev's own file and OpenCV's K/D/xi and back.
OpenCV's own functions check that K, D and xi mean what cv2.fisheye / cv2.omnidir
users expect.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from omnidev.errors import CalibrationError
from omnidev.fisheye import miniyaml
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.camfile import write_camera_file
from omnidev.fisheye.formats import (
    basalt_text,
    detect_format,
    import_calibration,
    kalibr_text,
    ocamcalib_text,
    opencv_nodes,
    parse_basalt,
    parse_kalibr,
    parse_ocamcalib,
    parse_pyocamcalib,
    write_opencv,
)
from omnidev.fisheye.models import (
    EUCM,
    DoubleSphere,
    FieldOfView,
    IdealFisheye,
    KannalaBrandt,
    LensModel,
    Scaramuzza,
    Unified,
)

KB4 = KannalaBrandt(fx=190.97, fy=190.93, cx=254.93, cy=256.89, k=(0.0035, 7e-4, -2.05e-3, 2e-4))
MEI = Unified(
    fx=366.07, fy=366.16, cx=643.71, cy=521.31, xi=1.443, skew=-1.73,
    k1=0.1098, k2=0.2166, p1=8.25e-4, p2=-2.58e-4,
)  # fmt: skip
DS = DoubleSphere(fx=158.28, fy=158.27, cx=254.96, cy=256.88, xi=-0.1721, alpha=0.5931)
EU = EUCM(fx=191.14, fy=191.13, cx=254.95, cy=256.88, alpha=0.6291, beta=1.0418)
FOV = FieldOfView(fx=446.91584, fy=447.071232, cx=631.2192, cy=510.997504, w=0.933271)
OCAM = Scaramuzza(
    ss=(-337.4374, 0.0, 0.001232446, -1.355883e-06, 2.914654e-09),
    xc=378.875612, yc=541.097113, c=0.998971, d=-0.000104, e=-0.000312,
    invpol=(509.74394, 292.31636, -13.734732, 41.371323, 24.066967, -7.800231),
)  # fmt: skip
SIZE = (512, 512)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _omnidev_round_trip(tmp: Path, lens: Any, size: tuple[int, int]) -> None:
    """Through omnidev's own ``fisheye`` file (mount down) and back: identical."""
    path = tmp / "omnidev.yml"
    write_camera_file(path, FisheyeCamera(lens, size, MOUNTS["down"], 95.0), force=True)
    back = import_calibration(path)
    assert back.lens == lens and back.image_size == size
    assert back.max_angle_deg == 95.0 and back.mount is not None
    assert np.array_equal(back.mount, MOUNTS["down"])


# ---------------------------------------------------------------- miniyaml


def test_miniyaml_reads_the_kalibr_block_style_cv2_filestorage_rejects(tmp_path: Path) -> None:
    text = (
        "cam0:\n  T_cam_imu:\n  - [1.0, 0.0, 0.0, 0.05]\n  - [0, 1, 0, -0.1]\n"
        "  camera_model: pinhole   # comment\n  intrinsics: [190.9, 190.8,\n    254.9, 256.8]\n"
        "  rostopic: '/cam0/image # raw'\n  flag: true\n  none: ~\n"
        'cam1: {fx: 1.5e2, k: [1, -2], name: "a b"}\n'
    )
    assert miniyaml.loads(text) == {
        "cam0": {
            "T_cam_imu": [[1.0, 0.0, 0.0, 0.05], [0, 1, 0, -0.1]],
            "camera_model": "pinhole",
            "intrinsics": [190.9, 190.8, 254.9, 256.8],
            "rostopic": "/cam0/image # raw",
            "flag": True,
            "none": None,
        },
        "cam1": {"fx": 150.0, "k": [1, -2], "name": "a b"},
    }
    path = _write(tmp_path / "chain.yaml", "%YAML:1.0\n" + text)
    with pytest.raises((cv2.error, SystemError)):  # why omnidev reads Kalibr YAML itself
        cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("a: [1, 2\nb: 3\n", "line 1: unclosed"),
        ("a: 1\na: 2\n", "line 2: key 'a' given twice"),
        ("a: &x 1\n", "line 1: anchors"),
        ("a:\n  b: 1\n   c: 2\n", "line 3"),
    ],
)
def test_miniyaml_errors_name_the_line(text: str, where: str) -> None:
    with pytest.raises(miniyaml.YamlError, match=where):
        miniyaml.loads(text)


# ---------------------------------------------------------------- OCamCalib


def test_ocamcalib_round_trip(tmp_path: Path) -> None:
    path = _write(tmp_path / "calib_results.txt", ocamcalib_text(OCAM, (1032, 778)))
    assert detect_format(path) == "ocamcalib"
    got = import_calibration(path)
    assert got.lens == OCAM and got.image_size == (1032, 778) and got.format == "ocamcalib"
    _omnidev_round_trip(tmp_path, OCAM, (1032, 778))
    no_inv = dataclasses.replace(OCAM, invpol=None)
    assert parse_ocamcalib(ocamcalib_text(no_inv, (1032, 778)), "x").lens == no_inv


def test_ocamcalib_conventions_row_column_and_frame() -> None:
    """Centre (xc, yc) is (row, column); the optical axis is -z of OCamCalib's frame."""
    text = "# c\n3 -100 0 0.001\n0\n200.0 300.0\n1 0 0\n480 640\n"
    lens = parse_ocamcalib(text, "x").lens
    uv, ok = lens.project(np.array([0.0, 0.0, 1.0]))
    assert ok and np.allclose(uv, [300.0, 200.0])  # u = column yc, v = row xc
    # a ray to the right (+x optical) lands right of the centre, one down lands below it
    uv, _ = lens.project(np.array([[0.1, 0.0, 1.0], [0.0, 0.1, 1.0]]))
    assert uv[0, 0] > 300 and abs(uv[0, 1] - 200) < 1e-9
    assert uv[1, 1] > 200 and abs(uv[1, 0] - 300) < 1e-9


# ---------------------------------------------------------------- Kalibr


@pytest.mark.parametrize("lens", [KB4, dataclasses.replace(MEI, skew=0.0), DS, EU, FOV])
def test_kalibr_round_trip(tmp_path: Path, lens: Any) -> None:
    other = dataclasses.replace(KB4, fx=100.0)
    text = kalibr_text(other, (640, 480), "cam0") + kalibr_text(lens, SIZE, "cam1")
    path = _write(tmp_path / "camchain.yaml", text)
    assert detect_format(path) == "kalibr"
    for camera in ("cam1", "1"):
        got = import_calibration(path, camera=camera)
        assert got.lens == lens and got.image_size == SIZE
        assert got.camera == "cam1" and got.cameras == ("cam0", "cam1")
    assert import_calibration(path).lens == other  # default: the first camera
    _omnidev_round_trip(tmp_path, lens, SIZE)
    if isinstance(lens, KannalaBrandt | Unified):
        out = tmp_path / "opencv.yml"
        write_opencv(out, lens, SIZE)
        back = import_calibration(out)
        assert back.lens == lens and back.image_size == SIZE


def test_kalibr_pinhole_radtan_is_the_unified_model_with_xi_zero() -> None:
    doc = miniyaml.loads(
        "cam0:\n  camera_model: pinhole\n  intrinsics: [400.0, 401.0, 320.0, 240.0]\n"
        "  distortion_model: radtan\n  distortion_coeffs: [-0.2, 0.05, 0.001, -0.002]\n"
        "  resolution: [640, 480]\n"
    )
    lens = parse_kalibr(doc, "x").lens
    assert isinstance(lens, Unified) and lens.xi == 0.0
    pts = np.random.default_rng(1).uniform([-0.5, -0.4, 1.0], [0.5, 0.4, 2.0], (50, 3))
    K = np.array([[400.0, 0, 320], [0, 401, 240], [0, 0, 1]])
    ref, _ = cv2.projectPoints(
        pts, np.zeros(3), np.zeros(3), K, np.array([-0.2, 0.05, 0.001, -0.002])
    )
    uv, ok = lens.project(pts)
    assert ok.all() and np.abs(uv - ref.reshape(-1, 2)).max() < 1e-9


def test_tumvi_style_named_yaml() -> None:
    doc = miniyaml.loads(
        "width: 512\nheight: 512\ncam0: {fx: 190.9, fy: 190.8, cx: 254.9, cy: 256.8,\n"
        "       k1: 0.0034, k2: 0.0007, k3: -0.002, k4: 0.0002}\n"
    )
    got = parse_kalibr(doc, "x")
    assert got.lens == KannalaBrandt(190.9, 190.8, 254.9, 256.8, (0.0034, 0.0007, -0.002, 0.0002))
    assert got.image_size == (512, 512)


# ---------------------------------------------------------------- basalt and others


def test_basalt_round_trip(tmp_path: Path) -> None:
    lenses: list[LensModel] = [KB4, DS, EU, FOV]
    sizes = [SIZE, (640, 480), (1280, 1024), (1280, 1024)]
    path = _write(tmp_path / "calibration.json", basalt_text(lenses, sizes))
    assert detect_format(path) == "basalt"
    for i, (lens, size) in enumerate(zip(lenses, sizes, strict=True)):
        got = import_calibration(path, camera=str(i))
        assert got.lens == lens and got.image_size == size and got.cameras == ("0", "1", "2", "3")
        _omnidev_round_trip(tmp_path, lens, size)
    assert import_calibration(path, camera="cam2").lens == EU


def test_basalt_ucm_is_the_unified_model() -> None:
    """basalt's UCM: u = fx x / (alpha d + (1 - alpha) z) + cx."""
    fx, fy, cx, cy, alpha = 300.0, 301.0, 320.0, 240.0, 0.6
    doc = {"value0": {"intrinsics": [{"camera_type": "ucm", "intrinsics": dict(
        fx=fx, fy=fy, cx=cx, cy=cy, alpha=alpha)}]}}  # fmt: skip
    lens = parse_basalt(doc, "x").lens
    assert isinstance(lens, Unified)
    pts = np.random.default_rng(2).normal(size=(100, 3)) + np.array([0, 0, 1.0])
    d = np.linalg.norm(pts, axis=1)
    m = alpha * d + (1 - alpha) * pts[:, 2]
    ref = np.stack([fx * pts[:, 0] / m + cx, fy * pts[:, 1] / m + cy], 1)
    uv, ok = lens.project(pts)
    assert np.abs(uv[ok] - ref[ok]).max() < 1e-9 and ok.sum() > 80


def test_camera_intrinsic_model_json(tmp_path: Path) -> None:
    params = {"fx": EU.fx, "fy": EU.fy, "cx": EU.cx, "cy": EU.cy, "alpha": EU.alpha}
    doc = {"EUCM": {**params, "beta": EU.beta, "width": 512, "height": 512}}
    path = _write(tmp_path / "eucm0.json", json.dumps(doc))
    assert detect_format(path) == "cim"
    assert import_calibration(path).lens == EU
    doc = {"FovCamera": {"fx": FOV.fx, "fy": FOV.fy, "cx": FOV.cx, "cy": FOV.cy, "w": FOV.w,
                         "width": 1280, "height": 1024}}  # fmt: skip
    path = _write(tmp_path / "fov.json", json.dumps(doc))
    assert detect_format(path) == "cim"
    got = import_calibration(path)
    assert got.lens == FOV and got.image_size == (1280, 1024)


def test_kalibr_pinhole_fov_is_the_fov_model() -> None:
    """Kalibr's FovDistortion: r_d = atan(2 r tan(w / 2)) / w on x / z, y / z."""
    doc = miniyaml.loads(
        "cam0:\n  camera_model: pinhole\n  intrinsics: [400.0, 401.0, 320.0, 240.0]\n"
        "  distortion_model: fov\n  distortion_coeffs: [0.9]\n  resolution: [640, 480]\n"
    )
    lens = parse_kalibr(doc, "x").lens
    assert lens == FieldOfView(400.0, 401.0, 320.0, 240.0, 0.9)
    pts = np.random.default_rng(5).uniform([-0.8, -0.6, 0.5], [0.8, 0.6, 2.0], (50, 3))
    x, y = pts[:, 0] / pts[:, 2], pts[:, 1] / pts[:, 2]
    r = np.hypot(x, y)
    f = np.arctan(2 * r * np.tan(0.45)) / (0.9 * r)
    uv, ok = lens.project(pts)
    assert (
        ok.all() and np.abs(uv - np.stack([400 * f * x + 320, 401 * f * y + 240], 1)).max() < 1e-9
    )


# ---------------------------------------------------------------- py-OCamCalib


def _pyocam_world2cam(doc: dict[str, Any], pts: np.ndarray) -> np.ndarray:
    """py-OCamCalib's Camera.world2cam as it is written: the smallest positive real root of
    P(rho) - rho z / hypot(x, y), then the stretch applied with the column updated first."""
    p = np.array(doc["taylor_coefficient"], np.float64)
    (c, d), (e, _) = doc["stretch_matrix"]
    out = []
    for x, y, z in pts:
        r = math.hypot(x, y)
        coeffs = p[::-1].copy()
        coeffs[-2] -= z / r
        roots = np.roots(coeffs)
        rho = min(v.real for v in roots if abs(v.imag) < 1e-12 and v.real > 0)
        px, py = x / r * rho, y / r * rho
        px = px * c + py * d
        py = px * e + py
        out.append((px + doc["distortion_center"][0], py + doc["distortion_center"][1]))
    return np.array(out)


PYOCAM_DOC = {
    "taylor_coefficient": [337.7168, 0.0, -0.00122383, 1.3804e-06, -3.0106e-09],
    "distortion_center": [543.986, 377.649],
    "stretch_matrix": [[1.0033, 0.0123], [-0.0104, 1.0]],
    "rms_overall": 0.24,
}


def test_pyocamcalib_json_projects_as_pyocamcalib_does(tmp_path: Path) -> None:
    """Centre (column, row), stretch on the columns (with world2cam's row-after-column update),
    sign-flipped Taylor polynomial, inverse polynomial in descending powers of the angle from
    the axis: the imported Scaramuzza lens projects as py-OCamCalib's world2cam, exactly."""
    pts = np.random.default_rng(6).normal(size=(300, 3)) + np.array([0.0, 0.0, 0.3])
    ref = _pyocam_world2cam(PYOCAM_DOC, pts)
    path = _write(tmp_path / "calibration_fisheye.json", json.dumps(PYOCAM_DOC))
    assert detect_format(path) == "pyocamcalib"
    got = import_calibration(path)
    lens = got.lens
    assert isinstance(lens, Scaramuzza) and lens.invpol is None and got.format == "pyocamcalib"
    assert (lens.xc, lens.yc) == (377.649, 543.986) and lens.ss[0] < 0
    uv, ok = lens.project(pts)
    angle = np.degrees(np.arctan2(np.hypot(pts[:, 0], pts[:, 1]), pts[:, 2]))
    assert ok[angle < 150].all()
    assert np.abs(uv[ok] - ref[ok]).max() < 1e-8
    rays, ok2 = lens.unproject(uv[ok])
    unit = pts[ok] / np.linalg.norm(pts[ok], axis=1)[:, None]
    assert ok2.all() and np.abs(rays - unit).max() < 1e-10
    # inverse_poly as py-OCamCalib fits it: rho(theta) over [0, 0.9 pi], descending powers
    theta = np.linspace(0, 0.9 * math.pi, 100)
    rho = np.hypot(*(_pyocam_world2cam({**PYOCAM_DOC, "stretch_matrix": [[1, 0], [0, 1]],
        "distortion_center": [0, 0]}, np.stack([np.sin(theta[1:]), 0 * theta[1:],
        np.cos(theta[1:])], 1))).T)  # fmt: skip
    inv = np.polyfit(theta[1:], rho, 12)
    assert np.abs(np.polyval(inv, theta[1:]) - rho).max() < 0.05  # px, to 162 degrees
    with_inv = parse_pyocamcalib({**PYOCAM_DOC, "inverse_poly": inv.tolist()}, "x").lens
    assert isinstance(with_inv, Scaramuzza) and with_inv.invpol is not None
    uv3, ok3 = with_inv.project(pts)
    both = ok & ok3 & (angle < 0.9 * 180)
    assert both.sum() > 250 and np.abs(uv3[both] - ref[both]).max() < 0.1
    _omnidev_round_trip(tmp_path, lens, (1032, 778))


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"taylor_coefficient": None}, "missing key 'taylor_coefficient'"),
        ({"taylor_coefficient": [-337.0, 0.0, 0.001]}, "first > 0"),
        ({"distortion_center": [1.0]}, "'distortion_center' has 1 numbers, expected 2"),
        ({"stretch_matrix": [[1.0, 0.0]]}, "'stretch_matrix' is not a 2x2 matrix"),
        ({"stretch_matrix": [[1.0, 0.0], [0.0, 2.0]]}, "[[c, d], [e, 1]]"),
        ({"inverse_poly": [1.0, "a"]}, "key 'inverse_poly' is not a number"),
    ],
)
def test_pyocamcalib_bad_keys_are_named(tmp_path: Path, change: dict[str, Any], key: str) -> None:
    path = _write(tmp_path / "py.json", json.dumps({**PYOCAM_DOC, **change}))
    assert key in _error(path, fmt="pyocamcalib")


# ---------------------------------------------------------------- OpenCV


@pytest.mark.parametrize("suffix", [".yml", ".xml", ".json", ".yml.gz"])
@pytest.mark.parametrize("lens", [KB4, dataclasses.replace(KB4, skew=0.4), MEI])
def test_opencv_round_trip(tmp_path: Path, lens: Any, suffix: str) -> None:
    path = tmp_path / ("cam" + suffix)
    write_opencv(path, lens, SIZE)
    assert detect_format(path) == "opencv"
    got = import_calibration(path)
    assert got.lens == lens and got.image_size == SIZE and got.format == "opencv"
    _omnidev_round_trip(tmp_path, lens, SIZE)


def test_opencv_export_means_what_cv2_fisheye_and_omnidir_read() -> None:
    pts = np.random.default_rng(3).uniform([-1, -1, 0.2], [1, 1, 1.0], (200, 1, 3))
    kb = dataclasses.replace(KB4, skew=0.4)
    n = opencv_nodes(kb, SIZE)
    ref, _ = cv2.fisheye.projectPoints(
        pts, np.zeros(3), np.zeros(3), n["K"], n["D"], alpha=0.4 / kb.fx
    )
    uv, ok = kb.project(pts.reshape(-1, 3))
    assert ok.all() and np.abs(uv - ref.reshape(-1, 2)).max() < 1e-9
    n = opencv_nodes(MEI, SIZE)
    ref, _ = cv2.omnidir.projectPoints(
        pts, np.zeros(3), np.zeros(3), n["K"], float(n["xi"][0, 0]), n["D"]
    )
    uv, ok = MEI.project(pts.reshape(-1, 3))
    assert ok.all() and np.abs(uv - ref.reshape(-1, 2)).max() < 1e-9


def test_opencv_reads_plain_cv2_files_and_ros_camera_info(tmp_path: Path) -> None:
    path = tmp_path / "fisheye.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    K = np.array([[KB4.fx, 0, KB4.cx], [0, KB4.fy, KB4.cy], [0, 0, 1]])
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", np.array(KB4.k).reshape(1, 4))
    fs.release()
    got = import_calibration(path)
    assert got.lens == KB4 and got.image_size is None
    ros = tmp_path / "camera_info.yaml"
    ros.write_text(
        "image_width: 512\nimage_height: 512\ncamera_name: fish\ncamera_matrix:\n  rows: 3\n"
        f"  cols: 3\n  data: [{KB4.fx!r}, 0, {KB4.cx!r}, 0, {KB4.fy!r}, {KB4.cy!r}, 0, 0, 1]\n"
        "distortion_model: equidistant\ndistortion_coefficients:\n  rows: 1\n  cols: 4\n"
        f"  data: [{', '.join(repr(k) for k in KB4.k)}]\n"
    )
    assert detect_format(ros) == "opencv"
    got = import_calibration(ros)
    assert got.lens == KB4 and got.image_size == SIZE


def test_opencv_export_of_models_opencv_lacks() -> None:
    eq = IdealFisheye("equidistant", 300.0, 320.0, 240.0)
    assert opencv_nodes(eq, None)["D"].ravel().tolist() == [0.0] * 4
    with pytest.raises(CalibrationError, match="OpenCV has no 'ds' lens"):
        opencv_nodes(DS, SIZE)


# ---------------------------------------------------------------- bad input


def _error(path: Path, **kw: Any) -> str:
    with pytest.raises(CalibrationError) as info:
        import_calibration(path, **kw)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg
    return msg


def test_unreadable_files(tmp_path: Path) -> None:
    assert "not found" in _error(tmp_path / "missing.txt")
    binary = tmp_path / "calib.yaml"
    binary.write_bytes(b"\xff\xfe\x00\x81binary")
    assert "cannot read" in _error(binary)
    bad = _write(tmp_path / "calib.json", "{not json")
    assert "not JSON" in _error(bad, fmt="basalt")
    yml = _write(tmp_path / "chain.yaml", "cam0:\n  intrinsics: [1, 2\n")
    assert "line 2: unclosed" in _error(yml, fmt="kalibr")


@pytest.mark.parametrize(
    ("name", "text", "fmt", "key"),
    [
        ("c.txt", "#\n3 -100 0 0.001\n0\n200 300\n", "ocamcalib", "affine c d e"),
        ("c.txt", "#\n3 -100 0\n0\n200 300\n1 0 0\n480 640\n", "ocamcalib", "ss (polynomial)"),
        ("k.yaml", "cam0:\n  camera_model: omni\n  resolution: [1, 1]\n", "kalibr",
         "cam0.intrinsics"),
        ("k.yaml", "cam0:\n  camera_model: ds\n  intrinsics: [1, 2]\n", "kalibr",
         "cam0.intrinsics"),
        ("k.yaml", "cam0: {fx: 1, fy: 1, cx: 1, cy: 1, k1: 0}\n", "kalibr", "cam0.k2"),
        ("b.json", '{"value0": {"intrinsics": [{"camera_type": "ds", "intrinsics": '
         '{"fx": 1, "fy": 1, "cx": 1, "cy": 1, "xi": 0}}]}}', "basalt", "intrinsics.alpha"),
        ("b.json", '{"value0": {"resolution": []}}', "basalt", "value0.intrinsics"),
        ("f.json", '{"FovCamera": {"fx": 1}}', "cim", "FovCamera.fy"),
        ("o.yml", "%YAML:1.0\nD: [0, 0, 0, 0]\n", "opencv", "'K'"),
        ("o.yml", "%YAML:1.0\nK: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
         "  data: [1, 0, 1, 0, 1, 1, 0, 0, 1]\n", "opencv", "'D'"),
    ],
)  # fmt: skip
def test_partial_files_name_the_key(
    tmp_path: Path, name: str, text: str, fmt: str, key: str
) -> None:
    assert key in _error(_write(tmp_path / name, text), fmt=fmt)


@pytest.mark.parametrize(
    ("name", "text", "what"),
    [
        ("k.yaml", "cam0:\n  camera_model: fov\n  intrinsics: [1]\n", "camera_model 'fov'"),
        ("k.yaml", "cam0:\n  camera_model: omni\n  intrinsics: [1, 1, 1, 1, 1]\n"
         "  distortion_model: fov\n  distortion_coeffs: [0.9]\n", "omni with distortion 'fov'"),
        ("k.yaml", "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 1, 1]\n"
         "  distortion_model: fisheye\n  distortion_coeffs: [0.9]\n",
         "distortion_model 'fisheye'"),
        ("b.json", '{"value0": {"intrinsics": [{"camera_type": "bal", "intrinsics": {}}]}}',
         "camera_type 'bal'"),
        ("f.json", '{"KannalaBrandt": {"fx": 1}}', "model 'KannalaBrandt'"),
        ("o.yml", "%YAML:1.0\nK: [1, 0, 1, 0, 1, 1, 0, 0, 1]\n", "not an upper-triangular"),
        ("o.yml", "%YAML:1.0\nkind: pano-table\n", "kind 'pano-table'"),
        ("c.txt", "#\n3 100 0 0.001\n0\n200 300\n1 0 0\n480 640\n", "ss[0] < 0"),
    ],
)  # fmt: skip
def test_unknown_models_name_the_key(tmp_path: Path, name: str, text: str, what: str) -> None:
    assert what in _error(_write(tmp_path / name, text))


def test_camera_choice_errors(tmp_path: Path) -> None:
    path = _write(tmp_path / "camchain.yaml", kalibr_text(KB4, SIZE, "cam0"))
    assert "no camera 'cam3' (the file has cam0)" in _error(path, camera="cam3")
    ocam = _write(tmp_path / "calib_results.txt", ocamcalib_text(OCAM, SIZE))
    assert "--camera applies to Kalibr and basalt" in _error(ocam, camera="1")


KALIBR_CAMCHAIN = """\
cam0:
  T_cam_imu:
  - [-0.9995250378696743, 0.029615343885863205, -0.008522328211654736, 0.04727988224914392]
  - [0.0075019185074052044, -0.03439736061393144, -0.9993800792498829, -0.047443232143367084]
  - [-0.02989013031643309, -0.998969345370175, 0.03415885127385616, -0.0681999605066297]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [1]
  camera_model: pinhole
  distortion_coeffs: [0.0034823894022493434, 0.0007150348452162257, -0.0020532361418706202,
    0.00020293673591811182]
  distortion_model: equidistant
  intrinsics: [190.97847715128717, 190.9733070521226, 254.93170605935475, 256.8974428996504]
  resolution: [512, 512]
  rostopic: /cam0/image_raw
  timeshift_cam_imu: 0.0
cam1:
  T_cn_cnm1:
  - [0.999999445773493, 0.000791687752817, 0.000694034010224, 0.101063427414194]
  - [-0.000823363992158, 0.998899461915674, 0.046895490788700, 0.001946204678584]
  - [-0.000656143613644, -0.046896036240590, 0.998899560146304, 0.001015350132563]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [0]
  camera_model: omni
  distortion_coeffs: [-0.1, 0.02, 1.0e-4, -2.0e-4]
  distortion_model: radtan
  intrinsics: [1.2, 480.0, 481.0, 254.0, 255.0]
  resolution: [512, 512]
  rostopic: /cam1/image_raw
"""


def test_a_kalibr_camchain_as_kalibr_writes_it(tmp_path: Path) -> None:
    """Kalibr's own layout (PyYAML block style, extrinsics, a wrapped flow list)."""
    path = _write(tmp_path / "camchain-imucam.yaml", KALIBR_CAMCHAIN)
    assert detect_format(path) == "kalibr"
    cam0 = import_calibration(path)
    assert cam0.lens == KannalaBrandt(
        190.97847715128717, 190.9733070521226, 254.93170605935475, 256.8974428996504,
        (0.0034823894022493434, 0.0007150348452162257, -0.0020532361418706202,
         0.00020293673591811182),
    )  # fmt: skip
    cam1 = import_calibration(path, camera="cam1")
    assert cam1.lens == Unified(
        fx=480.0, fy=481.0, cx=254.0, cy=255.0, xi=1.2, k1=-0.1, k2=0.02, p1=1e-4, p2=-2e-4
    )
    assert cam0.image_size == cam1.image_size == (512, 512)

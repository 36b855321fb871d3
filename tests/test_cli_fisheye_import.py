"""``omnidev calibrate import``: other tools' calibrations -> omnidev ``fisheye`` files that
``omnidev unwarp --camera`` reads; exit 2 with one line on bad input."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from omnidev.cli.main import main
from omnidev.fisheye.camera import MOUNTS
from omnidev.fisheye.camfile import read_camera_file
from omnidev.fisheye.formats import import_calibration, kalibr_text, ocamcalib_text
from omnidev.fisheye.models import DoubleSphere, KannalaBrandt, Scaramuzza
from tests.conftest import REALDATA

KB4 = KannalaBrandt(fx=190.97, fy=190.93, cx=254.93, cy=256.89, k=(0.0035, 7e-4, -2.05e-3, 2e-4))
DS = DoubleSphere(fx=158.28, fy=158.27, cx=254.96, cy=256.88, xi=-0.1721, alpha=0.5931)


def _one_line_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "error:" in err
    return err


def test_import_kalibr_write_export_and_unwarp(tmp_path, capsys):
    chain = tmp_path / "camchain.yaml"
    chain.write_text(kalibr_text(DS, (512, 512), "cam0") + kalibr_text(KB4, (512, 512), "cam1"))
    out, cv = tmp_path / "cam.yml", tmp_path / "opencv.yml"
    argv = ["calibrate", "import", str(chain), "--camera", "cam1", "--mount", "down",
            "-o", str(out), "--export-opencv", str(cv)]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "kalibr camera cam1 of cam0, cam1" in text and "kb4: fx=190.97" in text
    cam = read_camera_file(out)
    assert cam.lens == KB4 and cam.image_size == (512, 512)
    assert np.array_equal(cam.mount, MOUNTS["down"])
    assert import_calibration(cv).lens == KB4
    # omnidev unwarp reads the written file (the kind picks the fisheye unwarper)
    img = tmp_path / "fish.png"
    cv2.imwrite(str(img), np.random.default_rng(0).integers(0, 255, (512, 512), np.uint8))
    view = tmp_path / "persp.png"
    argv = ["unwarp", str(img), "--camera", str(out), "--view", "perspective:160x120,fov=90,"
            "tilt=-90", "-o", str(view)]  # fmt: skip
    assert main(argv) == 0
    got = cv2.imread(str(view))
    assert got.shape == (120, 160, 3) and got.std() > 20  # filled with the noise image


def test_import_then_opencv_export_refused_for_ds(tmp_path, capsys):
    chain = tmp_path / "camchain.yaml"
    chain.write_text(kalibr_text(DS, (512, 512)))
    out = tmp_path / "cam.yml"
    argv = ["calibrate", "import", str(chain), "-o", str(out), "--export-opencv",
            str(tmp_path / "cv.yml")]  # fmt: skip
    assert "OpenCV has no 'ds' lens" in _one_line_error(capsys, argv)
    assert not out.exists()  # nothing written


def test_import_errors(tmp_path, capsys):
    out = str(tmp_path / "cam.yml")
    missing = tmp_path / "missing.txt"
    assert f"{missing}: calibration file not found" in _one_line_error(
        capsys, ["calibrate", "import", str(missing), "-o", out]
    )
    partial = tmp_path / "calib_results.txt"
    partial.write_text("#\n3 -100 0 0.001\n0\n200 300\n")
    err = _one_line_error(capsys, ["calibrate", "import", str(partial), "-o", out])
    assert str(partial) in err and "affine c d e" in err
    chain = tmp_path / "camchain.yaml"
    chain.write_text("cam0:\n  camera_model: fov\n  intrinsics: [0.9]\n")
    err = _one_line_error(capsys, ["calibrate", "import", str(chain), "-o", out])
    assert str(chain) in err and "cam0.camera_model 'fov'" in err
    nosize = tmp_path / "k.yml"
    fs = cv2.FileStorage(str(nosize), cv2.FILE_STORAGE_WRITE)
    fs.write("K", np.array([[300.0, 0, 320], [0, 300, 240], [0, 0, 1]]))
    fs.write("D", np.zeros((4, 1)))
    fs.release()
    err = _one_line_error(capsys, ["calibrate", "import", str(nosize), "-o", out])
    assert "no image size in the file; give --image-size WxH" in err
    assert main(["calibrate", "import", str(nosize), "--image-size", "640x480", "-o", out]) == 0
    assert read_camera_file(tmp_path / "cam.yml").image_size == (640, 480)
    assert "exists; pass --force" in _one_line_error(
        capsys, ["calibrate", "import", str(nosize), "--image-size", "640x480", "-o", out]
    )
    ocam = tmp_path / "ocam.txt"
    lens = Scaramuzza(ss=(-100.0, 0.0, 0.001), xc=240.0, yc=320.0)
    ocam.write_text(ocamcalib_text(lens, (640, 480)))
    err = _one_line_error(
        capsys, ["calibrate", "import", str(ocam), "--image-size", "800x600", "-o", out, "--force"]
    )
    assert "the file says 640x480 px" in err
    assert "--max-angle-deg" in _one_line_error(
        capsys, ["calibrate", "import", str(ocam), "--max-angle-deg", "200", "-o", out, "--force"]
    )
    huge = tmp_path / "huge.txt"  # finite, but 3 * 1e308 overflows (fuzz seed 13)
    text = ocamcalib_text(lens, (640, 480))
    assert "\n3 -100.0 0.0 0.001\n" in text
    huge.write_text(text.replace("\n3 -100.0 0.0 0.001\n", "\n4 -100.0 0.0 0.001 1e308\n"))
    err = _one_line_error(capsys, ["calibrate", "import", str(huge), "-o", out, "--force"])
    assert f"{huge}: scaramuzza ss[3] = 1e+308 is too large" in err


realdata = pytest.mark.skipif(
    not REALDATA.is_dir(), reason=f"{REALDATA} absent (shared/realdata not mounted)"
)


@realdata
@pytest.mark.parametrize(
    ("calib", "image", "mount", "view"),
    [
        ("ocamcalib_matsuren_fisheye1600/calib_results_0.txt",
         "ocamcalib_matsuren_fisheye1600/img0.jpg", "forward", "perspective:320x240,fov=100"),
        ("tumvi_fisheye/calib/tumvi_512_kb4_official.yaml", "tumvi_fisheye/images/cam0.png",
         "up", "perspective:200x200,fov=100,tilt=90"),
        ("tumvi_fisheye/calib/camera-intrinsic-model_fov_tum_mono.json",
         "tumvi_fisheye/images/fov_tum_mono.png", "forward", "perspective:320x240,fov=100"),
    ],
)  # fmt: skip
def test_real_calibration_imports_and_unwarps(tmp_path, capsys, calib, image, mount, view):
    out = tmp_path / "cam.yml"
    argv = ["calibrate", "import", str(REALDATA / calib), "--mount", mount, "-o", str(out)]
    assert main(argv) == 0
    png = tmp_path / "view.png"
    assert main(["unwarp", str(REALDATA / image), "--camera", str(out), "--view", view,
                 "-o", str(png)]) == 0  # fmt: skip
    got = cv2.imread(str(png))
    w, h = (int(x) for x in view.split(":")[1].split(",")[0].split("x"))
    assert got.shape == (h, w, 3)
    assert got.mean() > 20 and got.std() > 10  # a real picture, not the invalid fill


@realdata
def test_pyocamcalib_json_is_detected_and_needs_the_image_size(tmp_path, capsys):
    calib = REALDATA / "ocamcalib_urban_samples/Fisheye1/py-OCamCalib_calibration_fisheye_1.json"
    out = tmp_path / "cam.yml"
    err = _one_line_error(capsys, ["calibrate", "import", str(calib), "-o", str(out)])
    assert "no image size in the file; give --image-size" in err
    argv = ["calibrate", "import", str(calib), "--image-size", "1032x778", "--mount", "forward",
            "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    assert "scaramuzza: ss=[-338.83" in capsys.readouterr().out
    cam = read_camera_file(out)
    assert isinstance(cam.lens, Scaramuzza) and cam.image_size == (1032, 778)
    png = tmp_path / "view.png"
    image = REALDATA / "ocamcalib_urban_samples/Fisheye1/images/Fisheye1_1.jpg"
    assert main(["unwarp", str(image), "--camera", str(out), "--view",
                 "perspective:320x240,fov=100", "-o", str(png)]) == 0  # fmt: skip
    got = cv2.imread(str(png))
    assert got.shape == (240, 320, 3) and got.mean() > 20 and got.std() > 10

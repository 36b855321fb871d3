"""End to end on the committed fixture: calibrate from its landmarks, unwarp its video."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from omnidev import build_maps, load_camera
from omnidev.cli.main import main
from omnidev.viewspec import parse_view
from tests.conftest import REPO, psnr

FIXTURE = REPO / "fixtures" / "omni_room"
TRUTH = json.loads((FIXTURE / "truth.json").read_text())


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    out = tmp_path_factory.mktemp("cal") / "camera.yml.gz"
    mc = ",".join(str(x) for x in TRUTH["mirror_center_world"])
    assert (
        main(
            [
                "calibrate",
                "pano-table",
                str(FIXTURE / "landmarks.csv"),
                "--mirror-center",
                mc,
                "--image",
                str(FIXTURE / "omni_0000.png"),
                "--image-center",
                "detect",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    return out


def pano_spec() -> str:
    v = TRUTH["views"]["panorama"]
    lo, hi = v["elevation_deg"]
    return f"panorama:{v['width']}x{v['height']},elev={lo}:{hi}"


def test_image_unwarp_matches_truth(table, tmp_path):
    out = tmp_path / "pano.png"
    assert (
        main(
            [
                "unwarp",
                str(FIXTURE / "omni_0000.png"),
                "--camera",
                str(table),
                "--view",
                pano_spec(),
                "-o",
                str(out),
            ]
        )
        == 0
    )
    pano = cv2.imread(str(out))
    truth = cv2.imread(str(FIXTURE / "truth_panorama.png"))
    inner = np.zeros(pano.shape[:2], bool)
    inner[3:-3] = True  # rows at the mirror's rim and cut-off blend in the dark surround
    value = psnr(pano, truth, inner)
    assert value >= 33.0, value


def test_video_unwarp_two_views_and_rig(table, tmp_path, capsys):
    p = TRUTH["views"]["perspective"]
    plane = (
        f"plane:{p['width']}x{p['height']},d={p['distance']},w={p['plane_width']},"
        f"z={p['z_bottom']}:{p['z_top']},az={p['azimuth_deg']}"
    )
    rig = tmp_path / "rig.toml"
    rig.write_text(f'[camera]\nsource = "video:{FIXTURE / "omni.avi"}"\ncalibration = "{table}"\n')
    pano, persp = tmp_path / "pano.avi", tmp_path / "persp.avi"
    assert (
        main(
            [
                "unwarp",
                "--rig",
                str(rig),
                "--view",
                pano_spec(),
                "-o",
                str(pano),
                "--view",
                plane,
                "-o",
                str(persp),
            ]
        )
        == 0
    )
    assert f"wrote {pano} ({TRUTH['frames']} frames)" in capsys.readouterr().out
    for path, truth_png, (w, h) in [
        (
            pano,
            "truth_panorama.png",
            (TRUTH["views"]["panorama"]["width"], TRUTH["views"]["panorama"]["height"]),
        ),
        (persp, "truth_perspective.png", (p["width"], p["height"])),
    ]:
        cap = cv2.VideoCapture(str(path))
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == TRUTH["frames"]
        ok, first = cap.read()
        cap.release()
        assert ok and first.shape == (h, w, 3)
        truth = cv2.imread(str(FIXTURE / truth_png))
        view = parse_view(pano_spec() if path == pano else plane)
        seen = build_maps(load_camera(table), view).valid.astype(np.uint8)
        inner = cv2.erode(seen, np.ones((7, 7), np.uint8)) > 0  # away from the disc's edges
        assert psnr(first, truth, inner) >= 28.0  # two MJPG generations + sensor noise
    # --frames limits, --force is needed to overwrite
    assert (
        main(
            [
                "unwarp",
                str(FIXTURE / "omni.avi"),
                "--camera",
                str(table),
                "--view",
                "panorama:256x64",
                "-o",
                str(pano),
                "--frames",
                "5",
            ]
        )
        == 2
    )
    assert (
        main(
            [
                "unwarp",
                str(FIXTURE / "omni.avi"),
                "--camera",
                str(table),
                "--view",
                "panorama:256x64",
                "-o",
                str(pano),
                "--frames",
                "5",
                "--force",
            ]
        )
        == 0
    )
    cap = cv2.VideoCapture(str(pano))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 5


def test_nearest_lookup_is_selectable_and_worse(table, tmp_path):
    outs = {}
    for lookup in ("bilinear", "nearest"):
        out = tmp_path / f"{lookup}.png"
        assert (
            main(
                [
                    "unwarp",
                    str(FIXTURE / "omni_0000.png"),
                    "--camera",
                    str(table),
                    "--camera-option",
                    f"lookup={lookup}",
                    "--view",
                    pano_spec(),
                    "-o",
                    str(out),
                ]
            )
            == 0
        )
        outs[lookup] = cv2.imread(str(out))
    truth = cv2.imread(str(FIXTURE / "truth_panorama.png"))
    inner = np.zeros(truth.shape[:2], bool)
    inner[3:-3] = True
    assert psnr(outs["bilinear"], truth, inner) > psnr(outs["nearest"], truth, inner) + 3.0

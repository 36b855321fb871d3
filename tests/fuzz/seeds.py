"""Valid inputs of every kind omnidev reads, made once per test session: the fuzz suite's seeds.

Each seed is a real file a command accepts as it is (the suite checks that
first); the malformed variants are made from them (tests/fuzz/mutate.py).
Seeds come from the committed fixtures and from omnidev's own writers, so a
format change shows up here as a seed that no longer loads.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from tests.fuzz.harness import REPO

FIXTURES = REPO / "fixtures"


@dataclass(frozen=True)
class Seeds:
    """Paths of the seed files (all in one world-readable folder)."""

    root: Path

    def __getitem__(self, name: str) -> Path:
        return self.root / name

    def text(self, name: str) -> bytes:
        return (self.root / name).read_bytes()


def _pano_table(root: Path) -> None:
    from omnidev.cli.main import main

    truth = json.loads((FIXTURES / "omni_room" / "truth.json").read_text())
    center = ",".join(str(v) for v in truth["mirror_center_world"])
    for name in ("cam.yml", "cam.yml.gz"):
        argv = [
            "calibrate", "pano-table", str(FIXTURES / "omni_room" / "landmarks.csv"),
            "--mirror-center", center, "--image-center", "322.9,317.4", "--image-size", "640x640",
            "--table-size", "48x24", "-o", str(root / name), "--plot", str(root / "fit.png"),
            "--force",
        ]  # fmt: skip
        assert main(argv) == 0
    # the same exact landmarks of an SVP mirror keep the unified radial term (radial_base)
    argv = [
        "calibrate", "pano-table", str(FIXTURES / "omni_room" / "landmarks.csv"),
        "--mirror-center", center, "--image-center", "322.9,317.4", "--image-size", "640x640",
        "--model", "general", "--table-size", "48x24", "-o", str(root / "cam_unified.yml"),
        "--force",
    ]  # fmt: skip
    assert main(argv) == 0


def _pano_table_more(root: Path) -> None:
    """A format-1 table file (stored table) and a generalized table from board landmarks."""
    from omnidev.cli.main import main
    from omnidev.panotable.camfile import load_table, save_table

    save_table(root / "cam_v1.yml", load_table(root / "cam.yml"), store_table=True, force=True)
    text = (root / "cam_v1.yml").read_text().replace("format_version: 2", "format_version: 1")
    (root / "cam_v1.yml").write_text(text)
    argv = ["calibrate", "pano-table", str(root / "boards.csv"), "--mirror-center",
            "0.3,-0.2,1.2", "--image-center", "320,320", "--image-size", "640x640",
            "--model", "general", "--table-size", "48x24", "-o", str(root / "cam_general.yml"),
            "--force"]  # fmt: skip
    assert main(argv) == 0


def _boards(root: Path) -> None:
    """Two small ChArUco boards near a rendered mirror camera: shot.png, boards.toml and the
    landmark CSV (with groups) that ``omnidev landmarks board`` makes of them."""
    from omnidev.cli.main import main
    from omnidev.sim import RoomScene, SvpHyperbolicCamera, render_omni
    from omnidev.sim.boards import BoardScene, boards_around

    room = RoomScene(301)
    boards = boards_around(room, 2, seed=301, distance=0.6, pattern="charuco:5x4,80,60,DICT_4X4_50")
    cam = SvpHyperbolicCamera.default(640)
    img = render_omni(cam, BoardScene(room, boards), supersample=1, noise_sigma=2.0, seed=1)
    cv2.imwrite(str(root / "shot.png"), img)
    rig = []
    for b in boards:
        w, h = b.pattern.size_mm()
        o, x, y = b.origin, b.world(np.array([[w, 0.0]]))[0], b.world(np.array([[0.0, h]]))[0]
        rig += ["[[board]]", f'pattern = "{b.pattern.describe()}"',
                f"first_marker = {b.first_marker}",
                f"origin = [{o[0]:.6f}, {o[1]:.6f}, {o[2]:.6f}]",
                f"x_end = [{x[0]:.6f}, {x[1]:.6f}, {x[2]:.6f}]",
                f"y_end = [{y[0]:.6f}, {y[1]:.6f}, {y[2]:.6f}]"]  # fmt: skip
    (root / "boards.toml").write_text("\n".join(rig) + "\n")
    argv = ["landmarks", "board", str(root / "shot.png"), "--boards", str(root / "boards.toml"),
            "-o", str(root / "boards.csv"), "--force"]  # fmt: skip
    assert main(argv) == 0


def _fisheye(root: Path) -> None:
    from omnidev.fisheye.formats import basalt_text, kalibr_text, ocamcalib_text
    from omnidev.fisheye.models import KannalaBrandt, Scaramuzza

    kb4 = KannalaBrandt(fx=190.97, fy=190.93, cx=254.93, cy=256.89, k=(0.0035, 7e-4, -2e-3, 2e-4))
    ocam = Scaramuzza(
        ss=(-337.4374, 0.0, 0.001232446, -1.355883e-06, 2.914654e-09),
        xc=378.875612, yc=541.097113, c=0.998971, d=-0.000104, e=-0.000312,
        invpol=(509.74394, 292.31636, -13.734732, 41.371323, 24.066967, -7.800231),
    )  # fmt: skip
    (root / "kalibr.yaml").write_text(kalibr_text(kb4, (512, 512)))
    (root / "calib_results.txt").write_text(ocamcalib_text(ocam, (1080, 760)))
    (root / "basalt.json").write_text(basalt_text([kb4], [(512, 512)]))
    pyocam = {
        "taylor_coefficient": [337.7168, 0.0, -0.00122383, 1.3804e-06, -3.0106e-09],
        "distortion_center": [543.986, 377.649],
        "stretch_matrix": [[1.0033, 0.0123], [-0.0104, 1.0]],
        "rms_overall": 0.24,
    }
    (root / "pyocam.json").write_text(json.dumps(pyocam))
    from omnidev.cli.main import main

    argv = ["calibrate", "import", str(root / "kalibr.yaml"), "--mount", "forward",
            "-o", str(root / "fish.yml"), "--export-opencv", str(root / "opencv.yml"),
            "--force"]  # fmt: skip
    assert main(argv) == 0


def _nonsvp(root: Path) -> None:
    from omnidev.nonsvp.camfile import write_camera_file
    from omnidev.nonsvp.model import DISSERTATION_CAMERA
    from omnidev.nonsvp.ring_pattern import RingLayout
    from omnidev.nonsvp.ringcal import project_plane_points

    cam = DISSERTATION_CAMERA
    write_camera_file(root / "nonsvp.yml", cam, force=True)
    plane = RingLayout(cam.mirror.m).calibration_points_mm()
    uv = project_plane_points(cam.lens, cam.pose, plane)
    lines = ["u,v,X,Y"] + [
        f"{u:.4f},{v:.4f},{x:.4f},{y:.4f}" for (u, v), (x, y, _) in zip(uv, plane, strict=True)
    ]
    (root / "points.csv").write_text("\n".join(lines) + "\n")


def _screen(root: Path) -> None:
    from omnidev.cli.main import main

    fx = FIXTURES / "screen" / "k1+0.10-640x480"
    for name in ("white", "black", "dots"):
        shutil.copy(fx / f"{name}.png", root / f"{name}.png")
    argv = ["calibrate", "screen", "--white", str(fx / "white.png"), "--black",
            str(fx / "black.png"), "--dots", str(fx / "dots.png"), "-o", str(root / "screen.yml"),
            "--force"]  # fmt: skip
    assert main(argv) == 0
    _clip(fx / "laser.avi", root / "laser.avi", 3)


def _clip(src: Path, dst: Path, frames: int) -> None:
    cap = cv2.VideoCapture(str(src))
    out = None
    for _ in range(frames):
        ok, img = cap.read()
        assert ok
        if out is None:
            h, w = img.shape[:2]
            out = cv2.VideoWriter(str(dst), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (w, h))
        out.write(img)
    assert out is not None
    out.release()
    cap.release()


def _daemon(root: Path) -> None:
    (root / "daemon.toml").write_text(
        f"""[source]
uri = "video:{root / "blob.avi"}"

[tracker]
name = "bright-blob"
[tracker.options]
threshold = 200
min_area = 12

[filter]
kind = "one-euro"
min_cutoff = 0.1
beta = 20.0
d_cutoff = 2.0

[sink]
name = "record"
[sink.options]
path = "pointer.jsonl"

[buttons]
dwell = false
dwell_s = 0.8
dwell_radius_px = 12.0
dwell_button = "left"
release_when_lost = true

[screen]
rect = "1920x1080+0+0"
layout = "1920x1080"

[daemon]
socket = "control.sock"
queue = 1
retry_initial_s = 0.5
retry_max_s = 10.0
"""
    )
    _clip(FIXTURES / "blob" / "blob.avi", root / "blob.avi", 3)
    # video streams only (issue 16): a fixed view, a steered one and one that follows the
    # panorama by auto-framing; outputs are raw files in the case's folder
    (root / "streams.toml").write_text(
        f"""[[stream]]
name = "room"
source = "video:{root / "blob.avi"}"
camera = "{root / "fish.yml"}"
interpolation = "linear"
fps = 15.0
queue = 2

[[stream.view]]
name = "pano"
view = "panorama:180x40,elev=-40:40"
output = "raw:pano.raw"

[[stream.view]]
name = "ptz"
view = "perspective:64x48,fov=60"
output = ["raw:ptz.raw"]
max_deg_s = 90.0
follow = "pano"
follow_method = "mog2"

[daemon]
socket = "control.sock"
"""
    )


def _replay(root: Path) -> None:
    lines = [
        {"t_ns": 1000, "kind": "open", "screen": [0, 0, 1920, 1080], "layout": [1920, 1080]},
        {"t_ns": 2000, "kind": "move", "x": 0.25, "y": 0.5, "pixel": [480, 540]},
        {"t_ns": 3000, "kind": "button", "button": "left", "down": True},
        {"t_ns": 4000, "kind": "move", "x": 0.75, "y": 0.25, "pixel": [1440, 270]},
        {"t_ns": 5000, "kind": "button", "button": "left", "down": False},
        {"t_ns": 6000, "kind": "close"},
    ]
    (root / "rec.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))


def _mouse(root: Path) -> None:
    fx = FIXTURES / "mouse" / "sweep-320x240"
    shutil.copy(fx / "landmarks.json", root / "layout.json")
    layout = json.loads((fx / "landmarks.json").read_text())
    toml = []
    scalars = {k: v for k, v in layout.items() if not isinstance(v, dict | list)}
    toml += [f"{k} = {json.dumps(v)}" for k, v in scalars.items()]
    for k, v in layout.items():
        if isinstance(v, list):
            toml.append(f"{k} = {json.dumps(v)}")
    for k, v in layout.items():
        if isinstance(v, dict):
            toml.append(f"[{k}]")
            toml += [f"{kk} = {json.dumps(vv)}" for kk, vv in v.items()]
    (root / "layout.toml").write_text("\n".join(toml) + "\n")
    _clip(fx / "mouse.avi", root / "mouse.avi", 3)


def _images(root: Path) -> None:
    img = cv2.imread(str(FIXTURES / "omni_room" / "omni_0000.png"))
    cv2.imwrite(str(root / "omni.png"), img)
    cv2.imwrite(str(root / "omni.jpg"), img)
    _clip(FIXTURES / "omni_room" / "omni.avi", root / "omni.avi", 3)
    shutil.copy(FIXTURES / "omni_room" / "landmarks.csv", root / "landmarks.csv")
    (root / "rig.toml").write_text(
        '[camera]\nname = "room"\nsource = "omni.png"\ncalibration = "cam.yml.gz"\n'
    )
    fish = np.random.default_rng(0).integers(0, 255, (512, 512, 3), np.uint8)
    cv2.imwrite(str(root / "fish.png"), fish)
    shutil.copy(FIXTURES / "nonsvp" / "dissertation-textured-640x480" / "omni.png",
                root / "nonsvp.png")  # fmt: skip
    # chessboard views for calibrate fisheye (board.png is the first, the one mutated)
    from omnidev.cli.main import main

    argv = ["sim", "chessboard", str(root / "cb"), "--views", "6", "--pattern",
            "chessboard:7x5,40", "--size", "480x360", "--force"]  # fmt: skip
    assert main(argv) == 0
    shutil.copy(root / "cb" / "view00.png", root / "board.png")


def make_seeds(root: Path) -> Seeds:
    """Write every seed into ``root`` (made world-readable for the unprivileged cases)."""
    root.mkdir(parents=True, exist_ok=True)
    makers = (_pano_table, _boards, _pano_table_more, _fisheye, _nonsvp, _screen, _daemon,
              _replay, _mouse, _images)  # fmt: skip
    for make in makers:
        make(root)
    for p in [root, *root.rglob("*")]:
        p.chmod(0o755 if p.is_dir() else 0o644)
    return Seeds(root)

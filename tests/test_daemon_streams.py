"""The daemon's ``[[stream]]`` sections and virtual PTZ (issue 16, deliverables 2 and 3).

A rendered fisheye clip (tests/test_cli_unwarp_video.py: each frame turned a further
15 degrees, so every frame differs) runs through a streams-only daemon, in this
process, into raw and Y4M files; each output frame is checked against the same
frame unwarped offline: exactly (raw BGR, the same cv2 decoding and fixed-point
maps) or by PSNR against ``omnidev unwarp`` itself (Y4M, 4:2:0 on both sides).
PTZ moves are sent through the control socket as ``omnidev ctl view`` sends them.
"""

from __future__ import annotations

import hashlib
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

import omnidev
from omnidev.camera import Remapper
from omnidev.cli.main import main as cli_main
from omnidev.daemon.config import load_config
from omnidev.daemon.control import request
from omnidev.daemon.main import Daemon
from omnidev.daemon.main import main as daemon_main
from omnidev.viewspec import parse_view
from tests.conftest import psnr
from tests.test_cli_unwarp_video import fisheye_clip, read_video

PTZ_W, PTZ_H = 96, 72


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    return fisheye_clip(tmp_path_factory.mktemp("clip"))


@pytest.fixture(scope="module")
def source_frames(clip):
    cap = cv2.VideoCapture(str(clip[0]))
    frames = []
    while True:
        ok, image = cap.read()
        if not ok:
            return frames
        frames.append(image)


def write_config(tmp: Path, body: str) -> Path:
    path = tmp / "omnidev.toml"
    path.write_text(
        body
        + f"""
[daemon]
socket = "{tmp / "control.sock"}"
retry_initial_s = 0.1
retry_max_s = 0.2
"""
    )
    return path


def stream_toml(source: str, cam: Path, views: list[tuple[str, str, str, str]]) -> str:
    text = f'[[stream]]\nname = "s"\nsource = "{source}"\ncamera = "{cam}"\n'
    for name, view, out, extra in views:
        text += f'[[stream.view]]\nname = "{name}"\nview = "{view}"\noutput = "{out}"\n{extra}\n'
    return text


class Running:
    """A daemon running on a thread of this process; stopped (outputs committed) on exit."""

    def __init__(self, config: Path) -> None:
        self.daemon = Daemon(config)
        self.status_code: int | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        self.status_code = self.daemon.run()

    def __enter__(self) -> Running:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.daemon.stopping.set()
        self.thread.join(10)

    def wait(self, predicate, timeout: float = 20.0) -> None:  # type: ignore[no-untyped-def]
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate(self.daemon.status()):
                return
            time.sleep(0.01)
        raise AssertionError(f"timed out; status {self.daemon.status()}")


def read_raw(path: Path, w: int, h: int) -> np.ndarray:
    data = np.fromfile(path, np.uint8)
    assert data.size % (w * h * 3) == 0
    return data.reshape(-1, h, w, 3)


def renders(camera, frames, view: str) -> list[np.ndarray]:
    remap = Remapper(omnidev.build_maps(camera, parse_view(view)))
    return [remap(f) for f in frames]


def test_stream_of_a_file_matches_offline_unwarp(clip, source_frames, tmp_path):
    video, cam = clip
    views = [
        ("pano", "equirect:256x128,tilt=90", f"raw:{tmp_path / 'pano.raw'}", ""),
        ("flat", "perspective:160x120,fov=90,tilt=45", f"y4m:{tmp_path / 'flat.y4m'}", ""),
    ]
    config = write_config(tmp_path, stream_toml(str(video), cam, views))
    with Running(config) as run:
        run.thread.join(30)  # a recorded source ends: the daemon exits by itself
    assert run.status_code == 0
    st = run.daemon.streams[0].status()
    assert st["state"] == "ended" and st["frames"] == st["written"] == len(source_frames) == 24
    assert st["dropped_frames"] == 0
    camera = omnidev.load_camera(cam)
    pano = read_raw(tmp_path / "pano.raw", 256, 128)
    truth = renders(camera, source_frames, "equirect:256x128,tilt=90")
    assert len(pano) == 24
    assert all(np.array_equal(a, b) for a, b in zip(pano, truth, strict=True))
    # the Y4M output against `omnidev unwarp` itself writing Y4M, on the BGR route the
    # stream takes (a URI with options is decoded by cv2; a bare file path would take
    # the 4:2:0 route, which agrees with BGR only to ~36 dB: test_cli_unwarp_video.py)
    offline = tmp_path / "offline.y4m"
    code = cli_main(
        ["unwarp", f"video:{video}?loop=0", "--camera", str(cam),
         "--view", "perspective:160x120,fov=90,tilt=45", "-o", f"y4m:{offline}"]
    )  # fmt: skip
    assert code == 0
    got, want = read_video(tmp_path / "flat.y4m"), read_video(offline)
    assert len(got) == len(want) == 24
    worst = min(psnr(a, b) for a, b in zip(got, want, strict=True))
    assert worst >= 40.0, worst


def _old_pose_hashes(camera, frames, view: str) -> set[bytes]:
    return {hashlib.sha1(r.tobytes()).digest() for r in renders(camera, frames, view)}


def test_ctl_view_move_is_visible_within_two_frames_and_smooth(clip, source_frames, tmp_path):
    video, cam = clip
    view = f"perspective:{PTZ_W}x{PTZ_H},fov=60,tilt=40"
    out = tmp_path / "ptz.raw"
    config = write_config(
        tmp_path,
        stream_toml(
            f"video:{video}?rate=30&loop=1", cam, [("ptz", view, f"raw:{out}", "max_deg_s = 60")]
        ),
    )
    camera = omnidev.load_camera(cam)
    old = _old_pose_hashes(camera, source_frames, view)
    new = _old_pose_hashes(
        camera, source_frames, f"perspective:{PTZ_W}x{PTZ_H},fov=60,pan=40,tilt=40"
    )
    sock = tmp_path / "control.sock"
    with Running(config) as run:
        run.wait(lambda s: s["streams"][0]["written"] >= 6)
        reply = request(sock, "view", view="ptz", moves=["pan=+40"])
        assert reply["ok"] and reply["target"]["pan"] == 40.0
        n = reply["written"]
        run.wait(lambda s: s["streams"][0]["views"][0]["pose"]["pan"] == 40.0)
        done = run.daemon.streams[0].status()["written"]
        run.wait(lambda s: s["streams"][0]["written"] >= done + 5)
        status = request(sock, "status")
    frames = read_raw(out, PTZ_W, PTZ_H)
    hashes = [hashlib.sha1(f.tobytes()).digest() for f in frames]
    assert all(h in old for h in hashes[:n])
    first_new = next(i for i in range(n, len(hashes)) if hashes[i] not in old)
    assert first_new <= n + 1, (n, first_new)  # the frame in flight, then the next one moves
    first_final = next(i for i in range(first_new, len(hashes)) if hashes[i] in new)
    # 40 degrees at 60 deg/s take 0.67 s, 20 frames at 30 fps: a smooth move, not a jump
    assert first_final - first_new >= 12, (first_new, first_final)
    assert all(h in new for h in hashes[first_final:])
    v = status["streams"][0]["views"][0]
    assert v["target"] == {"pan": 40.0, "tilt": 40.0, "fov": 60.0}
    assert v["rebuilds"] >= 12
    st = status["streams"][0]
    assert st["latency_p50_ms"] is not None and st["latency_p99_ms"] >= st["latency_p50_ms"]


def test_sweep_of_100_moves_never_mixes_old_and_new_maps(clip, source_frames, tmp_path):
    video, cam = clip
    base = f"perspective:{PTZ_W}x{PTZ_H},fov=60,tilt=40"
    out = tmp_path / "sweep.raw"
    config = write_config(
        tmp_path,
        stream_toml(
            f"video:{video}?rate=120&loop=1", cam, [("ptz", base, f"raw:{out}", "max_deg_s = 0")]
        ),
    )
    rng = np.random.default_rng(16)
    pans = [0.0, *np.round(rng.uniform(-180, 180, 100), 1).tolist()]
    tilts = [40.0, *np.round(rng.uniform(0, 60, 100), 1).tolist()]
    camera = omnidev.load_camera(cam)
    table: dict[bytes, tuple[int, int]] = {}
    for j, (pan, tilt) in enumerate(zip(pans, tilts, strict=True)):
        view = f"perspective:{PTZ_W}x{PTZ_H},fov=60,pan={pan},tilt={tilt}"
        for i, r in enumerate(renders(camera, source_frames, view)):
            table[hashlib.sha1(r.tobytes()).digest()] = (j, i)
    assert len(table) == 101 * 24  # every pose of every frame gives its own picture
    sock = tmp_path / "control.sock"
    with Running(config) as run:
        run.wait(lambda s: s["streams"][0]["written"] >= 3)
        for pan, tilt in zip(pans[1:], tilts[1:], strict=True):
            reply = request(sock, "view", view="ptz", moves=[f"pan=={pan}", f"tilt={tilt}"])
            assert reply["ok"]
            time.sleep(float(rng.uniform(0.002, 0.03)))
        run.wait(lambda s: s["streams"][0]["views"][0]["pose"]["pan"] == pans[-1])
        done = run.daemon.streams[0].status()["written"]
        run.wait(lambda s: s["streams"][0]["written"] >= done + 3)
    frames = read_raw(out, PTZ_W, PTZ_H)
    poses = []
    for k, f in enumerate(frames):
        hit = table.get(hashlib.sha1(f.tobytes()).digest())
        assert hit is not None, f"output frame {k} is no pose's unwarp of any frame (mixed maps?)"
        poses.append(hit[0])
    assert poses == sorted(poses)  # the moves are shown in the order they were sent
    assert poses[0] == 0 and poses[-1] == 100
    assert len(set(poses)) >= 50, len(set(poses))  # most moves were on screen


def test_streams_only_config_loads_and_checks(clip, tmp_path, capsys):
    video, cam = clip
    views = [("p", "perspective:64x48", f"raw:{tmp_path / 'p.raw'}", "max_deg_s = 30")]
    config = write_config(tmp_path, stream_toml(str(video), cam, views))
    c = load_config(config)
    assert not c.pointer and len(c.streams) == 1 and c.streams[0].views[0].max_deg_s == 30.0
    assert daemon_main(["--config", str(config), "--check"]) == 0
    out = capsys.readouterr().out
    assert "stream 's': view p 64x48 -> raw:" in out and "opened and aborted" in out
    assert not (tmp_path / "p.raw").exists()  # the check leaves no output behind


@pytest.mark.parametrize(
    ("view", "out", "extra", "message"),
    [
        ("perspective:64x48", "bogus:/x", "", "output: bogus:/x: no plugin for output scheme"),
        ("fisheye-ish:64x48", "raw:OUT", "", "view: "),
        ("panorama:64x16", "raw:OUT", "max_deg_s = 10", "only a perspective view is steerable"),
        ("perspective:64x48", "raw:OUT", "max_deg_s = -1", "max_deg_s: must be 0 (jump)"),
        ("perspective:64x48", "raw:OUT", "colour = 1", "unknown key"),
        ("perspective:64x48", "raw:OUT", 'follow = "pano"', "follow: no view 'pano'"),
        ("perspective:64x48", "raw:OUT", 'follow = "v"', "must be a panorama with an elevation"),
        ("panorama:64x16", "raw:OUT", 'follow = "v"', "follow: only a perspective view"),
        ("perspective:64x48", "raw:OUT", 'follow_method = "knn"', "given without follow"),
        ("perspective:64x48", "raw:OUT", 'follow = "v"\nfollow_method = "x"', "mog2, knn"),
    ],
)
def test_check_names_the_bad_stream_key_in_one_line(
    clip, tmp_path, capsys, view, out, extra, message
):
    video, cam = clip
    out = out.replace("OUT", str(tmp_path / "o.raw"))
    config = write_config(tmp_path, stream_toml(str(video), cam, [("v", view, out, extra)]))
    assert daemon_main(["--config", str(config), "--check"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and str(config) in err, err


def test_unknown_camera_and_duplicate_view_names(clip, tmp_path, capsys):
    video, cam = clip
    config = write_config(
        tmp_path,
        stream_toml(str(video), tmp_path / "none.yml", [("v", "perspective:64x48", "raw:-", "")]),
    )
    assert daemon_main(["--config", str(config), "--check"]) == 2
    assert f"camera: {tmp_path / 'none.yml'}: camera file not found" in capsys.readouterr().err
    folder = stream_toml(str(video), tmp_path, [("v", "perspective:64x48", "raw:-", "")])
    assert daemon_main(["--config", str(write_config(tmp_path, folder)), "--check"]) == 2
    assert f"camera: {tmp_path}: is a folder, not a camera file" in capsys.readouterr().err
    twice = stream_toml(str(video), cam, [("v", "perspective:64x48", "raw:-", "")])
    config = write_config(tmp_path, twice + twice.replace('name = "s"', 'name = "t"'))
    assert daemon_main(["--config", str(config), "--check"]) == 2
    assert "view 'v' given twice" in capsys.readouterr().err


def test_a_missing_camera_is_retried_not_fatal(clip, tmp_path):
    _, cam = clip
    config = write_config(
        tmp_path,
        stream_toml("v4l2:/dev/video-absent-h44", cam, [("v", "perspective:64x48", "raw:-", "")]),
    )
    with Running(config) as run:
        run.wait(lambda s: s["streams"][0]["camera_retries"] >= 3)
        st = run.daemon.status()["streams"][0]
        assert st["state"] == "waiting for camera" and run.thread.is_alive()


def test_ctl_view_refuses_unknown_views_and_bad_moves(clip, tmp_path, capsys):
    video, cam = clip
    config = write_config(
        tmp_path,
        stream_toml(
            f"video:{video}?rate=30&loop=1", cam,
            [("ptz", "perspective:64x48", "raw:" + str(tmp_path / "a.raw"), ""),
             ("pano", "panorama:64x16", "raw:" + str(tmp_path / "b.raw"), "")],
        ),
    )  # fmt: skip
    sock = str(tmp_path / "control.sock")
    with Running(config) as run:
        run.wait(lambda s: s["streams"][0]["written"] >= 1)
        assert cli_main(["ctl", "view", "nope", "pan=1", "--socket", sock]) == 2
        assert "no view 'nope' (views: ptz, pano)" in capsys.readouterr().err
        assert cli_main(["ctl", "view", "pano", "pan=1", "--socket", sock]) == 2
        assert "not a perspective view" in capsys.readouterr().err
        assert cli_main(["ctl", "view", "ptz", "zoom=2", "--socket", sock]) == 2
        assert "unknown axis 'zoom'" in capsys.readouterr().err
        assert cli_main(["ctl", "view", "ptz", "fov=-10", "tilt=5", "--socket", sock]) == 0
        assert "pan 0.00, tilt 5.00, fov 80.00" in capsys.readouterr().out
        assert cli_main(["ctl", "status", "--socket", sock]) == 0
        text = capsys.readouterr().out
        assert "stream s:" in text and "(capture -> output)" in text and "view ptz:" in text
        assert "pointer:         none (streams only)" in text


def test_an_output_that_cannot_open_stops_the_daemon_for_a_restart(clip, tmp_path):
    video, cam = clip
    config = write_config(
        tmp_path,
        stream_toml(
            str(video), cam, [("v", "perspective:64x48", "v4l2:/dev/video-absent-h44", "")]
        ),
    )
    with Running(config) as run:
        run.thread.join(20)
    assert run.status_code == 1  # systemd restarts it: the device may come back
    st = run.daemon.streams[0].status()
    assert st["state"] == "failed" and "/dev/video-absent-h44" in st["error"]


def test_camera_unplugged_and_replugged_resumes_without_a_restart(
    clip, source_frames, tmp_path, monkeypatch
):
    """A live source that stops delivering and cannot be opened for a while (the
    SourceErrors the V4L2 source raises; the real unplug is for the VM): the stream
    waits, retries, and goes on into the same outputs when it is back."""
    from omnidev.errors import SourceError
    from omnidev.sources.video import VideoSource

    video, cam = clip
    plugged = threading.Event()
    plugged.set()
    opens = []

    def open_camera(uri: str):  # type: ignore[no-untyped-def]
        if not plugged.is_set():
            raise SourceError(f"{uri}: no such device node (is the camera plugged in?)")
        opens.append(uri)

        class Live(VideoSource):
            def __iter__(self):  # type: ignore[no-untyped-def]
                for frame in super().__iter__():
                    if not plugged.is_set():
                        raise SourceError(f"{uri}: stopped delivering frames")
                    yield frame

        return Live(str(video), loop=True, rate=60.0)

    monkeypatch.setattr("omnidev.daemon.streams.open_source", open_camera)
    view = f"perspective:{PTZ_W}x{PTZ_H},fov=60,tilt=40"
    out = tmp_path / "cam.raw"
    config = write_config(
        tmp_path, stream_toml("v4l2:/dev/video-fake", cam, [("v", view, f"raw:{out}", "")])
    )
    with Running(config) as run:
        run.wait(lambda s: s["streams"][0]["written"] >= 10)
        plugged.clear()
        run.wait(lambda s: s["streams"][0]["state"] == "waiting for camera")
        retries = run.daemon.status()["streams"][0]["camera_retries"]
        run.wait(lambda s: s["streams"][0]["camera_retries"] >= retries + 2)
        written = run.daemon.status()["streams"][0]["written"]
        plugged.set()
        run.wait(lambda s: s["streams"][0]["written"] >= written + 10)
        assert run.thread.is_alive() and run.daemon.streams[0].status()["state"] == "running"
    assert len(opens) >= 2
    camera = omnidev.load_camera(cam)
    truth = _old_pose_hashes(camera, source_frames, view)
    frames = read_raw(out, PTZ_W, PTZ_H)
    assert len(frames) >= written + 10  # one output file across the unplug
    assert all(hashlib.sha1(f.tobytes()).digest() in truth for f in frames)


def test_a_following_view_is_steered_by_auto_framing(tmp_path, say):
    """A perspective view with ``follow`` keeps a rendered walking person framed
    (omnidev.sim.autoframe_video seed 2, from the auto-framing tuning range: a 480 px
    fisheye at 12.5 fps), the stream paced at the video's rate as a camera would be."""
    import math

    from omnidev.autoframe import view_offset
    from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
    from omnidev.fisheye.camfile import write_camera_file
    from omnidev.fisheye.models import IdealFisheye
    from omnidev.sim.autoframe_video import VideoRenderer, draw_video

    video = draw_video(2, kind="normal", camera="fisheye")
    r = VideoRenderer(video)
    sim = r.camera
    cam = tmp_path / "fisheye.yml"
    lens = IdealFisheye("equidistant", sim.f, *sim.center)
    max_deg = math.degrees(sim.max_angle)
    write_camera_file(cam, FisheyeCamera(lens, sim.image_size, MOUNTS["up"], max_angle_deg=max_deg))
    clip = tmp_path / "walk.avi"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter.fourcc(*"MJPG"), video.fps, sim.image_size)
    for i in range(video.frames):
        writer.write(r.render(i))
    writer.release()
    lo = max(90.0 - max_deg, -45.0)
    fov = 60.0
    views = [
        ("pano", f"panorama:360x{round(50 - lo)},elev={lo:g}:50", f"raw:{tmp_path / 'p.raw'}", ""),
        ("ptz", f"perspective:{PTZ_W}x{PTZ_H},fov={fov:g}", f"raw:{tmp_path / 'v.raw'}",
         'follow = "pano"\nmax_deg_s = 120'),
    ]  # fmt: skip
    # paced like a camera (a live source: at its end it is reopened, as a camera would be
    # after an unplug; the first pass is measured)
    config = write_config(tmp_path, stream_toml(f"video:{clip}?rate={video.fps:g}", cam, views))
    with Running(config) as run:
        run.wait(lambda s: s["streams"][0]["written"] >= video.frames, timeout=60)
        st = run.daemon.streams[0].status()
    ptz = run.daemon.streams[0].views[1]
    history = list(ptz.history)[: video.frames]
    assert [index for index, _ in history] == list(range(video.frames))
    assert st["views"][1]["follow_targets"] > 0
    offsets = [
        view_offset(pose.pan, pose.tilt, fov, *truth)
        for index, pose in history
        if pose is not None and (truth := r.truth(index)) is not None
    ]
    # after 1.5 s of the person being in view (acquisition), the person's centre within
    # 10 % of the view's width of its centre on >= 95 % of frames (the bound)
    settled = offsets[round(1.5 * video.fps) :]
    framed = float(np.mean(np.asarray(settled) <= 0.10))
    targets = st["views"][1]["follow_targets"]
    say(f"daemon auto-framing: framed {framed:.3f} of {len(settled)} frames, worst offset "
          f"{max(settled):.3f} view widths, {targets} targets")  # fmt: skip
    assert framed >= 0.95, (framed, max(settled))
    # before the person walks in, the view does not move
    before = [pose for index, pose in history if r.truth(index) is None]
    assert before and all(p == before[0] for p in before)

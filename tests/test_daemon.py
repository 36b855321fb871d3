"""The pointer daemon on the host: configuration errors, and the pipeline run on the
blob fixture into the record sink, checked against the fixture's truth."""

from __future__ import annotations

import json
import math
import threading
import time

import numpy as np
import pytest

from omnidev.daemon.config import load_config
from omnidev.daemon.pipeline import Pipeline
from omnidev.errors import ConfigError
from omnidev.sim.blob import load_blob_truth
from omnidev.sinks.record import read_events
from tests.daemon_helpers import BLOB, blob_config, match_to_truth


def wait_for(pred, timeout=20.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return False


@pytest.mark.parametrize(
    "text,key",
    [
        ("[source]\n", "source.uri: missing"),
        (
            '[source]\nuri = 3\n[tracker]\nname="x"\n[sink]\nname="r"\n',
            "source.uri: must be a string",
        ),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\n[sink]\nname="r"\n[filter]\nbeta=-1\n',
            "filter.beta",
        ),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\n[sink]\nname="r"\n[filter]\nkind="kalman"\n',
            "filter.kind",
        ),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\n[sink]\nname="r"\n[screen]\nrect="big"\n',
            "screen.rect",
        ),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\n[sink]\nname="r"\n[screen]\nrect="100x100+50+0"\nlayout="120x100"\n',
            "screen.layout",
        ),
        ('[source]\nuri="a"\nfps=3\n', "source.fps: unknown key"),
        ("[camera]\n", "camera: unknown section"),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\ncalibration="nope.yml"\n',
            "nope.yml: calibration file not found",
        ),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\ncalibration="."\n',
            "is a folder, not a calibration file",  # the configuration's own folder
        ),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\ncalibration="/dev/null"\n',
            "tracker.calibration: /dev/null: is a device, not a regular file; give the "
            "calibration file as a file",
        ),
        (
            '[source]\nuri="a"\n[tracker]\nname="x"\n[sink]\nname="r"\n[daemon]\nqueue=0\n',
            "daemon.queue",
        ),
        ("[source\n", "not valid TOML"),
    ],
)
def test_config_errors_name_the_key(tmp_path, text, key):
    path = tmp_path / "c.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    msg = str(info.value)
    assert str(path) in msg and key in msg and "\n" not in msg


def test_cli_config_error_is_one_line(tmp_path, capsys):
    from omnidev.daemon.main import main

    path = tmp_path / "c.toml"
    path.write_text(
        '[source]\nuri="a"\n[tracker]\nname="x"\n[sink]\nname="record"\n[filter]\nbeta="fast"\n'
    )
    assert main(["--config", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "filter.beta: must be a number" in err
    assert main(["--config", str(tmp_path / "missing.toml")]) == 2
    assert "configuration file not found" in capsys.readouterr().err


def test_unknown_plugins_are_named(tmp_path):
    cfg = load_config(
        blob_config(tmp_path, f"video:{BLOB}/blob.avi", "record", f'path = "{tmp_path}/r.jsonl"')
    )
    from dataclasses import replace

    from omnidev.errors import OmnidevError

    with pytest.raises(OmnidevError, match="tracker 'nope'.*installed: .*bright-blob"):
        Pipeline(replace(cfg, tracker="nope"))
    with pytest.raises(OmnidevError, match="sink 'nope'.*installed: .*record"):
        Pipeline(replace(cfg, sink="nope"))


def test_pipeline_follows_the_blob_into_the_record_sink(tmp_path):
    rec = tmp_path / "events.jsonl"
    cfg = load_config(
        blob_config(tmp_path, f"video:{BLOB}/blob.avi?rate=60", "record", f'path = "{rec}"')
    )
    truth = load_blob_truth(BLOB / "truth.json")
    p = Pipeline(cfg)
    p.start()
    try:
        assert wait_for(p.ended.is_set)  # the file ended: the run ends, no retry
        status = p.status()
    finally:
        p.stop()
    assert status["state"] == "ended" and status["camera_retries"] == 0
    assert status["source_kind"] == "live"  # rate=: a file standing in for a camera
    events = list(read_events(rec))
    moves = [e for e in events if e["kind"] == "move"]
    assert status["frames"] == len(truth)
    assert len(moves) + status["dropped_frames"] == len(truth)
    assert len(moves) >= 0.9 * len(truth)
    # every move names its frame: increasing, within the file, matched exactly to truth
    frames = [m["frame"] for m in moves]
    assert frames == sorted(set(frames)) and frames[0] >= 0 and frames[-1] < len(truth)
    pairs = [
        (i, math.hypot(m["x"] - truth[i].x, m["y"] - truth[i].y))
        for i, m in zip(frames, moves, strict=True)
    ]
    assert [i for i, _ in match_to_truth([(m["x"], m["y"]) for m in moves], truth)] == frames
    err_px = np.array([e for _, e in pairs]) * 1919  # normalized -> target-screen px
    print(
        f"\nblob -> record: {len(moves)} moves, error mean {err_px.mean():.3f} px, "
        f"max {err_px.max():.3f} px (1920-px screen); latency p50 {status['latency_p50_ms']} ms"
    )
    assert err_px.max() < 1.0
    # a paced file is stamped like a camera: the frame's delivery time, before the move
    assert all(0 < m["t_ns"] - m["frame_ns"] < 1e9 for m in moves)
    # buttons: the press/release sequence follows the fixture's clicks
    button_events = [(e["button"], e["down"]) for e in events if e["kind"] == "button"]
    want = []
    state = False
    for i, _ in pairs:
        if truth[i].pressed != state:
            state = truth[i].pressed
            want.append(("left", state))
    if state:
        want.append(("left", False))  # released when the source ended
    assert button_events == want
    assert events[-1]["kind"] == "close"


def test_stop_while_pressed_releases(tmp_path):
    """The source is paced so that the fixture is in a click when the pipeline stops."""
    rec = tmp_path / "events.jsonl"
    truth = load_blob_truth(BLOB / "truth.json")
    first_press = next(i for i, t in enumerate(truth) if t.pressed)
    cfg = load_config(
        blob_config(tmp_path, f"video:{BLOB}/blob.avi?rate=60", "record", f'path = "{rec}"')
    )
    p = Pipeline(cfg)
    p.start()
    try:
        assert wait_for(lambda: "left" in p.sink.pressed, 10)
    finally:
        p.stop()
    events = list(read_events(rec))
    buttons = [(e["button"], e["down"]) for e in events if e["kind"] == "button"]
    assert buttons[-1] == ("left", False) and buttons.count(("left", True)) == 1
    assert first_press > 0


class PluggableCamera:
    """A live source on the blob fixture that a test can unplug and plug back in:
    while unplugged, opening it fails and a running one stops delivering, with the
    SourceErrors the V4L2 source raises (the real unplug runs in the VM:
    tests/vm/test_daemon.py)."""

    def __init__(self) -> None:
        self.plugged = threading.Event()
        self.plugged.set()
        self.opens = 0

    def open(self, uri: str):
        from omnidev.errors import SourceError
        from omnidev.sources.video import VideoSource

        if not self.plugged.is_set():
            raise SourceError(f"{uri}: no such device node (is the camera plugged in?)")
        self.opens += 1
        camera = self

        class Live(VideoSource):
            def __iter__(self):
                for frame in super().__iter__():
                    if not camera.plugged.is_set():
                        raise SourceError(f"{uri}: stopped delivering frames")
                    yield frame

        return Live(str(BLOB / "blob.avi"), loop=True, rate=120.0)


def test_camera_gone_and_back(tmp_path, monkeypatch):
    """A live source that stops (camera unplugged): the daemon waits, retries, resumes."""
    camera = PluggableCamera()
    monkeypatch.setattr("omnidev.daemon.pipeline.open_source", camera.open)
    rec = tmp_path / "events.jsonl"
    cfg = load_config(blob_config(tmp_path, "cam:0", "record", f'path = "{rec}"'))
    p = Pipeline(cfg)
    p.start()
    try:
        assert wait_for(lambda: p.status()["tracked"] > 10)
        camera.plugged.clear()
        assert wait_for(lambda: p.status()["state"] == "waiting for camera")
        retries = p.status()["camera_retries"]
        assert wait_for(lambda: p.status()["camera_retries"] >= retries + 2)
        assert not p.sink.pressed
        tracked = p.status()["tracked"]
        camera.plugged.set()
        assert wait_for(lambda: p.status()["tracked"] > tracked + 10)
        assert p.alive and p.fatal is None and camera.opens >= 2
    finally:
        p.stop()
    text = rec.read_text()
    assert json.loads(text.splitlines()[-1])["kind"] == "close"


def test_replay_cli_reproduces_a_recording(tmp_path, capsys):
    from omnidev.cli.main import main

    rec = tmp_path / "events.jsonl"
    cfg = load_config(
        blob_config(tmp_path, f"video:{BLOB}/blob.avi?rate=240", "record", f'path = "{rec}"')
    )
    p = Pipeline(cfg)
    p.start()
    try:
        assert wait_for(p.ended.is_set)
    finally:
        p.stop()
    out = tmp_path / "again.jsonl"
    argv = ["replay", str(rec), "--sink", "record", "--sink-option", f"path={out}", "--fast"]
    assert main(argv) == 0
    a = [e for e in read_events(rec) if e["kind"] in ("move", "button")]
    b = [e for e in read_events(out) if e["kind"] in ("move", "button")]
    strip = [{k: v for k, v in e.items() if k not in ("t_ns", "frame", "frame_ns")} for e in a]
    assert strip == [{k: v for k, v in e.items() if k != "t_ns"} for e in b]
    assert main(["replay", str(tmp_path / "none.jsonl"), "--sink", "record"]) == 2
    assert "recording not found" in capsys.readouterr().err
    assert main(["replay", "/dev/null", "--sink", "record"]) == 2
    assert "/dev/null: is a device, not a regular file" in capsys.readouterr().err


def test_frame_size_change_stops_with_buttons_released(tmp_path):
    """A frame of another size mid-stream: a clear error, the pipeline stops, the button
    held at that moment is released (blob fixture frames as images, pressed at the switch)."""
    import cv2

    truth = load_blob_truth(BLOB / "truth.json")
    first_press = next(i for i, t in enumerate(truth) if t.pressed)
    frames = tmp_path / "frames"
    frames.mkdir()
    cap = cv2.VideoCapture(str(BLOB / "blob.avi"))
    for i in range(first_press + 3):
        ok, img = cap.read()
        assert ok
        cv2.imwrite(str(frames / f"f{i:04d}.png"), img)
    cap.release()
    assert truth[first_press + 2].pressed  # still pressed when the odd frame comes
    small = cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2))
    cv2.imwrite(str(frames / f"f{first_press + 3:04d}.png"), small)
    rec = tmp_path / "events.jsonl"
    cfg = load_config(blob_config(tmp_path, f"images:{frames}", "record", f'path = "{rec}"'))
    p = Pipeline(cfg)
    p.start()
    try:
        assert wait_for(lambda: not p.alive, 20)
    finally:
        p.stop()
    w, h = img.shape[1], img.shape[0]
    assert p.fatal is not None
    assert f"frame {first_press + 3} is {w // 2}x{h // 2}, the stream was {w}x{h}" in p.fatal
    assert p.status()["error"] == p.fatal
    events = list(read_events(rec))
    buttons = [(e["button"], e["down"]) for e in events if e["kind"] == "button"]
    assert buttons == [("left", True), ("left", False)]
    assert events[-1]["kind"] == "close"


@pytest.mark.parametrize("release", [True, False])
def test_target_lost_releases_buttons(tmp_path, release):
    """A frame with no target while a button is down releases it ([buttons]
    release_when_lost, default true); the next pressed frame presses again."""
    import cv2

    truth = load_blob_truth(BLOB / "truth.json")
    first_press = next(i for i, t in enumerate(truth) if t.pressed)
    assert all(t.pressed for t in truth[first_press : first_press + 5])
    frames = tmp_path / "frames"
    frames.mkdir()
    cap = cv2.VideoCapture(str(BLOB / "blob.avi"))
    imgs = [cap.read()[1] for _ in range(first_press + 5)]
    order = [*range(first_press + 2), None, first_press + 2, first_press + 3]
    for k, i in enumerate(order):  # None: a frame with no spot at all
        img = np.zeros_like(imgs[0]) if i is None else imgs[i]
        cv2.imwrite(str(frames / f"f{k:04d}.png"), img)
    rec = tmp_path / "events.jsonl"
    extra = "[buttons]\nrelease_when_lost = " + ("true" if release else "false")
    cfg = load_config(
        blob_config(tmp_path, f"images:{frames}", "record", f'path = "{rec}"', extra=extra)
    )
    p = Pipeline(cfg)
    p.start()
    try:
        assert wait_for(p.ended.is_set, 20)
    finally:
        p.stop()
    buttons = [(e["button"], e["down"]) for e in read_events(rec) if e["kind"] == "button"]
    if release:
        assert buttons == [("left", True), ("left", False), ("left", True), ("left", False)]
    else:
        assert buttons == [("left", True), ("left", False)]  # held through, released at stop

"""Honest file sources (issue 12 deliverable 4, issue 14's queue policy), on videos written
here: a file's frames carry its presentation times and are never dropped; a live source
drops its oldest frame and counts it; a truncated file ends the run with an error naming
its last good frame and is never replayed; the record sink names each sample's frame.

Variable-frame-rate files are written with ffmpeg (a system package of the project,
scripts/install-system-deps.sh) from frames made here, with presentation times chosen
here (integer milliseconds, exact in every container used)."""

from __future__ import annotations

import json
import math
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.daemon.config import FilterConfig, load_config
from omnidev.daemon.pipeline import Pipeline
from omnidev.errors import ConfigError, FileSourceError, SinkError, SourceError
from omnidev.filters import OneEuroFilter
from omnidev.frame import Frame
from omnidev.sinks.record import read_events
from omnidev.sources import open_source
from tests.daemon_helpers import BLOB, blob_config

W, H = 96, 64  # small frames: decoding is much faster than the slowed trackers below

needs_ffmpeg = pytest.mark.skipif(
    shutil.which("ffmpeg") is None,
    reason="ffmpeg (installed by scripts/install-system-deps.sh) writes the VFR test videos",
)


# -- test videos ----------------------------------------------------------------------


def dot_path(n: int, rest: tuple[int, int] | None = None) -> np.ndarray:
    """(n, 2) dot centres, camera px: a Lissajous path; frames rest[0]..rest[1]-1 hold
    the position of frame rest[0]."""
    i = np.arange(n, dtype=np.float64)
    xy = np.stack(
        [W / 2 + 30 * np.sin(2 * np.pi * i / 37.0), H / 2 + 18 * np.sin(2 * np.pi * i / 23.0)], 1
    )
    if rest is not None:
        xy[rest[0] : rest[1]] = xy[rest[0]]
    return xy


def dot_image(x: float, y: float) -> np.ndarray:
    img = np.full((H, W, 3), 16, np.uint8)
    s = 16  # cv2's sub-pixel shift: 4 fractional bits
    cv2.circle(img, (round(x * s), round(y * s)), 4 * s, (255, 255, 255), -1, cv2.LINE_AA, 4)
    return img


def write_cfr(path: Path, xy: np.ndarray, fps: float = 30.0) -> None:
    w = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), fps, (W, H))
    assert w.isOpened()
    for x, y in xy:
        w.write(dot_image(x, y))
    w.release()


def write_vfr(path: Path, xy: np.ndarray, times_ms: list[int], codec: str = "mjpeg") -> None:
    """Frames of ``xy`` at presentation times ``times_ms`` (ffmpeg: settb 1/1000 + setpts)."""
    expr = "0"
    for i in range(1, len(times_ms)):
        expr = f"if(eq(N,{i}),{times_ms[i]},{expr})"
    args = {
        "mjpeg": ["-c:v", "mjpeg", "-q:v", "2"],
        "h264": ["-c:v", "libx264", "-bf", "2", "-pix_fmt", "yuv420p", "-crf", "12"],
    }[codec]
    if path.suffix == ".mp4":
        args += ["-video_track_timescale", "1000"]
    raw = b"".join(dot_image(x, y).tobytes() for x, y in xy)
    cmd = [
        "ffmpeg", "-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo",
        "-pix_fmt", "bgr24", "-s", f"{W}x{H}", "-r", "1000", "-i", "-",
        "-vf", f"settb=1/1000,setpts='{expr}'", "-fps_mode", "passthrough",
        "-enc_time_base", "1:1000", *args, str(path),
    ]  # fmt: skip
    subprocess.run(cmd, input=raw, check=True, capture_output=True)


def irregular_times(n: int, seed: int) -> list[int]:
    """Presentation times, ms: spacings from 5 ms to 250 ms in random order (a VFR webcam
    recording, with stalls)."""
    rng = np.random.default_rng(seed)
    steps = rng.choice([5, 10, 17, 33, 50, 100, 250], size=n - 1)
    return [0, *np.cumsum(steps).astype(int).tolist()]


def cut_after(path: Path, out: Path, frames: int) -> None:
    """Copy an MJPEG AVI written by OpenCV, cut where frame ``frames`` begins (its chunk
    header, 8 bytes before the JPEG start), so exactly ``frames`` frames are whole."""
    data = path.read_bytes()
    soi = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xD8]
    out.write_bytes(data[: soi[frames] - 8])


class SlowTracker:
    """The real tracker, slowed by ``delay_s`` per frame (a heavy tracker, a loaded machine)."""

    def __init__(self, tracker, delay_s: float) -> None:
        self.inner, self.delay_s = tracker, delay_s

    def track(self, frame: Frame):
        time.sleep(self.delay_s)
        return self.inner.track(frame)

    def reset(self) -> None:
        self.inner.reset()


def run_pipeline(cfg_path: Path, slow_s: float = 0.0, timeout: float = 60.0) -> Pipeline:
    p = Pipeline(load_config(cfg_path))
    if slow_s:
        p.tracker = SlowTracker(p.tracker, slow_s)
    p.start()
    try:
        end = time.monotonic() + timeout
        while time.monotonic() < end and not p.ended.is_set() and p.fatal is None:
            time.sleep(0.02)
        assert p.ended.is_set() or p.fatal is not None, "the pipeline neither ended nor failed"
    finally:
        p.stop()
    return p


def moves_of(rec: Path) -> list[dict]:
    return [e for e in read_events(rec) if e["kind"] == "move"]


def cam_px_error(move: dict, xy: np.ndarray) -> float:
    """Distance, camera px, between a recorded position (bright-blob: u / (W - 1)) and
    the dot of the frame it names."""
    x, y = xy[move["frame"]]
    return math.hypot(move["x"] * (W - 1) - x, move["y"] * (H - 1) - y)


# -- the source: timestamps ----------------------------------------------------------


@needs_ffmpeg
@pytest.mark.parametrize("name,codec", [("v.mkv", "mjpeg"), ("v.mp4", "h264"), ("v.avi", "mjpeg")])
def test_file_frames_carry_the_containers_presentation_times(tmp_path, name, codec):
    """VFR files (H.264 with B-frames reordered in the decoder, too): each frame's
    timestamp is its presentation time, to the microsecond; nothing is called truncated
    although OpenCV estimates thousands of frames for Matroska and AVI from the duration."""
    times = irregular_times(60, seed=3)
    xy = dot_path(60)
    write_vfr(tmp_path / name, xy, times, codec)
    with open_source(str(tmp_path / name)) as src:
        assert not src.live
        frames = list(src)
    assert [f.index for f in frames] == list(range(60))
    got_ms = np.array([f.timestamp_ns for f in frames]) / 1e6
    assert np.abs(got_ms - np.array(times)).max() < 1e-3
    # delivered on the monotonic clock, decode time: far faster than the video plays
    delivered = [f.delivered_ns for f in frames]
    assert all(d is not None for d in delivered)
    assert delivered == sorted(delivered)


def test_images_and_loops_keep_increasing_timestamps(tmp_path):
    write_cfr(tmp_path / "v.avi", dot_path(10), fps=10.0)
    with open_source(f"video:{tmp_path / 'v.avi'}?loop=1") as src:
        assert not src.live and src.frame_count is None
        frames = [f for f, _ in zip(src, range(25), strict=False)]
    assert [f.index for f in frames] == list(range(25))
    # three passes of a 1 s file: 0, 0.1, ..., 2.4 s
    assert np.allclose([f.timestamp_ns / 1e9 for f in frames], np.arange(25) * 0.1, atol=1e-6)
    for i in range(4):
        cv2.imwrite(str(tmp_path / f"im{i}.png"), dot_image(*dot_path(4)[i]))
    with open_source(f"images:{tmp_path}/im*.png?fps=8") as src:
        assert [f.timestamp_ns for f in src] == [0, 125_000_000, 250_000_000, 375_000_000]
    with pytest.raises(SourceError, match=r"option fps must be frames per second"):
        open_source(f"images:{tmp_path}/im*.png?fps=inf")


@pytest.mark.parametrize("rate", ["inf", "nan", "0", "-5", "1e-300", "1e9", "fast"])
def test_rate_must_be_a_sane_number(tmp_path, rate):
    write_cfr(tmp_path / "v.avi", dot_path(3))
    with pytest.raises(SourceError, match=r"option rate must be 'realtime' or frames per second"):
        open_source(f"video:{tmp_path / 'v.avi'}?rate={rate}")


@needs_ffmpeg
def test_realtime_pacing_follows_the_presentation_times(tmp_path):
    """rate=realtime delivers each frame no earlier than its presentation time after the
    first (a lower bound only: a loaded machine may deliver later, never earlier)."""
    times = [0, 20, 30, 130, 140, 300]
    write_vfr(tmp_path / "v.mkv", dot_path(6), times)
    with open_source(f"video:{tmp_path / 'v.mkv'}?rate=realtime") as src:
        assert src.live
        frames = list(src)
    t = np.array([f.timestamp_ns for f in frames]) / 1e6
    assert [f.timestamp_ns for f in frames] == [f.delivered_ns for f in frames]  # camera-like
    assert np.all(t - t[0] >= np.array(times) - 1.0)


# -- the source: truncated and corrupt files -----------------------------------------


def _encode(src: Path, out: Path, *args: str) -> None:
    cmd = ["ffmpeg", "-hide_banner", "-loglevel", "error", "-y", "-i", str(src), *args, str(out)]
    subprocess.run(cmd, check=True, capture_output=True)


@needs_ffmpeg
@pytest.mark.parametrize(
    "name,args",
    [
        ("v.avi", []),  # OpenCV's MJPEG AVI as written
        ("h.mkv", ["-c:v", "libx264", "-pix_fmt", "yuv420p"]),
        ("h.mp4", ["-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags", "+faststart"]),
        ("m.avi", ["-c:v", "mpeg4"]),
    ],
)
@pytest.mark.parametrize("keep", [0.5, 0.9])
def test_truncated_files_name_their_last_good_frame(tmp_path, name, args, keep):
    write_cfr(tmp_path / "v.avi", dot_path(120), fps=30.0)
    whole = tmp_path / name
    if args:
        _encode(tmp_path / "v.avi", whole, *args)
    with open_source(str(whole)) as src:
        assert len(list(src)) == 120  # the whole file: complete, no error
    data = whole.read_bytes()
    cut = tmp_path / f"cut{whole.suffix}"
    cut.write_bytes(data[: int(len(data) * keep)])
    seen: list[int] = []
    with pytest.raises(FileSourceError) as info:
        with open_source(str(cut)) as src:
            seen.extend(f.index for f in src)
    msg = str(info.value)
    assert seen == list(range(len(seen))) and len(seen) < 120 * keep + 10
    assert f"frame {len(seen)} is corrupt or missing (truncated file?)" in msg
    assert f"read {len(seen)} of 120 frames, last good frame {len(seen) - 1}" in msg
    assert "\n" not in msg and str(cut) in msg


def dot_index(image: np.ndarray, xy: np.ndarray) -> tuple[int, float]:
    """The frame of ``xy`` whose dot this image shows, and the distance to it (camera px)."""
    ys, xs = np.nonzero(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) > 128)
    if len(xs) == 0:
        return -1, math.inf
    d = np.hypot(xy[:, 0] - xs.mean(), xy[:, 1] - ys.mean())
    return int(np.argmin(d)), float(d.min())


@needs_ffmpeg
@pytest.mark.parametrize("name", ["v.avi", "h.mkv", "h.mp4"])
def test_damage_inside_a_file_ends_the_run(tmp_path, name):
    """The middle fifth of the file's bytes overwritten with noise: the run ends with the
    error, never silently. MP4 and Matroska stop at the damage, and every frame delivered
    before it shows the dot of its presentation time (a frame the decoder skipped in the
    damage leaves a gap in the timestamps; the index counts the frames delivered). An
    AVI's demuxer skips over the damage (ffmpeg itself reports nothing), so the shortfall
    is found at the end, and the frames after the damage were numbered and stamped as
    they came (docs/daemon.md, "Complete files")."""
    xy = dot_path(120)
    write_cfr(tmp_path / "v.avi", xy, fps=30.0)
    whole = tmp_path / name
    if name != "v.avi":
        _encode(tmp_path / "v.avi", whole, "-c:v", "libx264", "-pix_fmt", "yuv420p")
    data = bytearray(whole.read_bytes())
    a, b = int(len(data) * 0.4), int(len(data) * 0.6)
    data[a:b] = np.random.default_rng(5).integers(0, 256, b - a, dtype=np.uint8).tobytes()
    bad = tmp_path / f"bad{whole.suffix}"
    bad.write_bytes(bytes(data))
    frames: list[Frame] = []
    with pytest.raises(FileSourceError, match=r"corrupt or missing|cannot be decoded") as info:
        with open_source(str(bad)) as src:
            frames.extend(src)
    assert len(frames) < 120 and f"last good frame {len(frames) - 1}" in str(info.value)
    print(f"\n{name} damaged at 40-60 %: {len(frames)} frames, then: {info.value}")
    if name != "v.avi":
        for f in frames:
            k, d = dot_index(f.image, xy)
            assert (k, d < 1.0) == (round(f.timestamp_ns * 30 / 1e9), True), (f.index, k, d)


# -- the pipeline: a file waits, a camera drops ----------------------------------------


def test_a_file_loses_no_frame_under_a_slow_tracker(tmp_path):
    """2000 frames, read ~10x faster than the slowed tracker takes them: every frame is
    tracked, in order, each position on its own frame's dot (no frame dropped)."""
    n = 2000
    xy = dot_path(n)
    write_cfr(tmp_path / "long.avi", xy, fps=30.0)
    rec = tmp_path / "events.jsonl"
    cfg = blob_config(tmp_path, f"video:{tmp_path / 'long.avi'}", "record", f'path = "{rec}"')
    p = run_pipeline(cfg, slow_s=0.001)
    st = p.status()
    print(f"\n2000-frame file, slow tracker: {p.summary()}")
    assert p.ended.is_set() and p.fatal is None
    assert st["source_kind"] == "recorded"
    assert st["frames"] == n and st["dropped_frames"] == 0 and st["tracked"] == n
    moves = moves_of(rec)
    assert [m["frame"] for m in moves] == list(range(n))
    assert max(cam_px_error(m, xy) for m in moves) < 0.5
    # presentation times of a 30 fps file, whatever the decode speed
    assert [m["frame_ns"] for m in moves[:4]] == [0, 33_333_333, 66_666_667, 100_000_000]
    assert "0 dropped (a file waits for the tracker)" in p.summary()


def test_a_live_source_drops_its_oldest_frames_and_counts_them(tmp_path):
    """A file paced at 400 fps stands in for a camera; the tracker takes 10 ms a frame.
    The queue keeps the newest frame: most frames are dropped and counted, the ones
    tracked are fresh (latency stays near one tracker period instead of growing)."""
    n = 400
    xy = dot_path(n)
    write_cfr(tmp_path / "cam.avi", xy, fps=30.0)
    rec = tmp_path / "events.jsonl"
    uri = f"video:{tmp_path / 'cam.avi'}?rate=400"
    p = run_pipeline(blob_config(tmp_path, uri, "record", f'path = "{rec}"'), slow_s=0.010)
    st = p.status()
    moves = moves_of(rec)
    frames = [m["frame"] for m in moves]
    gaps = np.diff(frames)
    print(
        f"\nlive source at 400 fps, 10 ms tracker: {p.summary()}; "
        f"latency p99 {st['latency_p99_ms']} ms, median index step {np.median(gaps)}"
    )
    assert st["source_kind"] == "live"
    assert st["frames"] == n and st["tracked"] == len(moves)
    assert st["tracked"] + st["dropped_frames"] == n and st["dropped_frames"] >= n // 2
    assert frames == sorted(set(frames)) and np.median(gaps) >= 2
    assert max(cam_px_error(m, xy) for m in moves) < 0.5
    # waiting instead would have queued ~300 frames: latency of seconds by the end
    assert st["latency_p99_ms"] < 200
    assert "dropped (live source: the oldest frame when behind)" in p.summary()


def test_queue_sizes_are_bounded(tmp_path):
    for queue in (17, 100000):
        cfg = blob_config(tmp_path, "video:x.avi", "record", 'path = "r"', extra=f"queue = {queue}")
        with pytest.raises(ConfigError, match=r"daemon\.queue: must be 1 \.\. 16 frames"):
            load_config(cfg)


# -- the pipeline: the file's timestamps reach the filter and the dwell click -----------


@needs_ffmpeg
def test_presentation_times_reach_the_one_euro_filter(tmp_path):
    """The same VFR file run with the filter off and on: the filtered positions are the
    One Euro filter of the raw ones at the file's presentation times, to 1e-9, and not
    what the filter gives at the decode-time spacing (~1 ms) the pipeline saw."""
    n = 80
    xy = dot_path(n)
    times = irregular_times(n, seed=11)
    write_vfr(tmp_path / "vfr.mkv", xy, times)
    runs = {}
    for kind in ("none", "one-euro"):
        rec = tmp_path / f"{kind}.jsonl"
        cfg = blob_config(
            tmp_path, f"video:{tmp_path / 'vfr.mkv'}", "record", f'path = "{rec}"', filt=kind
        )
        p = run_pipeline(cfg)
        assert p.status()["dropped_frames"] == 0
        runs[kind] = moves_of(rec)
    raw, filtered = runs["none"], runs["one-euro"]
    assert [m["frame"] for m in raw] == [m["frame"] for m in filtered] == list(range(n))
    assert [m["frame_ns"] for m in filtered] == [t * 1_000_000 for t in times]
    f = FilterConfig()
    ref = OneEuroFilter(f.min_cutoff, f.beta, f.d_cutoff)
    want = np.array([ref(t / 1000.0, [m["x"], m["y"]]) for t, m in zip(times, raw, strict=True)])
    got = np.array([[m["x"], m["y"]] for m in filtered])
    assert np.abs(got - want).max() < 1e-9
    wall = OneEuroFilter(f.min_cutoff, f.beta, f.d_cutoff)
    at_wall = np.array([wall(m["t_ns"] / 1e9, [m["x"], m["y"]]) for m in raw])
    # at decode-time spacing the filter would lag the dot by a large part of the screen
    assert np.abs(at_wall - got).max() * 1919 > 50


@needs_ffmpeg
def test_dwell_click_runs_on_presentation_time(tmp_path):
    """The dot rests for 1.2 s of presentation time (5 frames 300 ms apart), decoded in a
    few ms: the dwell click (0.8 s) fires once, on the first frame 0.8 s after the rest
    began (frame 23 at 0.9 s), as it would live."""
    n = 40
    xy = dot_path(n, rest=(20, 25))
    times = [33 * i for i in range(21)] + [660 + 300 * k for k in range(1, 5)]
    times += [times[-1] + 33 * k for k in range(1, n - 24)]
    write_vfr(tmp_path / "rest.mkv", xy, times)
    rec = tmp_path / "events.jsonl"
    cfg = blob_config(
        tmp_path,
        f"video:{tmp_path / 'rest.mkv'}",
        "record",
        f'path = "{rec}"',
        extra="[buttons]\ndwell = true\ndwell_s = 0.8\ndwell_radius_px = 12.0",
    )
    p = run_pipeline(cfg)
    assert p.status()["dwell_clicks"] == 1
    events = [e for e in read_events(rec) if e["kind"] in ("move", "button")]
    presses = [k for k, e in enumerate(events) if e["kind"] == "button" and e["down"]]
    assert len(presses) == 1
    before = events[presses[0] - 1]
    assert before["kind"] == "move" and before["frame"] == 23
    press = events[presses[0]]  # the click names the frame that completed the rest
    assert (press["frame"], press["frame_ns"]) == (23, before["frame_ns"]) == (23, 1_560_000_000)
    wall_s = (events[-1]["t_ns"] - events[0]["t_ns"]) / 1e9
    print(f"\ndwell on a VFR file: click after frame 23 (0.9 s of video), run took {wall_s:.3f} s")


# -- truncated files end the run: never replayed -------------------------------------


def test_daemon_on_a_truncated_file_fails_once_and_is_not_restarted(tmp_path):
    """The issue's case: the blob video cut after 16 frames, looped at its frame rate, into
    the record sink. The daemon moves the pointer for those frames once, logs one error
    naming the last good frame within 1 s of that frame's position, and exits 65 (which
    the unit does not restart)."""
    cut = tmp_path / "cut.avi"
    cut_after(BLOB / "blob.avi", cut, 16)
    rec = tmp_path / "events.jsonl"
    cfg = blob_config(tmp_path, f"video:{cut}?loop=1&rate=realtime", "record", f'path = "{rec}"')
    proc = subprocess.Popen(
        [sys.executable, "-m", "omnidev.daemon.main", "--config", str(cfg)],
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: list[tuple[int, str]] = []  # (monotonic ns when read, line)
    try:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.append((time.monotonic_ns(), line.rstrip("\n")))
        assert proc.wait(30) == 65, "\n".join(text for _, text in lines)
    finally:
        if proc.poll() is None:
            proc.kill()
    t_exit = time.monotonic_ns()
    log = "\n".join(text for _, text in lines)
    errors = [(t, text) for t, text in lines if " ERROR " in text]
    assert len(errors) == 1, log
    t_error, error = errors[0]
    assert "frame 16 is corrupt or missing (truncated file?)" in error
    assert "last good frame 15" in error and "not retrying" in error
    assert "retrying in" not in log
    assert "exiting with status 65" in log
    events = list(read_events(rec))
    moves = [e for e in events if e["kind"] == "move"]
    frames = [m["frame"] for m in moves]
    assert frames == sorted(set(frames)) and frames[-1] <= 15  # once each, never replayed
    # paced, the file is live: a frame the loaded machine was too slow for is dropped
    summary = re.search(r"stopped: 16 frames, (\d+) dropped", log)
    assert summary is not None and len(moves) + int(summary[1]) == 16 and len(moves) >= 12
    assert events[-1]["kind"] == "close"
    error_s = (t_error - moves[-1]["t_ns"]) / 1e9
    exit_s = (t_exit - moves[-1]["t_ns"]) / 1e9
    print(
        f"\ndaemon on a truncated file: the error {error_s:.3f} s after the last good frame's "
        f"position, process gone (exit 65) after {exit_s:.3f} s"
    )
    assert error_s < 1.0
    assert exit_s < 5.0  # the interpreter's own exit takes 0.3-0.6 s on a loaded machine


def test_mouse_on_a_truncated_file_exits_with_the_error(tmp_path, capsys):
    """The foreground runner (omnidev mouse) on a cut camera-mouse fixture: the frames
    before the cut are tracked, then one error line, exit 2, within 1 s."""
    from omnidev.cli.main import main

    fx = Path(__file__).resolve().parents[1] / "fixtures" / "mouse" / "sweep-320x240"
    cut = tmp_path / "cut.avi"
    cut_after(fx / "mouse.avi", cut, 12)
    rec = tmp_path / "events.jsonl"
    argv = [
        "mouse", str(cut), "--layout", str(fx / "landmarks.json"),
        "--sink", "record", "--sink-option", f"path={rec}", "--filter", "none",
    ]  # fmt: skip
    assert main(argv) == 2
    t_exit = time.monotonic_ns()
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 2, err  # the summary, then the error
    assert lines[-1].startswith("omnidev mouse: error: video:") and "last good frame 11" in err
    assert "12 frames, 0 dropped (a file waits for the tracker)" in err
    moves = moves_of(rec)
    assert [m["frame"] for m in moves] == list(range(12))
    assert (t_exit - moves[-1]["t_ns"]) / 1e9 < 1.0


def test_missing_file_is_not_waited_for_as_a_camera(tmp_path):
    rec = tmp_path / "events.jsonl"
    cfg = blob_config(tmp_path, f"video:{tmp_path / 'none.avi'}", "record", f'path = "{rec}"')
    p = run_pipeline(cfg, timeout=10)
    assert p.source_failed and "file not found" in (p.fatal or "")
    assert p.status()["camera_retries"] == 0


# -- the record sink and replay ------------------------------------------------------


def _recording(path: Path, lines: list[dict]) -> Path:
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def test_replay_reads_format_1_and_refuses_unknown_formats(tmp_path, capsys):
    from omnidev.cli.main import main

    old = _recording(
        tmp_path / "old.jsonl",
        [
            {"t_ns": 1, "kind": "open", "screen": [0, 0, 1920, 1080], "layout": [1920, 1080]},
            {"t_ns": 2, "kind": "move", "x": 0.25, "y": 0.5, "pixel": [480, 540], "capture_ns": 1},
            {"t_ns": 3, "kind": "button", "button": "left", "down": True},
            {"t_ns": 4, "kind": "close"},
        ],
    )
    out = tmp_path / "out.jsonl"
    argv = ["replay", str(old), "--sink", "record", "--sink-option", f"path={out}", "--fast"]
    assert main(argv) == 0
    again = [e for e in read_events(out) if e["kind"] != "open"]
    assert [(e["kind"], e.get("x"), e.get("down")) for e in again] == [
        ("move", 0.25, None),
        ("button", None, True),
        ("button", None, False),  # released at the end
        ("close", None, None),
    ]
    new = _recording(tmp_path / "new.jsonl", [{"t_ns": 1, "kind": "open", "format": 3}])
    assert main(["replay", str(new), "--sink", "record", "--sink-option", f"path={out}"]) == 2
    assert "line 1: recording format 3 is not one this omnidev reads (1, 2)" in (
        capsys.readouterr().err
    )
    bad = _recording(tmp_path / "bad.jsonl", [{"t_ns": 1, "kind": "move", "x": "a", "y": 0}])
    with pytest.raises(SinkError, match=r"bad\.jsonl: line 1: x must be a number"):
        list(read_events(bad))


def test_replay_keeps_the_frames_pace(tmp_path):
    """Moves written 1 ms apart from frames 30 ms apart (a file tracked fast) replay on the
    frames' schedule by default, move k no earlier than 30 k ms after the first (a lower
    bound: a sleep never ends early), and with --timing written keep their order."""
    from omnidev.cli.main import main

    lines: list[dict] = [{"t_ns": 0, "kind": "open", "format": 2}]
    for i in range(6):
        lines.append(
            {"t_ns": 1_000_000 * (i + 1), "kind": "move", "x": i / 10, "y": 0.5, "frame": i,
             "frame_ns": 30_000_000 * i}
        )  # fmt: skip
    rec = _recording(tmp_path / "rec.jsonl", lines)
    for timing in ("frames", "written"):
        out = tmp_path / f"{timing}.jsonl"
        argv = ["replay", str(rec), "--sink", "record", "--sink-option", f"path={out}"]
        assert main([*argv, "--timing", timing]) == 0
        moves = moves_of(out)
        assert [m["x"] for m in moves] == [i / 10 for i in range(6)]
        if timing == "frames":
            since_ms = (np.array([m["t_ns"] for m in moves]) - moves[0]["t_ns"]) / 1e6
            assert np.all(since_ms >= 30.0 * np.arange(6) - 1.0), since_ms


def test_an_image_set_is_a_recorded_source(tmp_path):
    """The image-set path of the pipeline: every image tracked once, presentation times
    from ?fps=, nothing dropped."""
    xy = dot_path(30)
    d = tmp_path / "frames"
    d.mkdir()
    for i, (x, y) in enumerate(xy):
        cv2.imwrite(str(d / f"f{i:03d}.png"), dot_image(x, y))
    rec = tmp_path / "events.jsonl"
    p = run_pipeline(
        blob_config(tmp_path, f"images:{d}?fps=12", "record", f'path = "{rec}"'), slow_s=0.002
    )
    moves = moves_of(rec)
    assert [m["frame"] for m in moves] == list(range(30))
    spacing = statistics.median(np.diff([m["frame_ns"] for m in moves]))
    assert spacing == pytest.approx(1e9 / 12, abs=1)
    assert p.status()["dropped_frames"] == 0


# -- what the user sees: omnidev ctl status and the exit summaries ---------------------


def test_ctl_status_and_the_daemons_summary_count_a_live_sources_drops(tmp_path, capsys, caplog):
    """The daemon (in this process, its real control socket) on a file paced at 400 fps
    with a tracker of 10 ms a frame: `omnidev ctl status` shows the drops with the live
    policy, its figures add up (frames = tracked + dropped, give or take the frames in
    flight), and the daemon's log line on stopping counts them too."""
    import logging
    import tempfile
    import threading

    from omnidev.cli.main import main
    from omnidev.daemon.main import Daemon

    write_cfr(tmp_path / "cam.avi", dot_path(200), fps=30.0)
    sock_dir = Path(tempfile.mkdtemp(prefix="omh30-"))  # AF_UNIX paths: 107 bytes at most
    rec = tmp_path / "events.jsonl"
    uri = f"video:{tmp_path / 'cam.avi'}?rate=400&loop=1"
    cfg = blob_config(tmp_path, uri, "record", f'path = "{rec}"')
    text = cfg.read_text().replace(str(tmp_path / "control.sock"), str(sock_dir / "c.sock"))
    cfg.write_text(text)
    daemon = Daemon(cfg)
    daemon.pipeline.tracker = SlowTracker(daemon.pipeline.tracker, 0.010)
    caplog.set_level(logging.INFO, logger="omnidevd")
    result: list[int] = []
    runner = threading.Thread(target=lambda: result.append(daemon.run()))
    runner.start()
    try:
        end = time.monotonic() + 30
        while time.monotonic() < end and daemon.pipeline.status()["tracked"] < 30:
            time.sleep(0.05)
        capsys.readouterr()
        assert main(["ctl", "status", "--socket", str(sock_dir / "c.sock"), "--json"]) == 0
        st = json.loads(capsys.readouterr().out)
        assert main(["ctl", "status", "--socket", str(sock_dir / "c.sock")]) == 0
        human = capsys.readouterr().out
    finally:
        daemon.stopping.set()
        runner.join(30)
        shutil.rmtree(sock_dir, ignore_errors=True)
    assert result == [0]
    assert st["source_kind"] == "live" and st["state"] == "running"
    assert st["tracked"] >= 30 and st["dropped_frames"] >= st["tracked"]
    # every frame delivered was tracked or dropped, except the few in the queue or tracker
    assert 0 <= st["frames"] - st["tracked"] - st["dropped_frames"] <= 3
    row = re.search(r"frames: +(\d+) \(dropped (\d+); live: the oldest frame is dropped", human)
    assert row is not None, human
    assert int(row[1]) >= st["frames"] and int(row[2]) >= st["dropped_frames"]
    stopped = [r.getMessage() for r in caplog.records if r.getMessage().startswith("stopped: ")]
    assert len(stopped) == 1, [r.getMessage() for r in caplog.records]
    last = re.match(r"stopped: (\d+) frames, (\d+) dropped \(live source: the oldest", stopped[0])
    assert last is not None and int(last[2]) >= int(row[2])
    print(f"\nctl status on a live source: {row[0]}; daemon on stopping: {stopped[0]}")


def test_laser_prints_the_summary_of_its_source(tmp_path, capsys):
    """`omnidev laser` on a committed screen fixture (90 frames, 61 with a spot): read at
    its own pace every frame is tracked and the summary says none was dropped; paced with
    ?rate= it is a live source, and the summary counts its drops (how many depends on the
    machine: at most the frames without a position)."""
    from omnidev.cli.main import main

    fx = Path(__file__).resolve().parents[1] / "fixtures" / "screen" / "k1+0.10-640x480"
    calib = tmp_path / "screen.yml.gz"
    argv = [
        "calibrate", "screen", "--white", str(fx / "white.png"), "--black",
        str(fx / "black.png"), "--dots", str(fx / "dots.png"), "-o", str(calib),
    ]  # fmt: skip
    assert main(argv) == 0
    spots = [
        i
        for i, f in enumerate(json.loads((fx / "truth.json").read_text())["laser"]["per_frame"])
        if f.get("spot") is not None
    ]
    summaries = {}
    for uri in (str(fx / "laser.avi"), f"video:{fx / 'laser.avi'}?rate=2000"):
        rec = tmp_path / "events.jsonl"
        rec.unlink(missing_ok=True)
        capsys.readouterr()
        argv = [
            "laser", uri, "--calibration", str(calib), "--colour", "green",
            "--sink-option", f"path={rec}", "--filter", "none",
        ]  # fmt: skip
        assert main(argv) == 0
        err = capsys.readouterr().err.strip().splitlines()
        summaries[uri] = err[-1]
        m = re.fullmatch(
            r"90 frames, (\d+) dropped \((.+?)\), (\d+) cursor positions, latency p50 \S+ ms; "
            r"buttons released",
            err[-1],
        )
        assert m is not None, err
        frames = [e["frame"] for e in moves_of(rec)]
        assert int(m[3]) == len(frames) and set(frames) <= set(spots)
        if "?rate=" in uri:
            assert m[2] == "live source: the oldest frame when behind"
            assert int(m[1]) <= 90 - len(frames)
        else:
            assert m[2] == "a file waits for the tracker" and int(m[1]) == 0
            assert frames == spots  # every frame with a spot gave a position, once
    print("\nomnidev laser summaries: " + " | ".join(summaries.values()))


def test_a_bare_device_node_is_a_camera_not_a_missing_file(tmp_path):
    """`omnidev laser /dev/video9`: a camera node, so a missing one is a SourceError the
    daemon retries (a camera may be plugged in), not a final 'file not found'."""
    from omnidev.sources import split_uri

    assert split_uri("/dev/video9")[0] == "v4l2"
    assert split_uri(str(tmp_path / "talk.mp4"))[0] == "video"
    with pytest.raises(SourceError) as info:
        open_source("/dev/video9" if not Path("/dev/video9").exists() else "/dev/video99")
    assert not isinstance(info.value, FileSourceError) and "file not found" not in str(info.value)

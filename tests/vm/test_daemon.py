"""The pointer daemon on a real kernel: vivid's video loop plays the blob fixture as a
camera, the daemon follows the spot into the uinput sink, python-evdev reads the
kernel's events back; the camera is unplugged (unbind + rmmod vivid) and comes back."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from evdev import ecodes

from omnidev.daemon.config import parse_config
from omnidev.daemon.control import request
from omnidev.daemon.pipeline import Pipeline
from omnidev.evdev_find import find_event_nodes
from omnidev.screen import ABS_MAX
from omnidev.sim.blob import render_blob_video
from tests.daemon_helpers import match_to_truth
from tests.vm.evdev_read import (
    open_reader,
    pending_frames,
    read_frames_timed,
    use_monotonic_clock,
)
from tests.vm.vivid import start_loop, stop, write_raw

FRAMES = 40  # one loop of the path; 37 MB of raw BGR in /tmp
WARMUP = 5
SCREEN_PX = 1919  # normalized -> pixels of the 1920-px target screen


def _fixture() -> tuple[Path, list[Any]]:
    raw = Path("/tmp/blob.raw")
    images, truth = render_blob_video(FRAMES, 640, 480, seed=1)
    if not raw.exists():
        write_raw(raw, [cv2.cvtColor(i, cv2.COLOR_GRAY2BGR) for i in images])
    return raw, truth


def _doc(capture: str, phys: str, socket: str) -> dict[str, Any]:
    return {
        "source": {"uri": f"v4l2:{capture}?width=640&height=480&buffers=2"},
        "tracker": {"name": "bright-blob", "options": {"press_area": 700}},
        "filter": {"kind": "none"},
        "sink": {"name": "uinput", "options": {"phys": phys}},
        "screen": {"rect": "1920x1080+0+0"},
        "daemon": {"socket": socket, "retry_initial_s": 0.5, "retry_max_s": 2.0},
    }


def _toml(doc: dict[str, Any]) -> str:
    """The two-level tables of a daemon config as TOML text (strings and numbers)."""

    def value(v: Any) -> str:
        return f'"{v}"' if isinstance(v, str) else repr(v)

    lines = []
    for section, body in doc.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {value(v)}" for k, v in body.items() if not isinstance(v, dict)]
        for k, v in body.items():
            if isinstance(v, dict):
                lines.append(f"[{section}.{k}]")
                lines += [f"{kk} = {value(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


def _positions(frames: list[tuple[list[tuple[int, int, int]], int]]) -> list[dict[str, Any]]:
    """Per SYN frame that moved: device x, y, kernel time, and BTN_LEFT change if any."""
    x = y = None
    out = []
    for events, t_ns in frames:
        moved = False
        button = None
        for etype, code, value in events:
            if etype == ecodes.EV_ABS and code == ecodes.ABS_X:
                x, moved = value, True
            elif etype == ecodes.EV_ABS and code == ecodes.ABS_Y:
                y, moved = value, True
            elif etype == ecodes.EV_KEY and code == ecodes.BTN_LEFT:
                button = value
        if (moved or button is not None) and x is not None and y is not None:
            out.append({"x": x, "y": y, "t_ns": t_ns, "button": button})
    return out


def test_daemon_follows_vivid_camera_into_uinput(vm_figures):
    raw, truth = _fixture()
    capture, feeder = start_loop(raw)
    sent: dict[tuple[int, int], list[int]] = {}  # device position -> capture times (ns)
    try:
        config = parse_config(_doc(capture, "omnidev/vm-daemon", "/tmp/vmd.sock"), Path("vm"))

        def on_sample(sample: Any, done_ns: int) -> None:
            pos = config.screen.to_device(sample.x, sample.y)
            sent.setdefault(pos, []).append(sample.timestamp_ns)

        pipeline = Pipeline(config, on_sample=on_sample)
        node = pipeline.sink.event_node  # type: ignore[attr-defined]
        assert node, "the uinput sink did not find its own event node"
        dev = open_reader(node)
        use_monotonic_clock(dev)
        pipeline.start()
        try:
            frames = read_frames_timed(dev, 160, timeout_s=240)
            status = pipeline.status()
        finally:
            pipeline.stop()
    finally:
        stop(feeder)
    # The first pictures vivid delivers can predate the looped fixture (its own
    # pattern, half-written buffers): judge from the sixth move on.
    moves = _positions(frames)[WARMUP:]
    pairs = match_to_truth([(m["x"] / ABS_MAX, m["y"] / ABS_MAX) for m in moves], truth)
    err_px = np.array([e for _, e in pairs]) * SCREEN_PX
    # capture -> kernel event timestamp: the same position comes round every loop,
    # so each event pairs with the latest capture of its position before it
    lat_ms = np.array(
        [
            (m["t_ns"] - max(t for t in sent[(m["x"], m["y"])] if t < m["t_ns"])) / 1e6
            for m in moves
            if any(t < m["t_ns"] for t in sent.get((m["x"], m["y"]), []))
        ]
    )
    vm_figures.update(
        {
            "vm_daemon_moves": len(moves),
            "vm_daemon_error_mean_px": round(float(err_px.mean()), 3),
            "vm_daemon_error_p99_px": round(float(np.percentile(err_px, 99)), 3),
            "vm_daemon_error_max_px": round(float(err_px.max()), 3),
            "vm_daemon_fps": status["fps"],
            "vm_daemon_dropped_frames": status["dropped_frames"],
            "vm_latency_p50_ms": round(float(np.percentile(lat_ms, 50)), 3),
            "vm_latency_p99_ms": round(float(np.percentile(lat_ms, 99)), 3),
        }
    )
    assert len(moves) >= 100
    # the spot's centre on the 1920-px screen, through camera loop and kernel
    assert float(np.median(err_px)) < 0.5 and float(err_px.max()) < 1.5, err_px
    assert lat_ms.size > 0.8 * len(moves) and (lat_ms > 0).all()
    # every BTN_LEFT change is in the frame where the fixture's click starts or ends
    presses = [(m["button"], truth[i].pressed) for m, (i, _) in zip(moves, pairs, strict=True)]
    changes = [(b, p) for b, p in presses if b is not None]
    assert (1, True) in changes and (0, False) in changes, changes
    assert all(bool(b) == p for b, p in changes), changes


def _wait(pred: Any, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    last: Any = None
    while time.monotonic() < end:
        try:
            last = pred()
            if last:
                return
        except Exception as exc:
            last = exc
        time.sleep(0.2)
    raise AssertionError(f"timed out after {timeout} s waiting for {what} (last: {last!r})")


def _unplug_vivid() -> None:
    """Remove the camera as an unplug does: unbind the device, then unload the driver."""
    for dev in Path("/sys/bus/platform/drivers/vivid").glob("vivid.*"):
        Path("/sys/bus/platform/drivers/vivid/unbind").write_text(dev.name)
    _wait(
        lambda: subprocess.run(["rmmod", "vivid"], capture_output=True).returncode == 0,
        60,
        "rmmod vivid (the daemon must close the dead device)",
    )


def _replug_vivid(
    daemon: subprocess.Popen[bytes], raw: Path, capture: str
) -> subprocess.Popen[bytes]:
    """Bring the camera back (modprobe vivid, its loop fed again from ``raw``) under the
    same node; returns the new feeder. The daemon is frozen meanwhile only so that it
    cannot open the capture node before vivid is switched to its HDMI loop (vivid
    refuses input changes while a reader streams)."""
    daemon.send_signal(signal.SIGSTOP)
    try:
        subprocess.run(["modprobe", "vivid", "n_devs=1", "node_types=0x101"], check=True)
        subprocess.run(["udevadm", "settle", "--timeout=60"], check=False)
        capture2, feeder = start_loop(raw)
    finally:
        daemon.send_signal(signal.SIGCONT)
    assert capture2 == capture, "vivid came back under another node; the config names one"
    return feeder


def test_daemon_keeps_running_when_the_camera_is_unplugged(tmp_path):
    raw, _ = _fixture()
    capture, feeder = start_loop(raw)
    sock = "/tmp/vmd-recover.sock"
    config = tmp_path / "omnidev.toml"
    config.write_text(_toml(_doc(capture, "omnidev/vm-recover", sock)))
    with open("/tmp/omnidevd-recover.log", "w") as log_file:
        daemon = subprocess.Popen(
            [sys.executable, "-m", "omnidev.daemon.main", "--config", str(config)],
            stderr=log_file,
        )
    try:
        # 180 s: the daemon's start (Python imports under TCG) took over 60 s on a loaded host
        _wait(lambda: find_event_nodes(phys="omnidev/vm-recover"), 180, "the daemon's device")
        dev = open_reader(find_event_nodes(phys="omnidev/vm-recover")[0])
        _wait(lambda: request(Path(sock), "status")["tracked"] > 20, 120, "tracking")

        stop(feeder)
        _unplug_vivid()
        _wait(
            lambda: request(Path(sock), "status")["state"] == "waiting for camera",
            60,
            "the daemon to notice the camera is gone",
        )
        assert daemon.poll() is None
        assert dev.active_keys() == []  # no button left pressed while the camera is away
        retries = request(Path(sock), "status")["camera_retries"]
        _wait(lambda: request(Path(sock), "status")["camera_retries"] >= retries + 2, 30, "retries")

        tracked = request(Path(sock), "status")["tracked"]
        feeder = _replug_vivid(daemon, raw, capture)
        _wait(
            lambda: request(Path(sock), "status")["tracked"] > tracked + 20,
            120,
            "the daemon to resume when the camera returns",
        )
        assert request(Path(sock), "status")["state"] == "running"
        # SIGTERM while the fixture holds the button: the release reaches the kernel
        _wait(lambda: ecodes.BTN_LEFT in dev.active_keys(), 60, "a click in the fixture")
        daemon.send_signal(signal.SIGTERM)
        rest = [e for frame in pending_frames(dev, wait_s=5.0) for e in frame]
        assert daemon.wait(30) == 0
        assert (ecodes.EV_KEY, ecodes.BTN_LEFT, 0) in rest, rest
    finally:
        stop(feeder)
        if daemon.poll() is None:
            daemon.kill()
            daemon.wait()
    log = Path("/tmp/omnidevd-recover.log").read_text()
    assert "retrying" in log and "all buttons released" in log, log[-2000:]

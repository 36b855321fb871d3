"""omnidevd as a process: sd_notify READY/WATCHDOG, the control socket, pause/resume,
reload, SIGTERM with a button held (released before exit)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from omnidev.daemon.control import request
from omnidev.sinks.record import read_events
from tests.daemon_helpers import BLOB, blob_config


def wait_for(pred, timeout=20.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            if pred():
                return True
        except Exception:
            pass
        time.sleep(0.05)
    return False


@pytest.fixture
def notify_socket(tmp_path):
    path = tmp_path / "notify.sock"
    s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    s.bind(str(path))
    s.settimeout(0.1)
    yield path, s
    s.close()


def received(sock: socket.socket) -> list[str]:
    out = []
    while True:
        try:
            out += sock.recv(4096).decode().splitlines()
        except TimeoutError:
            return out


def test_daemon_process_end_to_end(tmp_path, notify_socket):
    rec = tmp_path / "events.jsonl"
    cfg = blob_config(
        tmp_path, f"video:{BLOB}/blob.avi?loop=1&rate=60", "record", f'path = "{rec}"'
    )
    nsock_path, nsock = notify_socket
    env = {**os.environ, "NOTIFY_SOCKET": str(nsock_path), "WATCHDOG_USEC": "2000000"}
    env.pop("WATCHDOG_PID", None)
    proc = subprocess.Popen(
        [sys.executable, "-m", "omnidev.daemon.main", "--config", str(cfg)],
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    sock = tmp_path / "control.sock"
    try:
        assert wait_for(lambda: request(sock, "status")["tracked"] > 30)
        st = request(sock, "status")
        assert st["ok"] and st["state"] == "running" and st["sink"] == "record"
        assert 50 < st["fps"] < 70 and st["latency_p99_ms"] is not None
        assert (sock.stat().st_mode & 0o777) == 0o600
        time.sleep(1.2)  # a watchdog period (half of WATCHDOG_USEC)
        msgs = received(nsock)
        assert "READY=1" in msgs and "WATCHDOG=1" in msgs
        assert any(m.startswith("STATUS=running") for m in msgs)

        assert request(sock, "pause")["ok"]
        time.sleep(0.3)
        n = request(sock, "status")["events"]
        time.sleep(0.5)
        st = request(sock, "status")
        assert st["state"] == "paused" and st["events"] == n  # nothing moves while paused
        assert request(sock, "resume")["ok"]
        assert wait_for(lambda: request(sock, "status")["events"] > n + 10)

        # reload: a broken file is refused and the daemon keeps running
        good = cfg.read_text()
        cfg.write_text(good.replace('kind = "none"', 'kind = "kalman"'))
        reply = request(sock, "reload")
        assert not reply["ok"] and "filter.kind" in reply["error"]
        cfg.write_text(good.replace('kind = "none"', 'kind = "one-euro"'))
        assert request(sock, "reload")["ok"]
        assert request(sock, "status")["state"] == "running"

        # SIGTERM while the fixture holds the button
        assert wait_for(lambda: "left" in _pressed_now(rec), 10)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    err = proc.stderr.read() if proc.stderr else ""
    assert "all buttons released" in err
    events = list(read_events(rec))
    assert events[-1]["kind"] == "close"
    assert _pressed(events) == set()
    assert not sock.exists()
    assert "STOPPING=1" in received(nsock)


def _pressed(events) -> set[str]:
    down: set[str] = set()
    for e in events:
        if e["kind"] == "button":
            (down.add if e["down"] else down.discard)(e["button"])
    return down


def _pressed_now(rec: Path) -> set[str]:
    return _pressed(read_events(rec))


def test_daemon_check_and_bad_plugin(tmp_path):
    cfg = blob_config(tmp_path, f"video:{BLOB}/blob.avi", "record", 'path = "-"')
    run = [sys.executable, "-m", "omnidev.daemon.main", "--config", str(cfg)]
    r = subprocess.run([*run, "--check"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "ok" in r.stdout
    cfg.write_text(cfg.read_text().replace('name = "record"', 'name = "warp-drive"'))
    r = subprocess.run(run, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "sink 'warp-drive'" in r.stderr

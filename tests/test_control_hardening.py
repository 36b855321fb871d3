"""The daemon's control socket under abuse: connection cap, nested JSON, socket moves on
reload, and a second daemon refused before it opens anything (its sink included)."""

from __future__ import annotations

import contextlib
import json
import socket
import threading
import time
from pathlib import Path

import pytest

from omnidev.daemon.control import MAX_CONNECTIONS, ControlError, ControlServer, request
from omnidev.daemon.main import Daemon
from tests.daemon_helpers import BLOB, blob_config


def _handler(cmd: str, args: dict) -> dict:
    return {"state": "running"}


def _ask(path: Path, line: bytes) -> dict:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(5)
        s.connect(str(path))
        s.sendall(line)
        data = b""
        while not data.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    return json.loads(data)


def test_connections_are_capped_with_a_reply_then_served_again(tmp_path):
    with ControlServer(tmp_path / "c.sock", _handler) as srv:
        idle = []
        for _ in range(MAX_CONNECTIONS):
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.connect(str(srv.path))
            idle.append(s)
        time.sleep(0.3)  # the server has accepted them all
        refused = [request(srv.path, "status")["error"] for _ in range(5)]
        assert all("too many control connections" in e for e in refused)
        assert srv.refused == 5
        threads = threading.active_count()
        for s in idle:
            s.close()
        time.sleep(0.3)
        assert request(srv.path, "status")["ok"] is True
        assert threading.active_count() <= threads  # no thread per refused connection


@pytest.mark.parametrize(
    "line",
    [b"[" * 60000 + b"\n", b'{"cmd": ' + b"[" * 5000 + b"]" * 5000 + b"}\n", b"\xff\xfe\n",
     b'{"cmd": 5}\n', b"null\n", b'{"cmd": "status"' + b" " * 10 + b"\n"],
    ids=["deep array", "deep in cmd", "not UTF-8", "cmd not a string", "null", "cut off"],
)  # fmt: skip
def test_every_malformed_request_gets_an_error_reply(tmp_path, line):
    with ControlServer(tmp_path / "c.sock", _handler) as srv:
        reply = _ask(srv.path, line)
        assert reply["ok"] is False and "malformed request" in reply["error"]
        assert request(srv.path, "status")["ok"] is True  # still serving


def _daemon(tmp_path: Path, name: str, socket_path: Path) -> tuple[Daemon, Path]:
    folder = tmp_path / name
    folder.mkdir()
    config = blob_config(
        folder,
        f"video:{BLOB / 'blob.avi'}?loop=1&rate=30",
        "record",
        f'path = "{folder / "pointer.jsonl"}"',
    )
    text = config.read_text().replace(str(folder / "control.sock"), str(socket_path))
    config.write_text(text)
    return Daemon(config), config


def _run(daemon: Daemon) -> threading.Thread:
    t = threading.Thread(target=daemon.run, daemon=True)
    t.start()
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:  # until the socket answers, not only exists
        if daemon.server is not None and daemon.socket.exists():
            with contextlib.suppress(ControlError):
                request(daemon.socket, "status")
                break
        time.sleep(0.05)
    return t


def test_second_daemon_refused_before_it_opens_its_sink(tmp_path):
    sock = tmp_path / "control.sock"
    first, _ = _daemon(tmp_path, "a", sock)
    t = _run(first)
    try:
        with pytest.raises(ControlError, match="another omnidevd already answers"):
            _daemon(tmp_path, "b", sock)
        assert not (tmp_path / "b" / "pointer.jsonl").exists()  # its sink was never opened
        assert request(sock, "status")["ok"] is True
    finally:
        first.stopping.set()
        t.join(10)


def test_reload_moves_the_socket_or_refuses(tmp_path):
    sock, moved = tmp_path / "control.sock", tmp_path / "moved.sock"
    daemon, config = _daemon(tmp_path, "a", sock)
    t = _run(daemon)
    try:
        text = config.read_text()
        config.write_text(text.replace(str(sock), str(moved)))
        reply = request(sock, "reload")
        assert reply["ok"] is True and reply["socket"] == str(moved)
        assert request(moved, "status")["ok"] is True
        deadline = time.monotonic() + 5
        while sock.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not sock.exists()  # the old socket is closed and removed
        # a socket path that cannot be bound: refused, the running socket kept
        blocker = tmp_path / "file.sock"
        blocker.write_text("not a socket")
        config.write_text(text.replace(str(sock), str(blocker)))
        reply = request(moved, "reload")
        assert reply["ok"] is False and "daemon.socket" in reply["error"]
        assert "running configuration is kept" in reply["error"]
        assert request(moved, "status")["ok"] is True
    finally:
        daemon.stopping.set()
        t.join(10)

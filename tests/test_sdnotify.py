"""sd_notify against real AF_UNIX datagram sockets standing in for systemd's notify socket."""

from __future__ import annotations

import os
import socket
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from omnidev.daemon import sdnotify


def _receive(sock: socket.socket) -> str:
    sock.settimeout(5.0)
    return sock.recv(4096).decode("utf-8")


@pytest.fixture
def path_socket(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[socket.socket]:
    """A datagram socket bound to a file in tmp_path, announced as $NOTIFY_SOCKET."""
    path = tmp_path / "notify"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(path))
    monkeypatch.setenv("NOTIFY_SOCKET", str(path))
    yield sock
    sock.close()


@pytest.fixture
def abstract_socket(monkeypatch: pytest.MonkeyPatch) -> Iterator[socket.socket]:
    """A datagram socket in the abstract namespace, announced as $NOTIFY_SOCKET=@name."""
    name = f"omnidev-test-{uuid.uuid4().hex}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind("\0" + name)
    monkeypatch.setenv("NOTIFY_SOCKET", "@" + name)
    yield sock
    sock.close()


def test_path_socket_receives_each_state(path_socket):
    assert sdnotify.ready() is True
    assert _receive(path_socket) == "READY=1"
    assert sdnotify.watchdog() is True
    assert _receive(path_socket) == "WATCHDOG=1"
    assert sdnotify.status("running: 29.9 fps\nsink uinput") is True
    assert _receive(path_socket) == "STATUS=running: 29.9 fps sink uinput"
    assert sdnotify.reloading() is True
    assert _receive(path_socket) == "RELOADING=1"
    assert sdnotify.stopping() is True
    assert _receive(path_socket) == "STOPPING=1"
    assert sdnotify.notify("READY=1\nSTATUS=ok") is True
    assert _receive(path_socket) == "READY=1\nSTATUS=ok"


def test_abstract_socket_receives(abstract_socket):
    assert sdnotify.ready() is True
    assert _receive(abstract_socket) == "READY=1"
    assert sdnotify.status("waiting for camera") is True
    assert _receive(abstract_socket) == "STATUS=waiting for camera"


def test_sender_is_this_process(path_socket):
    """systemd's NotifyAccess=main accepts only datagrams whose sender is the main PID."""
    path_socket.setsockopt(socket.SOL_SOCKET, socket.SO_PASSCRED, 1)
    assert sdnotify.ready()
    path_socket.settimeout(5.0)
    msg, ancdata, _, _ = path_socket.recvmsg(4096, socket.CMSG_SPACE(12))
    assert msg == b"READY=1"
    creds = [data for level, kind, data in ancdata if kind == socket.SCM_CREDENTIALS]
    assert creds, "no SCM_CREDENTIALS received"
    pid = int.from_bytes(creds[0][:4], "little")
    assert pid == os.getpid()


def test_no_systemd_is_a_no_op(monkeypatch):
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    assert sdnotify.ready() is False
    assert sdnotify.watchdog() is False
    assert sdnotify.status("x") is False
    monkeypatch.setenv("NOTIFY_SOCKET", "")
    assert sdnotify.ready() is False
    monkeypatch.setenv("NOTIFY_SOCKET", "vsock:2:1234")
    assert sdnotify.ready() is False


def test_missing_socket_returns_false_without_raising(tmp_path, monkeypatch):
    monkeypatch.setenv("NOTIFY_SOCKET", str(tmp_path / "gone"))
    assert sdnotify.ready() is False


@pytest.mark.parametrize(
    ("usec", "pid", "expected"),
    [
        ("10000000", None, 5.0),  # WatchdogSec=10 -> ping every 5 s
        ("3000000", "self", 1.5),
        ("250000", None, 0.125),
        ("10000000", "other", None),  # armed for another process
        ("0", None, None),
        ("", None, None),
        ("ten", None, None),
        ("10000000", "x", None),
        (None, None, None),
    ],
)
def test_watchdog_interval(monkeypatch, usec, pid, expected):
    if usec is None:
        monkeypatch.delenv("WATCHDOG_USEC", raising=False)
    else:
        monkeypatch.setenv("WATCHDOG_USEC", usec)
    if pid is None:
        monkeypatch.delenv("WATCHDOG_PID", raising=False)
    else:
        value = {"self": str(os.getpid()), "other": str(os.getpid() + 1)}.get(pid, pid)
        monkeypatch.setenv("WATCHDOG_PID", value)
    assert sdnotify.watchdog_interval_s() == expected

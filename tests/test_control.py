"""The control socket on real Unix sockets in tmp_path: mode, protocol, errors, concurrency."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import stat
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

from omnidev.cli import ctl_cmd
from omnidev.daemon.control import DEFAULT_SOCKET, ControlError, ControlServer, request
from omnidev.errors import ConfigError, OmnidevError


class ToyDaemon:
    """A handler with the daemon's status keys and a pause flag."""

    def __init__(self) -> None:
        self.paused = False
        self.calls: list[tuple[str, dict[str, Any]]] = []
        self.reloads = 0

    def __call__(self, cmd: str, args: dict[str, Any]) -> dict[str, Any]:
        self.calls.append((cmd, args))
        if cmd == "pause":
            self.paused = True
        elif cmd == "resume":
            self.paused = False
        elif cmd == "reload":
            if args.get("fail"):
                raise ConfigError("/etc/omnidev/omnidev.toml: [filter] beta: must be >= 0")
            if args.get("crash"):
                raise RuntimeError("boom")
            self.reloads += 1
            return {"state": self.state, "message": f"reloaded {self.reloads}"}
        return self.status()

    @property
    def state(self) -> str:
        return "paused" if self.paused else "running"

    def status(self) -> dict[str, Any]:
        return {
            "state": self.state,
            "source": "video:fixtures/blob/blob.avi?loop=1",
            "sink": "record",
            "tracker": "bright-blob",
            "fps": 60.0,
            "latency_p50_ms": 1.25,
            "latency_p99_ms": 3.5,
            "frames": 120,
            "dropped_frames": 2,
            "events": 118,
            "camera_retries": 0,
            "uptime_s": 2.0,
        }


@pytest.fixture
def short_tmp() -> Any:
    """A short directory: AF_UNIX paths are limited to 107 bytes; pytest's tmp_path may exceed."""
    import tempfile

    d = Path(tempfile.mkdtemp(prefix="omctl-"))
    yield d
    shutil.rmtree(d, ignore_errors=True)


@pytest.fixture
def server(short_tmp):
    daemon = ToyDaemon()
    srv = ControlServer(short_tmp / "run" / "control.sock", daemon)
    srv.start()
    yield srv, daemon
    srv.close()


def raw_exchange(path: Path, data: bytes, n_replies: int) -> list[dict[str, Any]]:
    """Send raw bytes, read ``n_replies`` reply lines."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(5.0)
        s.connect(str(path))
        s.sendall(data)
        buf = b""
        while buf.count(b"\n") < n_replies:
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
    return [json.loads(line) for line in buf.splitlines()]


def test_socket_is_mode_0600_and_a_socket(server):
    srv, _ = server
    st = os.stat(srv.path)
    assert stat.S_ISSOCK(st.st_mode)
    assert stat.S_IMODE(st.st_mode) == 0o600
    assert st.st_uid == os.getuid()


def test_status_pause_resume_round_trip(server):
    srv, daemon = server
    reply = request(srv.path, "status")
    assert reply == {"ok": True, **daemon.status()}
    assert reply["state"] == "running"
    assert request(srv.path, "pause")["state"] == "paused"
    assert daemon.paused is True
    assert request(srv.path, "status")["state"] == "paused"
    assert request(srv.path, "resume")["state"] == "running"
    assert request(srv.path, "reload") == {"ok": True, "state": "running", "message": "reloaded 1"}
    assert [c for c, _ in daemon.calls] == ["status", "pause", "status", "resume", "reload"]


def test_extra_arguments_reach_the_handler(server):
    srv, daemon = server
    request(srv.path, "status", verbose=True, n=3)
    assert daemon.calls[-1] == ("status", {"verbose": True, "n": 3})


def test_handler_errors_become_error_replies(server):
    srv, _ = server
    reply = request(srv.path, "reload", fail=True)
    assert reply == {"ok": False, "error": "/etc/omnidev/omnidev.toml: [filter] beta: must be >= 0"}
    reply = request(srv.path, "reload", crash=True)
    assert reply["ok"] is False
    assert "RuntimeError: boom" in reply["error"]
    assert request(srv.path, "status")["ok"] is True  # still serving


def test_malformed_and_unknown_requests_get_errors_and_server_lives(server):
    srv, daemon = server
    replies = raw_exchange(
        srv.path,
        b"not json\n"
        b"[1, 2]\n"
        b'{"nocmd": 1}\n'
        b'{"cmd": 7}\n'
        b'{"cmd": "shutdown"}\n'
        b"\xff\xfe\n"
        b"\n"  # blank lines are skipped, not answered
        b'{"cmd": "status"}\n',
        7,
    )
    assert len(replies) == 7
    assert [r["ok"] for r in replies] == [False] * 6 + [True]
    assert "malformed request" in replies[0]["error"]
    assert "JSON object" in replies[1]["error"]
    assert "'cmd'" in replies[2]["error"]
    assert "'cmd'" in replies[3]["error"]
    assert replies[4]["error"] == (
        "unknown command 'shutdown' (known: status, pause, resume, reload, view)"
    )
    assert "malformed request" in replies[5]["error"]
    assert replies[6]["state"] == "running"
    assert [c for c, _ in daemon.calls] == ["status"]
    assert request(srv.path, "status")["ok"] is True


def test_last_request_without_newline_is_answered(server):
    srv, _ = server
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(5.0)
        s.connect(str(srv.path))
        s.sendall(b'{"cmd": "status"}')
        s.shutdown(socket.SHUT_WR)
        data = s.recv(65536)
    assert json.loads(data)["ok"] is True


def test_oversized_request_is_refused(server):
    srv, _ = server
    replies = raw_exchange(srv.path, b"x" * 70000, 1)
    assert replies[0]["ok"] is False
    assert "longer than 65536 bytes" in replies[0]["error"]
    assert request(srv.path, "status")["ok"] is True


def test_nan_and_non_serializable_replies(short_tmp):
    def handler(cmd: str, args: dict[str, Any]) -> dict[str, Any]:
        if cmd == "status":
            return {"fps": float("nan"), "latency_p99_ms": float("inf"), "frames": 0}
        return {"thing": object()}

    with ControlServer(short_tmp / "c.sock", handler) as srv:
        assert request(srv.path, "status") == {
            "ok": True,
            "fps": None,
            "latency_p99_ms": None,
            "frames": 0,
        }
        reply = request(srv.path, "pause")
        assert reply["ok"] is False
        assert "not JSON serializable" in reply["error"]


def test_concurrent_clients(server):
    srv, daemon = server
    n_threads, n_requests = 16, 25
    results: list[list[dict[str, Any]]] = [[] for _ in range(n_threads)]
    errors: list[BaseException] = []

    def client(i: int) -> None:
        try:
            for _ in range(n_requests):
                results[i].append(request(srv.path, "status", timeout=10.0, client=i))
        except BaseException as exc:  # reported below
            errors.append(exc)

    threads = [threading.Thread(target=client, args=(i,)) for i in range(n_threads)]
    for t in threads:
        t.start()
    # one slow client holding a connection open must not block the others
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as idle:
        idle.connect(str(srv.path))
        for t in threads:
            t.join()
    assert errors == []
    assert all(len(r) == n_requests and all(x["ok"] for x in r) for r in results)
    assert len(daemon.calls) == n_threads * n_requests
    assert sorted({a["client"] for _, a in daemon.calls}) == list(range(n_threads))


def test_many_requests_on_one_connection(server):
    srv, _ = server
    replies = raw_exchange(srv.path, b'{"cmd": "pause"}\n{"cmd": "resume"}\n{"cmd": "status"}\n', 3)
    assert [r["state"] for r in replies] == ["paused", "running", "running"]


def test_stale_socket_file_is_replaced(short_tmp):
    path = short_tmp / "control.sock"
    dead = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    dead.bind(str(path))
    dead.close()  # the file stays, nobody listens: what a crashed daemon leaves
    assert stat.S_ISSOCK(os.stat(path).st_mode)
    with pytest.raises(ControlError, match="stale"):
        request(path, "status")
    os.chmod(path, 0o666)
    with ControlServer(path, ToyDaemon()) as srv:  # binding would fail were the file still there
        assert request(srv.path, "status")["ok"] is True
        assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert not path.exists()


def test_refuses_to_start_when_a_live_server_answers(server):
    srv, _ = server
    second = ControlServer(srv.path, ToyDaemon())
    with pytest.raises(ControlError, match="another omnidevd already answers"):
        second.start()
    assert request(srv.path, "status")["ok"] is True  # the first one is untouched


def test_refuses_a_path_that_is_not_a_socket(short_tmp):
    path = short_tmp / "control.sock"
    path.write_text("precious")
    with pytest.raises(ControlError, match="is not a socket"):
        ControlServer(path, ToyDaemon()).start()
    assert path.read_text() == "precious"


def test_close_unlinks_and_stops(short_tmp):
    path = short_tmp / "control.sock"
    srv = ControlServer(path, ToyDaemon())
    srv.start()
    assert path.exists()
    srv.close()
    assert not path.exists()
    with pytest.raises(ControlError, match="no control socket"):
        request(path, "status")


def test_close_leaves_a_successors_socket_alone(short_tmp):
    path = short_tmp / "control.sock"
    first = ControlServer(path, ToyDaemon())
    first.start()
    path.unlink()  # e.g. an admin removed it and a new daemon started
    with ControlServer(path, ToyDaemon()) as second:
        first.close()
        assert path.exists()
        assert request(second.path, "status")["ok"] is True


def test_missing_socket_error_names_the_default(short_tmp):
    with pytest.raises(ControlError) as info:
        request(short_tmp / "nope.sock", "status")
    message = str(info.value)
    assert "is omnidevd running?" in message
    assert str(DEFAULT_SOCKET) == "/run/omnidev/control.sock"
    assert str(DEFAULT_SOCKET) in message
    assert "\n" not in message
    assert isinstance(info.value, OmnidevError)


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to run the client as user nobody")
def test_permission_denied_for_another_user(server):
    if shutil.which("setpriv") is None:
        pytest.skip("setpriv (util-linux) is not installed: cannot drop to user nobody")
    srv, _ = server
    srv.path.parent.chmod(0o755)  # let nobody reach the socket itself (mode 0600)
    srv.path.parent.parent.chmod(0o755)
    code = (
        "import sys; from pathlib import Path; from omnidev.daemon.control import request\n"
        "try:\n    request(Path(sys.argv[1]), 'status')\n"
        "except Exception as e:\n    print(type(e).__name__, e)\n"
    )
    repo = Path(__file__).resolve().parents[1]
    drop = ["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups"]
    proc = subprocess.run(
        [*drop, sys.executable, "-c", code, str(srv.path)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd="/",
        env={**os.environ, "PYTHONPATH": str(repo)},
    )
    if "Permission denied" in proc.stderr and "omnidev" not in proc.stdout:
        pytest.skip(f"user nobody cannot run this Python environment: {proc.stderr.strip()[:200]}")
    assert proc.stdout.startswith("ControlError "), proc.stdout + proc.stderr
    assert "permission denied" in proc.stdout
    assert "sudo omnidev ctl" in proc.stdout


# -- omnidev ctl -------------------------------------------------------------


def ctl(*argv: str) -> int:
    parser = argparse.ArgumentParser(prog="omnidev")
    sub = parser.add_subparsers(dest="command", required=True)
    ctl_cmd.register(sub)
    args = parser.parse_args(["ctl", *argv])
    return int(args.func(args))


def test_ctl_status_human(server, capsys):
    srv, _ = server
    assert ctl("status", "--socket", str(srv.path)) == 0
    out = capsys.readouterr().out
    assert "state:           running" in out
    assert "fps:             60.00" in out
    assert "latency:         p50 1.25 ms, p99 3.50 ms" in out
    assert "frames:          120 (dropped 2)" in out
    assert "sink:            record" in out
    assert "source:          video:fixtures/blob/blob.avi?loop=1" in out
    assert "uptime:          00:00:02" in out


def test_ctl_json_and_pause_resume(server, capsys):
    srv, daemon = server
    assert ctl("status", "--socket", str(srv.path), "--json") == 0
    assert json.loads(capsys.readouterr().out) == {"ok": True, **daemon.status()}
    assert ctl("pause", "--socket", str(srv.path)) == 0
    assert capsys.readouterr().out.strip() == "omnidevd: pause ok, state paused"
    assert daemon.paused
    assert ctl("resume", "--socket", str(srv.path)) == 0
    assert capsys.readouterr().out.strip() == "omnidevd: resume ok, state running"
    assert ctl("reload", "--socket", str(srv.path)) == 0
    assert capsys.readouterr().out.strip() == "omnidevd: reload ok, state running, reloaded 1"


def test_ctl_errors_are_omnidev_errors(short_tmp):
    with pytest.raises(ControlError, match="is omnidevd running"):
        ctl("status", "--socket", str(short_tmp / "missing.sock"))

    def refuse(cmd: str, args: dict[str, Any]) -> dict[str, Any]:
        raise ConfigError("[sink] name: unknown sink 'nope'")

    with ControlServer(short_tmp / "c.sock", refuse) as srv:
        with pytest.raises(ControlError, match=r"refused 'reload': \[sink\] name: unknown sink"):
            ctl("reload", "--socket", str(srv.path))


def test_ctl_rejects_unknown_action():
    with pytest.raises(SystemExit):
        ctl("shutdown")


def test_ctl_through_the_omnidev_command(server):
    """Once the lead registers ctl_cmd in omnidev.cli.main, the real command works too."""
    from omnidev.cli import main as cli_main

    if "ctl_cmd" not in cli_main.SUBCOMMANDS:
        pytest.skip("ctl_cmd is not yet in omnidev.cli.main.SUBCOMMANDS")
    srv, _ = server
    proc = subprocess.run(
        [sys.executable, "-m", "omnidev.cli.main", "ctl", "status", "--socket", str(srv.path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert "state:           running" in proc.stdout
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "omnidev.cli.main",
            "ctl",
            "status",
            "--socket",
            "/nonexistent.sock",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0
    assert "is omnidevd running?" in proc.stderr

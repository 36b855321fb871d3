"""omnidevd's control socket: one JSON request per line in, one JSON reply per line out.

The daemon serves a Unix stream socket (default :data:`DEFAULT_SOCKET`, in the
``RuntimeDirectory=omnidev`` systemd creates) with mode 0600, so only the
daemon's user and root can talk to it. Protocol, UTF-8, newline-terminated::

    -> {"cmd": "status"}
    <- {"ok": true, "state": "running", "fps": 29.97, ...}
    -> {"cmd": "bogus"}
    <- {"ok": false, "error": "unknown command 'bogus' (known: status, pause, ...)"}
    -> {"cmd": "view", "view": "ptz", "moves": ["pan=+10", "fov=60"]}
    <- {"ok": true, "view": "ptz", "target": {"pan": 10.0, "tilt": 0.0, "fov": 60.0}, ...}

A connection may send several requests; each gets exactly one reply line.
Malformed JSON, a non-object, a missing ``cmd`` or an unknown command get an
``ok: false`` reply and never stop the server. The handler (the daemon) is
called as ``handler(cmd, args)`` with ``args`` the request without ``cmd``; calls
are serialized, so the handler needs no lock of its own. An
:class:`~omnidev.errors.OmnidevError` it raises becomes ``{"ok": false, "error":
str(exc)}``; any other exception is logged with its traceback and reported as an
internal error. Non-finite floats in a reply (NaN fps before the first frame)
are sent as null.

:class:`ControlServer` is the daemon's side, :func:`request` the client's
(``omnidev ctl``).
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import math
import os
import select
import socket
import stat
import threading
from collections.abc import Callable, Iterable
from pathlib import Path
from types import TracebackType
from typing import Any

from omnidev.errors import OmnidevError

log = logging.getLogger(__name__)

DEFAULT_SOCKET = Path("/run/omnidev/control.sock")
"""Where omnidevd listens unless its configuration says otherwise ([daemon] socket)."""

COMMANDS: tuple[str, ...] = ("status", "pause", "resume", "reload", "view")
"""The commands the server passes to its handler; anything else is refused."""

MAX_REQUEST_BYTES = 65536
"""A request line longer than this is refused and the connection closed."""

MAX_CONNECTIONS = 32
"""Connections served at once; one more gets an error reply and is closed at once."""

MAX_NESTING = 32
"""Deepest JSON nesting of a request (a request is one flat object)."""

CLIENT_IDLE_TIMEOUT_S = 30.0
"""A connection silent for this long is closed (so a stuck client holds nothing)."""

Handler = Callable[[str, dict[str, Any]], dict[str, Any]]

__all__ = [
    "COMMANDS",
    "DEFAULT_SOCKET",
    "ControlError",
    "ControlServer",
    "Handler",
    "check_free",
    "request",
]


class ControlError(OmnidevError):
    """The control socket cannot be created, reached, or answered with a malformed reply."""


def _json_safe(value: Any) -> Any:
    """``value`` with non-finite floats replaced by None (JSON has no NaN/inf).

    >>> _json_safe({"fps": float("nan"), "n": [1, float("inf"), 2.5]})
    {'fps': None, 'n': [1, None, 2.5]}
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def _encode(reply: dict[str, Any]) -> bytes:
    return (json.dumps(_json_safe(reply), allow_nan=False) + "\n").encode("utf-8")


def _error(message: str) -> dict[str, Any]:
    return {"ok": False, "error": message}


def _nesting(text: str) -> int:
    """Deepest bracket nesting of ``text`` (strings not excluded: an upper bound)."""
    depth = deepest = 0
    for ch in text:
        if ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def check_free(path: Path) -> None:
    """Raise :class:`ControlError` if a live server answers on ``path`` (a second daemon must
    stop before it opens its camera, tracker or sink) or ``path`` is not a socket."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise ControlError(f"control socket {path}: {exc.strerror}") from None
    if not stat.S_ISSOCK(st.st_mode):
        raise ControlError(
            f"control socket {path}: the path exists and is not a socket; "
            "remove it or configure another [daemon] socket"
        )
    if _live_server_at(path):
        raise ControlError(
            f"control socket {path}: another omnidevd already answers there "
            "(stop it first, or configure another [daemon] socket)"
        )


def _live_server_at(path: Path) -> bool:
    """True if something accepts connections on the Unix socket ``path``."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_CLOEXEC) as probe:
        probe.settimeout(1.0)
        try:
            probe.connect(os.fspath(path))
        except OSError:
            return False
    return True


class ControlServer:
    """Serve the control protocol on the Unix socket ``path`` with ``handler``.

    Args:
        path: socket file to create (its directory is created if missing).
        handler: ``handler(cmd, args) -> reply`` for every command in ``commands``;
            the reply gets ``"ok": true`` added unless it sets ``ok`` itself.
        commands: the accepted command names.

    ``start()`` binds and serves on a daemon thread; ``close()`` stops, closes every
    connection and unlinks the socket (if it is still the one it created). Also
    a context manager.
    """

    def __init__(
        self,
        path: Path,
        handler: Handler,
        *,
        commands: Iterable[str] = COMMANDS,
    ) -> None:
        self.path = Path(path)
        self.handler = handler
        self.commands = tuple(commands)
        self._listener: socket.socket | None = None
        self._inode: tuple[int, int] | None = None
        self._wake_r, self._wake_w = socket.socketpair()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._handler_lock = threading.Lock()
        self._conns: set[socket.socket] = set()
        self._conns_lock = threading.Lock()
        self.refused = 0  # connections refused for being over MAX_CONNECTIONS

    # -- lifecycle ---------------------------------------------------------

    def start(self) -> None:
        """Create the socket (mode 0600) and serve it on a daemon thread.

        Raises:
            ControlError: another server answers on ``path``; ``path`` exists and
                is not a socket; the socket cannot be created (permissions).
        """
        if self._thread is not None:
            raise ControlError(f"control socket {self.path}: server already started")
        self._remove_stale()
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ControlError(
                f"control socket {self.path}: cannot create directory {self.path.parent}: "
                f"{exc.strerror}"
            ) from None
        listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_CLOEXEC)
        old_umask = os.umask(0o177)  # the node is born 0600: no window with a wider mode
        try:
            listener.bind(os.fspath(self.path))
            listener.listen(16)  # at once: a client that sees the file gets an answer
        except OSError as exc:
            listener.close()
            raise ControlError(f"control socket {self.path}: cannot bind: {exc.strerror}") from None
        finally:
            os.umask(old_umask)
        os.chmod(self.path, 0o600)
        st = os.stat(self.path)
        self._inode = (st.st_dev, st.st_ino)
        listener.setblocking(False)
        self._listener = listener
        self._thread = threading.Thread(target=self._serve, name="omnidev-control", daemon=True)
        self._thread.start()
        log.info("control socket listening on %s", self.path)

    def close(self) -> None:
        """Stop serving, close all connections and unlink the socket file."""
        self._stop.set()
        with contextlib.suppress(OSError):
            self._wake_w.send(b"x")
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        with self._conns_lock:
            conns = list(self._conns)
        for conn in conns:
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)
        if self._inode is not None:
            # Checked while our listener still holds the inode, so the number cannot have
            # been reused: a different inode at the path is a successor's socket.
            with contextlib.suppress(OSError):
                st = os.stat(self.path)
                if (st.st_dev, st.st_ino) == self._inode:
                    self.path.unlink()
            self._inode = None
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        self._wake_r.close()
        self._wake_w.close()

    def __enter__(self) -> ControlServer:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _remove_stale(self) -> None:
        """Unlink a socket file left by a dead server; refuse a live one or a non-socket."""
        try:
            st = os.lstat(self.path)
        except FileNotFoundError:
            return
        if not stat.S_ISSOCK(st.st_mode):
            raise ControlError(
                f"control socket {self.path}: the path exists and is not a socket; "
                "remove it or configure another [daemon] socket"
            )
        if _live_server_at(self.path):
            raise ControlError(
                f"control socket {self.path}: another omnidevd already answers there "
                "(stop it first, or configure another [daemon] socket)"
            )
        log.info("removing stale control socket %s", self.path)
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()

    # -- serving -----------------------------------------------------------

    def _serve(self) -> None:
        assert self._listener is not None
        listener = self._listener
        while not self._stop.is_set():
            try:
                readable, _, _ = select.select([listener, self._wake_r], [], [])
            except (OSError, ValueError):
                return  # closed under us
            if self._stop.is_set():
                return
            if listener not in readable:
                continue
            try:
                conn, _ = listener.accept()
            except BlockingIOError:
                continue
            except OSError as exc:
                if self._stop.is_set():
                    return
                log.warning("control socket accept failed: %s", exc)
                continue
            conn.setblocking(True)
            conn.settimeout(CLIENT_IDLE_TIMEOUT_S)
            with self._conns_lock:
                busy = len(self._conns) >= MAX_CONNECTIONS
                if not busy:
                    self._conns.add(conn)
            if busy:
                self._refuse(conn)
                continue
            threading.Thread(
                target=self._serve_connection,
                args=(conn,),
                name="omnidev-control-conn",
                daemon=True,
            ).start()

    def _refuse(self, conn: socket.socket) -> None:
        """Answer a connection over :data:`MAX_CONNECTIONS` with an error and close it."""
        self.refused += 1
        with contextlib.suppress(OSError):
            conn.settimeout(0.5)
            conn.sendall(
                _encode(
                    _error(
                        f"too many control connections (at most {MAX_CONNECTIONS} at once); "
                        "close idle ones and try again"
                    )
                )
            )
        conn.close()

    def _serve_connection(self, conn: socket.socket) -> None:
        buffer = b""
        try:
            while not self._stop.is_set():
                newline = buffer.find(b"\n")
                if newline < 0:
                    if len(buffer) > MAX_REQUEST_BYTES:
                        conn.sendall(
                            _encode(_error(f"request longer than {MAX_REQUEST_BYTES} bytes"))
                        )
                        return
                    chunk = conn.recv(4096)
                    if not chunk:
                        if buffer.strip():  # a last request without its newline
                            conn.sendall(_encode(self._reply(buffer)))
                        return
                    buffer += chunk
                    continue
                line, buffer = buffer[:newline], buffer[newline + 1 :]
                if not line.strip():
                    continue
                conn.sendall(_encode(self._reply(line)))
        except OSError as exc:  # timeouts, peers that went away, close()
            if not self._stop.is_set() and exc.errno not in (errno.EPIPE, errno.ECONNRESET, None):
                log.debug("control connection ended: %s", exc)
        finally:
            with self._conns_lock:
                self._conns.discard(conn)
            conn.close()

    def _reply(self, line: bytes) -> dict[str, Any]:
        """The reply to one request line; never raises."""
        try:
            text = line.decode("utf-8")
            if _nesting(text) > MAX_NESTING:
                return _error(f"malformed request: JSON nested deeper than {MAX_NESTING} levels")
            request_obj = json.loads(text)
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
            return _error(f"malformed request (expected one JSON object per line): {exc}")
        if not isinstance(request_obj, dict):
            return _error('malformed request: expected a JSON object like {"cmd": "status"}')
        cmd = request_obj.pop("cmd", None)
        if not isinstance(cmd, str):
            return _error("malformed request: missing string key 'cmd'")
        if cmd not in self.commands:
            return _error(f"unknown command {cmd!r} (known: {', '.join(self.commands)})")
        try:
            with self._handler_lock:
                reply = self.handler(cmd, request_obj)
        except OmnidevError as exc:
            return _error(str(exc))
        except Exception as exc:
            log.exception("control command %r failed", cmd)
            return _error(f"internal error in {cmd!r}: {type(exc).__name__}: {exc}")
        if not isinstance(reply, dict):
            log.error("control handler returned %r for %r, not a dict", type(reply), cmd)
            return _error(f"internal error in {cmd!r}: handler reply is not an object")
        out: dict[str, Any] = {"ok": True}
        out.update(reply)
        try:
            _encode(out)
        except (TypeError, ValueError) as exc:
            log.error("control reply to %r is not JSON: %s", cmd, exc)
            return _error(f"internal error in {cmd!r}: reply is not JSON serializable: {exc}")
        return out


def request(path: Path, cmd: str, timeout: float = 2.0, **args: Any) -> dict[str, Any]:
    """Send one command to the server at ``path`` and return its reply object.

    Args:
        path: the control socket.
        cmd: ``status``, ``pause``, ``resume``, ``reload`` or ``view``.
        timeout: seconds to wait for connecting and for the reply.
        **args: extra request keys (JSON-serializable).

    Returns:
        The reply as sent: ``{"ok": True, ...}`` or ``{"ok": False, "error": ...}``.

    Raises:
        ControlError: one line saying why nothing answered (no socket, stale
            socket, permission denied, timeout, malformed reply).
    """
    path = Path(path)
    hint = f"is omnidevd running? default socket {DEFAULT_SOCKET}"
    payload = (json.dumps({"cmd": cmd, **args}) + "\n").encode("utf-8")
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_CLOEXEC) as sock:
        sock.settimeout(timeout)
        try:
            sock.connect(os.fspath(path))
        except FileNotFoundError:
            raise ControlError(f"{path}: no control socket ({hint})") from None
        except ConnectionRefusedError:
            raise ControlError(
                f"{path}: nothing answers on this socket, it is stale ({hint})"
            ) from None
        except PermissionError:
            raise ControlError(
                f"{path}: permission denied: the control socket is mode 0600, for the daemon's "
                "user (omnidev) and root only; run `sudo omnidev ctl ...`"
            ) from None
        except TimeoutError:
            raise ControlError(f"{path}: no answer within {timeout:g} s ({hint})") from None
        except OSError as exc:
            raise ControlError(f"{path}: cannot connect: {exc.strerror or exc}") from None
        data = b""
        try:
            # a server refusing the connection has replied and closed: read that reply
            with contextlib.suppress(BrokenPipeError, ConnectionResetError):
                sock.sendall(payload)
            while b"\n" not in data:
                chunk = sock.recv(65536)
                if not chunk:
                    break
                data += chunk
        except TimeoutError:
            raise ControlError(
                f"{path}: omnidevd did not reply to {cmd!r} within {timeout:g} s"
            ) from None
        except OSError as exc:
            raise ControlError(
                f"{path}: connection failed during {cmd!r}: {exc.strerror or exc}"
            ) from None
    line = data.split(b"\n", 1)[0]
    if not line:
        raise ControlError(f"{path}: connection closed without a reply to {cmd!r}")
    try:
        reply = json.loads(line.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise ControlError(f"{path}: malformed reply to {cmd!r}: {line[:200]!r}") from None
    if not isinstance(reply, dict) or not isinstance(reply.get("ok"), bool):
        raise ControlError(f"{path}: malformed reply to {cmd!r} (no boolean 'ok'): {line[:200]!r}")
    return reply

"""A real X server for tests and benchmarks: Xvfb on a free display number.

    from tests.xserver import xvfb, missing_x_tools

    with xvfb(3840, 1080) as display:      # e.g. ":5"
        ...  # DISPLAY=display for Xlib, xdotool, the xtest sink

Xvfb chooses the display number itself (``-displayfd``), so parallel runs never
collide; it reports the number once it accepts connections, and the helper then
also confirms that its socket answers. The server listens on its local socket
only (``-nolisten tcp``) with access control off (``-ac``), so no xauth cookie
is needed. It is terminated (then killed) when the block ends.
"""

from __future__ import annotations

import os
import select
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager


def missing_x_tools(tools: Sequence[str] = ("Xvfb", "xdotool")) -> str | None:
    """A skip reason naming the X tools that are not installed, or None when all are."""
    missing = [t for t in tools if shutil.which(t) is None]
    if not missing:
        return None
    return (
        f"{' and '.join(missing)} not installed (Debian packages xvfb, xdotool; "
        "scripts/install-system-deps.sh installs them)"
    )


@contextmanager
def xvfb(
    width: int = 1920,
    height: int = 1080,
    *,
    depth: int = 24,
    more_screens: Sequence[tuple[int, int]] = (),
    args: Sequence[str] = (),
    timeout_s: float = 10.0,
) -> Iterator[str]:
    """Run Xvfb with screen 0 of ``width`` x ``height`` pixels; yields its DISPLAY (``":N"``).

    Args:
        width, height: size of screen 0 (its root window), pixels.
        depth: bits per pixel of every screen.
        more_screens: sizes of screens 1, 2, ... (separate X screens, ``:N.1`` ...).
        args: extra Xvfb arguments (e.g. ``["-tst"]`` to leave out XTEST).
        timeout_s: how long to wait for the server to accept connections.

    Raises:
        RuntimeError: Xvfb is not installed, exited, or did not become ready in time.
    """
    exe = shutil.which("Xvfb")
    if exe is None:
        raise RuntimeError("Xvfb is not installed (Debian package xvfb)")
    read_fd, write_fd = os.pipe()
    cmd = [exe, "-displayfd", str(write_fd), "-nolisten", "tcp", "-ac", "-noreset"]
    for i, (w, h) in enumerate([(width, height), *more_screens]):
        cmd += ["-screen", str(i), f"{w}x{h}x{depth}"]
    cmd += list(args)
    log = tempfile.TemporaryFile()  # noqa: SIM115 (closed in finally)
    proc = subprocess.Popen(
        cmd, pass_fds=(write_fd,), stdin=subprocess.DEVNULL, stdout=log, stderr=log
    )
    os.close(write_fd)
    try:
        try:
            number = _read_display_number(read_fd, proc, timeout_s)
            _wait_for_socket(number, proc, timeout_s)
        except RuntimeError as exc:
            log.seek(0)
            tail = log.read().decode(errors="replace").strip().splitlines()[-5:]
            raise RuntimeError(f"{exc}: {' | '.join(tail)}") from None
        yield f":{number}"
    finally:
        os.close(read_fd)
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        log.close()


def _read_display_number(fd: int, proc: subprocess.Popen[bytes], timeout_s: float) -> int:
    """The display number Xvfb writes to ``-displayfd`` when it is ready."""
    deadline = time.monotonic() + timeout_s
    data = b""
    while not data.endswith(b"\n"):
        left = deadline - time.monotonic()
        if left <= 0:
            raise RuntimeError(f"Xvfb did not report a display within {timeout_s} s")
        ready, _, _ = select.select([fd], [], [], min(left, 0.1))
        if ready:
            chunk = os.read(fd, 64)
            if not chunk:
                raise RuntimeError(f"Xvfb exited with status {proc.wait()}")
            data += chunk
        elif proc.poll() is not None:
            raise RuntimeError(f"Xvfb exited with status {proc.returncode}")
    return int(data.strip())


def _wait_for_socket(number: int, proc: subprocess.Popen[bytes], timeout_s: float) -> None:
    """Return once the server's local socket accepts a connection."""
    path = f"/tmp/.X11-unix/X{number}"
    deadline = time.monotonic() + timeout_s
    while True:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            try:
                s.connect(path)
                return
            except OSError:
                pass
        if proc.poll() is not None:
            raise RuntimeError(f"Xvfb exited with status {proc.returncode}")
        if time.monotonic() > deadline:
            raise RuntimeError(f"Xvfb display :{number} does not accept connections at {path}")
        time.sleep(0.02)


# -- reading the pointer back from the server (a second client, not the sink) ------

BUTTON_MASKS = {"left": 1 << 8, "middle": 1 << 9, "right": 1 << 10}  # X11 Button1..3Mask
X_BUTTON_NAMES = {1: "left", 2: "middle", 3: "right"}


def xdotool_location(display: str) -> tuple[int, int, int]:
    """``xdotool getmouselocation --shell``: the pointer's root pixel (x, y) and screen."""
    out = subprocess.run(
        ["xdotool", "getmouselocation", "--shell"],
        env={**os.environ, "DISPLAY": display},
        capture_output=True,
        text=True,
        check=True,
        timeout=10,
    ).stdout
    values = dict(line.split("=", 1) for line in out.splitlines() if "=" in line)
    return int(values["X"]), int(values["Y"]), int(values["SCREEN"])


def buttons_down(display: str) -> set[str]:
    """The buttons the X server holds down, from the core pointer's QueryPointer mask."""
    from Xlib.display import Display

    d = Display(display)
    try:
        mask = int(d.screen().root.query_pointer().mask)
    finally:
        d.close()
    return {name for name, bit in BUTTON_MASKS.items() if mask & bit}


def xdotool_release_all(display: str) -> None:
    """Release buttons 1-3 through xdotool (cleanup after a deliberately stuck button)."""
    for b in ("1", "2", "3"):
        subprocess.run(
            ["xdotool", "mouseup", b],
            env={**os.environ, "DISPLAY": display},
            check=True,
            timeout=10,
        )


class PointerListener:
    """Pointer events the X server delivers to its root window, seen by another client.

    Selects MotionNotify, ButtonPress and ButtonRelease on screen ``screen``'s root
    (an Xvfb with no other clients has no child windows, so the root receives them).
    :meth:`events` returns what arrived since the last call, as ``("move", x, y)``
    in root pixels and ``("press" | "release", button name)``.
    """

    def __init__(self, display: str, screen: int = 0) -> None:
        from Xlib import X
        from Xlib.display import Display

        self._x = X
        self._d = Display(display)
        self._d.screen(screen).root.change_attributes(
            event_mask=X.PointerMotionMask | X.ButtonPressMask | X.ButtonReleaseMask
        )
        self._d.sync()

    def events(self) -> list[tuple[object, ...]]:
        """Events received so far (a round trip first, so all sent before now are in)."""
        self._d.sync()
        out: list[tuple[object, ...]] = []
        while self._d.pending_events():
            e = self._d.next_event()
            if e.type == self._x.MotionNotify:
                out.append(("move", int(e.root_x), int(e.root_y)))
            elif e.type in (self._x.ButtonPress, self._x.ButtonRelease):
                kind = "press" if e.type == self._x.ButtonPress else "release"
                out.append((kind, X_BUTTON_NAMES.get(int(e.detail), int(e.detail))))
        return out

    def close(self) -> None:
        self._d.close()

    def __enter__(self) -> PointerListener:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

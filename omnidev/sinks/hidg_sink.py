"""``hidg`` sink: the omnidev box as a USB mouse of another computer (Linux HID gadget).

The gadget (made by ``udev/omnidev-gadget.sh``, see docs/hid-gadget.md) gives a
device node /dev/hidgN; every report written to it is sent to the USB host the
next time the host polls the interrupt endpoint. Reports are packed by
:mod:`omnidev.hid_reports`.

Modes (option ``mode``, which must match the gadget script's ``--mode``):

- ``absolute``: each report carries the buttons and the position in device units
  0 .. 32767 spanning the host's whole desktop layout
  (:meth:`~omnidev.screen.ScreenMapping.to_device`), so the target screen
  rectangle of a multi-monitor layout is reached exactly. Before the first move a
  button report carries the target screen's centre.
- ``relative``: each report carries buttons and signed 8-bit deltas in mouse
  counts. The sink keeps the position it has sent so far in *layout pixels*
  (:meth:`~omnidev.screen.ScreenMapping.to_pixel`) and sends the difference to the
  new one, split into steps of at most 127 counts. With ``home`` (the default) the
  first report pushes the pointer by minus the layout size to the layout's
  top-left corner, where the host clamps it, so the sent position starts known.
  Relative mode cannot guarantee absolute placement: the host applies its pointer
  acceleration and speed to the counts (one count is one pixel only with a flat
  1:1 profile), and any other mouse moves the same pointer.

Never blocking the pipeline: the node is opened ``O_WRONLY | O_NONBLOCK``; the
kernel holds at most one report in flight, and a write waits at most
``timeout_ms`` for it to be taken (``poll``). When the host does not take it
(it is not polling, e.g. nobody opened the device on the host) the report is
dropped and counted (``dropped`` in :meth:`HidgSink.stats`), and later writes do
not wait at all until one succeeds again. Nothing stale is queued in the sink: a
report holds the whole state (absolute position or, in relative mode, all the
motion not yet delivered), so the next write carries the latest state. The one
report the kernel already holds is delivered when the host polls again. On close
the sink retries the last state (buttons released) for up to ``close_timeout_ms``.
"""

from __future__ import annotations

import errno
import os
import select
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from omnidev.errors import SinkError
from omnidev.hid_reports import (
    BUTTON_BITS,
    DESCRIPTORS,
    MODES,
    REPORT_LENGTHS,
    Mode,
    pack_absolute,
    pack_relative,
)
from omnidev.screen import ScreenMapping
from omnidev.sinks.base import PointerSink

DEFAULT_DEVICE = "/dev/hidg0"
CONFIGFS_GADGETS = Path("/sys/kernel/config/usb_gadget")
SETUP_HINT = (
    "set up the USB gadget first: run udev/omnidev-gadget.sh as root, or "
    "systemctl enable --now omnidev-gadget.service (docs/hid-gadget.md)"
)
_HOST_GONE = {errno.ESHUTDOWN, errno.EPIPE, errno.ENODEV, errno.ECONNRESET}


class HostGoneError(SinkError):
    """The USB host is not there: cable out, host off or asleep, gadget unbound."""


class HidgSink(PointerSink):
    """Writes mouse reports to a Linux USB HID gadget node (/dev/hidgN).

    Attributes:
        device: the node path; mode: ``absolute`` or ``relative``.
        reports: reports handed to the kernel; dropped: reports dropped because the
            host did not take the previous one within the timeout.
    """

    name = "hidg"

    def __init__(
        self,
        mapping: ScreenMapping,
        *,
        device: str = DEFAULT_DEVICE,
        mode: Mode = "absolute",
        timeout_ms: float = 20.0,
        close_timeout_ms: float = 250.0,
        home: bool = True,
    ) -> None:
        super().__init__(mapping)
        if mode not in MODES:
            raise SinkError(f"hidg sink: mode {mode!r} is not absolute or relative")
        self.device = device
        self.mode: Mode = mode
        self.timeout_ms = float(timeout_ms)
        self.close_timeout_ms = float(close_timeout_ms)
        self.reports = 0
        self.dropped = 0
        self._stalled = False  # the last write timed out: do not wait until one succeeds
        self._buttons = 0
        # absolute: the target and the last report handed to the kernel
        self._target_abs = mapping.to_device(0.5, 0.5)
        self._delivered_abs: bytes | None = None
        # relative: target and sent position in layout pixels, homing still to send
        self._target_px: tuple[int, int] | None = None
        self._sent_px: tuple[int, int] | None = None if home else (0, 0)
        self._home_left = (mapping.layout_width, mapping.layout_height) if home else (0, 0)
        self._delivered_buttons = 0
        self._fd = self._open(device)
        try:
            _check_gadget_mode(device, os.fstat(self._fd).st_rdev, mode)
        except SinkError:
            os.close(self._fd)
            raise
        self._poll = select.poll()
        self._poll.register(self._fd, select.POLLOUT)

    @staticmethod
    def _open(device: str) -> int:
        try:
            return os.open(device, os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        except FileNotFoundError:
            raise SinkError(f"hidg sink: {device} does not exist: {SETUP_HINT}") from None
        except PermissionError:
            raise SinkError(
                f"hidg sink: {device} is not writable by this user: install "
                "udev/60-omnidev.rules (it gives /dev/hidgN to group input, mode 0660; "
                "then re-run the gadget setup) and add the user to group input"
            ) from None
        except OSError as exc:
            if exc.errno in (errno.ENXIO, errno.ENODEV):
                raise SinkError(
                    f"hidg sink: {device} has no gadget function behind it: {SETUP_HINT}"
                ) from None
            raise SinkError(f"hidg sink: cannot open {device}: {exc.strerror}") from None

    # -- PointerSink -----------------------------------------------------------------
    def _move(self, nx: float, ny: float) -> None:
        if self.mode == "absolute":
            self._target_abs = self.mapping.to_device(nx, ny)
        else:
            self._target_px = self.mapping.to_pixel(nx, ny)

    def _button(self, button: str, down: bool) -> None:
        bit = BUTTON_BITS[button]
        self._buttons = (self._buttons | bit) if down else (self._buttons & ~bit)

    def _flush(self) -> None:
        self._send(self.timeout_ms)

    def close(self) -> None:
        """Release every button, then the node. Safe to call twice.

        When the host is gone (:class:`HostGoneError`) there is nothing to release on
        it (a USB host drops a vanished mouse's buttons), so closing does not fail.
        """
        try:
            super().close()
        except SinkError as exc:
            if not isinstance(exc.__cause__, HostGoneError):
                raise

    def _close(self) -> None:
        try:
            if self._pending():  # the last state (buttons released) was dropped: retry
                self._stalled = False
                self._send(self.close_timeout_ms)
        except SinkError:
            pass
        finally:
            os.close(self._fd)

    def stats(self) -> dict[str, Any]:
        """Counters: ``reports`` handed to the kernel, ``dropped`` reports, and the base's."""
        return {
            **super().stats(),
            "device": self.device,
            "mode": self.mode,
            "reports": self.reports,
            "dropped": self.dropped,
        }

    # -- reports ---------------------------------------------------------------------
    def _pending(self) -> bool:
        """Whether the latest state has not been handed to the kernel yet."""
        if self.mode == "absolute":
            return self._delivered_abs != pack_absolute(self._buttons, *self._target_abs)
        dx, dy = self._relative_delta()
        return dx != 0 or dy != 0 or self._buttons != self._delivered_buttons

    def _relative_delta(self) -> tuple[int, int]:
        """Counts still to send: the homing push first, then target minus sent position."""
        if self._home_left != (0, 0):
            return -self._home_left[0], -self._home_left[1]
        if self._target_px is None or self._sent_px is None:
            return 0, 0
        return self._target_px[0] - self._sent_px[0], self._target_px[1] - self._sent_px[1]

    def _send(self, timeout_ms: float) -> None:
        if self.mode == "absolute":
            report = pack_absolute(self._buttons, *self._target_abs)
            if report != self._delivered_abs and self._write(report, timeout_ms):
                self._delivered_abs = report
            return
        while self._pending():
            homing = self._home_left != (0, 0)
            dx, dy = self._relative_delta()
            for report in pack_relative(self._buttons, dx, dy):
                if not self._write(report, timeout_ms):
                    return  # the rest stays pending for the next write
                sx, sy = _signed8(report[1]), _signed8(report[2])
                self._delivered_buttons = report[0]
                if homing:
                    self._home_left = (self._home_left[0] + sx, self._home_left[1] + sy)
                    if self._home_left == (0, 0):
                        self._sent_px = (0, 0)  # clamped at the layout's top-left
                elif self._sent_px is not None:
                    self._sent_px = (self._sent_px[0] + sx, self._sent_px[1] + sy)

    def _write(self, report: bytes, timeout_ms: float) -> bool:
        """Hand one report to the kernel; False (and counted) when it was dropped."""
        wait = 0 if self._stalled else max(0, round(timeout_ms))
        try:
            # Wait for the report in flight to be taken, then write in any case: a
            # gadget the host has not configured (or that was disconnected) is never
            # writable, and only the write tells it apart (ESHUTDOWN, not EAGAIN).
            self._poll.poll(wait)
            written = os.write(self._fd, report)
        except BlockingIOError:
            return self._drop()
        except OSError as exc:
            if exc.errno in _HOST_GONE:
                raise HostGoneError(
                    f"hidg sink: {self.device}: the USB host has not configured the gadget "
                    f"({errno.errorcode.get(exc.errno or 0, exc.errno)}): cable unplugged, host "
                    "off or asleep, or the gadget unbound"
                ) from None
            raise SinkError(f"hidg sink: writing {self.device}: {exc.strerror}") from None
        if written != len(report):
            raise SinkError(
                f"hidg sink: {self.device} took {written} of {len(report)} bytes: the gadget's "
                f"report_length does not match {self.mode} mode ({SETUP_HINT})"
            )
        self._stalled = False
        self.reports += 1
        return True

    def _drop(self) -> bool:
        self.dropped += 1
        self._stalled = True
        return False


def _signed8(b: int) -> int:
    return b - 256 if b > 127 else b


def _check_gadget_mode(device: str, rdev: int, mode: Mode) -> None:
    """Refuse a gadget whose report descriptor is omnidev's other mode (read from configfs).

    Best effort: when configfs is not mounted or not readable nothing is checked.
    """
    want = f"{os.major(rdev)}:{os.minor(rdev)}"
    try:
        functions = list(CONFIGFS_GADGETS.glob("*/functions/hid.*"))
    except OSError:
        return
    for fn in functions:
        try:
            if (fn / "dev").read_text().strip() != want:
                continue
            desc = (fn / "report_desc").read_bytes()
            length = int((fn / "report_length").read_text())
        except (OSError, ValueError):
            return
        for other, other_desc in DESCRIPTORS.items():
            if other != mode and desc == other_desc:
                raise SinkError(
                    f"hidg sink: {device} is set up in {other} mode but the sink's mode is "
                    f"{mode}: set mode = {other!r}, or run omnidev-gadget.sh --mode {mode}"
                )
        if length != REPORT_LENGTHS[mode]:
            raise SinkError(
                f"hidg sink: {device} has {length}-byte reports ({fn}), {mode} mode writes "
                f"{REPORT_LENGTHS[mode]}: run omnidev-gadget.sh --mode {mode}"
            )
        return


def open_hidg(options: Mapping[str, Any], mapping: ScreenMapping) -> HidgSink:
    """Entry point. Options:

    - ``device``: the gadget node (default /dev/hidg0);
    - ``mode``: ``absolute`` (default) or ``relative``, as the gadget was set up;
    - ``timeout_ms``: longest wait for the host to take the previous report (default 20);
    - ``home``: relative mode only, push to the top-left corner first (default true).
    """
    return HidgSink(mapping, **_settings(options))


def check_hidg(options: Mapping[str, Any], mapping: ScreenMapping) -> str:
    """What ``omnidev daemon --check`` checks: the options, and that the gadget node opens for
    writing in the configured mode (closed again; no report is sent)."""
    settings = _settings(options)
    fd = HidgSink._open(settings["device"])
    try:
        _check_gadget_mode(settings["device"], os.fstat(fd).st_rdev, settings["mode"])
    finally:
        os.close(fd)
    return f"hidg: {settings['device']} writable ({settings['mode']})"


open_hidg.check = check_hidg  # type: ignore[attr-defined]


def _settings(options: Mapping[str, Any]) -> dict[str, Any]:
    known = {"device", "mode", "timeout_ms", "home"}
    unknown = set(options) - known
    if unknown:
        raise SinkError(
            f"hidg sink: unknown option {sorted(unknown)[0]!r} "
            f"(options: {', '.join(sorted(known))})"
        )
    device = options.get("device", DEFAULT_DEVICE)
    if not isinstance(device, str) or not device or "\0" in device:
        raise SinkError("hidg sink: option 'device' must be a path such as /dev/hidg0")
    mode = options.get("mode", "absolute")
    if mode not in MODES:
        raise SinkError(f"hidg sink: option 'mode' is {mode!r}, not 'absolute' or 'relative'")
    timeout = options.get("timeout_ms", 20)
    if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0 <= timeout <= 1e4:
        raise SinkError(f"hidg sink: option 'timeout_ms' is {timeout!r}, not a number >= 0")
    home = options.get("home", True)
    if not isinstance(home, bool):
        raise SinkError(f"hidg sink: option 'home' is {home!r}, not true or false")
    return {"device": device, "mode": mode, "timeout_ms": float(timeout), "home": home}

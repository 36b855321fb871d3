"""``uinput`` sink: one kernel absolute pointer through /dev/uinput.

The device has EV_ABS ABS_X/ABS_Y over 0 .. :data:`~omnidev.screen.ABS_MAX`
spanning the whole desktop layout (see :mod:`omnidev.screen`), with a
resolution in device units per millimetre, EV_KEY BTN_LEFT/BTN_RIGHT/BTN_MIDDLE,
INPUT_PROP_DIRECT, and no relative axes: udev tags it ID_INPUT_MOUSE and libinput
treats it as an absolute pointer (not a tablet or a touchscreen). It is created
on bus BUS_VIRTUAL with a distinctive name and ``phys`` tag, so omnidev's daemon
and udev rules can recognise (and skip) their own device.

How it is made: python-uinput's ``Device`` writes the legacy
``struct uinput_user_dev`` (name, ids, axis ranges) and issues UI_DEV_CREATE, but
cannot set phys, input properties or axis resolution. So this module opens
/dev/uinput itself, sets those with the UI_SET_PHYS, UI_SET_PROPBIT and
UI_ABS_SETUP ioctls, and hands the descriptor to ``uinput.Device(fd=...)``; the
kernel's legacy setup path overwrites only min/max/fuzz/flat of each axis and
keeps the resolution set by UI_ABS_SETUP (checked on a real kernel by
tests/vm/test_uinput.py). python-uinput 1.0.1's device creation does not sleep.

The OS bindings (python-uinput, fcntl ioctls) are imported inside the functions
that use them, so importing this module works on any machine.
"""

from __future__ import annotations

import errno
import os
import struct
from collections.abc import Mapping
from typing import Any

from omnidev.errors import SinkError
from omnidev.evdev_find import device_info
from omnidev.screen import ABS_MAX, ScreenMapping
from omnidev.sinks.base import PointerSink

DEFAULT_NAME = "omnidev absolute pointer"
DEFAULT_PHYS = "omnidev/pointer0"
DEFAULT_DEVICE = "/dev/uinput"
DEFAULT_RESOLUTION = 100  # device units per mm when the screen size is not given
OPTIONS = ("device", "name", "phys", "resolution", "screen_mm")

BUS_VIRTUAL = 0x06
INPUT_PROP_DIRECT = 0x01
ABS_X, ABS_Y = 0x00, 0x01
UINPUT_MAX_NAME_SIZE = 80  # including the terminating NUL


def _ioc(direction: int, nr: int, size: int) -> int:
    """Linux ``_IOC(dir, 'U', nr, size)`` for the uinput ioctls (dir 1 = write, 2 = read)."""
    return (direction << 30) | (size << 16) | (ord("U") << 8) | nr


# struct uinput_abs_setup { __u16 code; struct input_absinfo absinfo; }:
# code, 2 bytes padding, then value, minimum, maximum, fuzz, flat, resolution (__s32).
ABS_SETUP = struct.Struct("=H2x6i")
UI_ABS_SETUP = _ioc(1, 4, ABS_SETUP.size)
UI_SET_PHYS = _ioc(1, 108, struct.calcsize("P"))  # _IOW('U', 108, char *)
UI_SET_PROPBIT = _ioc(1, 110, struct.calcsize("i"))  # _IOW('U', 110, int)


def ui_get_sysname(length: int) -> int:
    """``_IOC(_IOC_READ, 'U', 44, len)``: the created device's sysfs name, ``inputN``."""
    return _ioc(2, 44, length)


def open_uinput_node(path: str) -> int:
    """Open the uinput control node for writing; errors say which fix applies."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        if exc.errno in (errno.ENOENT, errno.ENODEV, errno.ENXIO):
            raise SinkError(
                f"uinput sink: {path} missing: load the module (modprobe uinput; "
                f"udev/modules-load.d/omnidev.conf loads it at boot)"
            ) from None
        if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise SinkError(
                f"uinput sink: {path} not writable: install udev/60-omnidev.rules "
                f"(GROUP=input, MODE=0660) and add the user to group input "
                f"(sudo usermod -aG input $USER, then log in again)"
            ) from None
        raise SinkError(f"uinput sink: cannot open {path}: {exc.strerror}") from None
    if fd == 0:  # python-uinput treats fd 0 as "open one yourself"
        import fcntl

        moved = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 3)
        os.close(fd)
        fd = moved
    return fd


class UinputSink(PointerSink):
    """An absolute pointer device created through /dev/uinput.

    Attributes:
        device: the uinput control node it was created through.
        device_name, phys: the input device's name and phys tag.
        resolution: (x, y) axis resolution, device units per mm.
        sysname: ``inputN`` of the created device in /sys/class/input, or None.
        event_node: its ``/dev/input/eventN``, or None when it cannot be found.
    """

    name = "uinput"

    def __init__(
        self,
        mapping: ScreenMapping,
        *,
        device: str = DEFAULT_DEVICE,
        name: str = DEFAULT_NAME,
        phys: str = DEFAULT_PHYS,
        resolution: tuple[int, int] = (DEFAULT_RESOLUTION, DEFAULT_RESOLUTION),
    ) -> None:
        super().__init__(mapping)
        self.closed = True  # until the device exists (so __del__/close do nothing)
        self.device = device
        self.device_name = name
        self.phys = phys
        self.resolution = resolution
        if not name or len(name.encode()) >= UINPUT_MAX_NAME_SIZE:
            raise SinkError(
                f"uinput sink: name {name!r} must be 1..{UINPUT_MAX_NAME_SIZE - 1} bytes"
            )
        try:
            import uinput
        except (ImportError, OSError) as exc:
            raise SinkError(
                f"uinput sink: python-uinput is not usable ({exc}); "
                f"install it with pip install 'omnidev[hw]' (it needs libudev)"
            ) from None
        self._uinput: Any = uinput
        fd = open_uinput_node(device)
        try:
            self._setup_fd(fd)
            self._dev: Any = uinput.Device(
                [
                    (*uinput.ABS_X, 0, ABS_MAX, 0, 0),
                    (*uinput.ABS_Y, 0, ABS_MAX, 0, 0),
                    uinput.BTN_LEFT,
                    uinput.BTN_RIGHT,
                    uinput.BTN_MIDDLE,
                ],
                name=name,
                bustype=BUS_VIRTUAL,
                vendor=0,
                product=0,
                version=1,
                fd=fd,
            )
        except OSError as exc:
            os.close(fd)
            raise SinkError(f"uinput sink: creating the device failed: {exc.strerror}") from None
        self.closed = False
        self._fd = fd
        self.sysname = self._sysname()
        info = device_info(self.sysname) if self.sysname else None
        self.event_node: str | None = info.event_node if info else None
        self._buttons = {
            "left": uinput.BTN_LEFT,
            "right": uinput.BTN_RIGHT,
            "middle": uinput.BTN_MIDDLE,
        }

    def _setup_fd(self, fd: int) -> None:
        """Phys, INPUT_PROP_DIRECT and the two axes (range and resolution) before creation."""
        import fcntl

        fcntl.ioctl(fd, UI_SET_PHYS, self.phys.encode() + b"\0")
        fcntl.ioctl(fd, UI_SET_PROPBIT, INPUT_PROP_DIRECT)
        for code, res in ((ABS_X, self.resolution[0]), (ABS_Y, self.resolution[1])):
            fcntl.ioctl(fd, UI_ABS_SETUP, ABS_SETUP.pack(code, 0, 0, ABS_MAX, 0, 0, res))

    def _sysname(self) -> str | None:
        import fcntl

        buf = bytearray(64)
        try:
            fcntl.ioctl(self._fd, ui_get_sysname(len(buf)), buf, True)
        except OSError:
            return None
        return bytes(buf).split(b"\0", 1)[0].decode() or None

    def _emit(self, event: tuple[int, int], value: int) -> None:
        try:
            self._dev.emit(event, value, syn=False)
        except OSError as exc:
            raise SinkError(f"uinput sink: writing to {self.device}: {exc.strerror}") from None

    def _move(self, nx: float, ny: float) -> None:
        x, y = self.mapping.to_device(nx, ny, ABS_MAX)
        self._emit(self._uinput.ABS_X, x)
        self._emit(self._uinput.ABS_Y, y)

    def _button(self, button: str, down: bool) -> None:
        self._emit(self._buttons[button], 1 if down else 0)

    def _flush(self) -> None:
        try:
            self._dev.syn()
        except OSError as exc:
            raise SinkError(f"uinput sink: writing to {self.device}: {exc.strerror}") from None

    def _close(self) -> None:
        try:
            self._dev.destroy()  # UI_DEV_DESTROY, then closes the descriptor
        except OSError as exc:
            raise SinkError(f"uinput sink: destroying the device: {exc.strerror}") from None

    def stats(self) -> dict[str, Any]:
        return {**super().stats(), "event_node": self.event_node, "phys": self.phys}

    def __enter__(self) -> UinputSink:
        return self


def resolution_for(mapping: ScreenMapping, screen_mm: tuple[float, float]) -> tuple[int, int]:
    """Device units per mm on x and y, given the target screen's physical size in mm.

    >>> resolution_for(ScreenMapping.single(1920, 1080), (527.0, 296.0))
    (62, 111)
    """
    w_mm, h_mm = screen_mm
    s = mapping.screen
    rx = ABS_MAX * s.width / (max(mapping.layout_width - 1, 1) * w_mm)
    ry = ABS_MAX * s.height / (max(mapping.layout_height - 1, 1) * h_mm)
    return max(round(rx), 1), max(round(ry), 1)


def _parse_screen_mm(value: Any) -> tuple[float, float]:
    try:
        if isinstance(value, str):
            w, h = (float(v) for v in value.lower().split("x"))
        else:
            w, h = (float(v) for v in value)
    except (TypeError, ValueError):
        w = h = 0.0
    if not (0 < w < 1e5 and 0 < h < 1e5):
        raise SinkError(f"uinput sink: screen_mm={value!r} must be WxH in mm (e.g. 527x296)")
    return w, h


def open_uinput(options: Mapping[str, Any], mapping: ScreenMapping) -> UinputSink:
    """Entry point. Options (all optional):

    - ``device``: the uinput node (default /dev/uinput);
    - ``name``, ``phys``: the input device's name and phys tag;
    - ``resolution``: device units per mm on both axes (default 100);
    - ``screen_mm``: the target screen's size ``WxH`` in mm, from which the
      resolution is computed when ``resolution`` is not given.
    """
    return UinputSink(mapping, **_settings(options, mapping))


def check_uinput(options: Mapping[str, Any], mapping: ScreenMapping) -> str:
    """What ``omnidev daemon --check`` checks: the options, and that the uinput node opens
    for writing (no device is created, nothing moves)."""
    settings = _settings(options, mapping)
    os.close(open_uinput_node(settings["device"]))
    return f"uinput: {settings['device']} writable"


open_uinput.check = check_uinput  # type: ignore[attr-defined]


def _settings(options: Mapping[str, Any], mapping: ScreenMapping) -> dict[str, Any]:
    unknown = set(options) - set(OPTIONS)
    if unknown:
        raise SinkError(
            f"uinput sink: unknown option {sorted(unknown)[0]!r} (options: {', '.join(OPTIONS)})"
        )
    for key in ("device", "name", "phys"):
        if key in options and (not isinstance(options[key], str) or "\0" in options[key]):
            raise SinkError(f"uinput sink: option {key!r} must be a string")
    if "resolution" in options:
        res = options["resolution"]
        if isinstance(res, bool) or not isinstance(res, int) or res < 1:
            raise SinkError(
                f"uinput sink: resolution={res!r} must be a positive integer (units/mm)"
            )
        resolution = (res, res)
    elif "screen_mm" in options:
        resolution = resolution_for(mapping, _parse_screen_mm(options["screen_mm"]))
    else:
        resolution = (DEFAULT_RESOLUTION, DEFAULT_RESOLUTION)
    return {
        "device": options.get("device", DEFAULT_DEVICE),
        "name": options.get("name", DEFAULT_NAME),
        "phys": options.get("phys", DEFAULT_PHYS),
        "resolution": resolution,
    }

"""``evdev:`` button input: keys of a Linux input device (python-evdev) as pointer buttons.

Reads /dev/input/eventN without blocking. A key's press (value 1) and release
(value 0) drive its button; autorepeat (value 2) is ignored. When the kernel
reports dropped events (SYN_DROPPED, the reader fell behind) the key state is
read back from the device (EVIOCGKEY) at the next SYN_REPORT. The device is not
grabbed unless the spec says ``grab=1``: without a grab the keys also reach every
other program (the desktop, the console).

python-evdev is imported only when a device is opened, so this module imports on
any machine.
"""

from __future__ import annotations

import contextlib
import errno
import os
from typing import Any

from omnidev.buttons.inputs import ButtonEvent, ButtonInputError, ButtonStates
from omnidev.buttons.spec import EvdevSpec
from omnidev.errors import ConfigError
from omnidev.evdev_find import find_event_nodes, list_devices

PERMISSION_FIX = (
    "add the user to group input (sudo usermod -aG input USER, then log in again; "
    "Debian's udev gives /dev/input/event* to group input, mode 0660) or run omnidevd "
    "with the groups and udev rule of udev/60-omnidev.rules and docs/daemon.md; under "
    "omnidevd.service the unit must allow char-input (sudo make install writes "
    "omnidevd.service.d/10-devices.conf from the configuration)"
)


def _ecodes() -> Any:
    try:
        from evdev import ecodes
    except ImportError:
        raise ButtonInputError(
            "evdev button input: python-evdev is not installed (pip install 'omnidev[hw]' or evdev)"
        ) from None
    return ecodes


def key_codes(spec: EvdevSpec) -> dict[int, str]:
    """Linux key code -> button of the spec (names resolved through evdev.ecodes)."""
    ecodes = _ecodes()
    codes: dict[int, str] = {}
    for name, button in spec.keys:
        if name.isdigit():
            code = int(name)
        else:
            code = ecodes.ecodes.get(name)
            if code is None or not name.startswith(("KEY_", "BTN_")):
                raise ConfigError(
                    f"button input {spec.spec!r}: {name} is not a Linux key name "
                    f"(see /usr/include/linux/input-event-codes.h)"
                )
        codes[int(code)] = button
    return codes


def _open_node(path: str, spec: EvdevSpec) -> Any:
    import evdev

    try:
        return evdev.InputDevice(path)
    except OSError as exc:
        if exc.errno in (errno.EACCES, errno.EPERM):
            raise ButtonInputError(
                f"evdev button input {spec.spec!r}: no permission to read {path}: {PERMISSION_FIX}"
            ) from None
        if exc.errno in (errno.ENOENT, errno.ENODEV, errno.ENXIO):
            raise ButtonInputError(
                f"evdev button input {spec.spec!r}: {path} does not exist (unplugged? "
                f"list devices with `omnidev devices` or /proc/bus/input/devices)"
            ) from None
        raise ButtonInputError(
            f"evdev button input {spec.spec!r}: cannot open {path}: {exc}"
        ) from None


def _find_by_name(spec: EvdevSpec, codes: dict[int, str]) -> Any:
    """The first event node named ``spec.name`` that has every mapped key."""
    assert spec.name is not None
    nodes = find_event_nodes(name=spec.name)
    if not nodes:
        names = sorted({i.name for i in list_devices() if i.event_node})
        raise ButtonInputError(
            f"evdev button input {spec.spec!r}: no input device named {spec.name!r} "
            f"(present: {', '.join(repr(n) for n in names) or 'none'})"
        )
    ecodes = _ecodes()
    for node in nodes:
        dev = _open_node(node, spec)
        if set(codes) <= set(dev.capabilities().get(ecodes.EV_KEY, [])):
            return dev
        dev.close()
    raise ButtonInputError(
        f"evdev button input {spec.spec!r}: no device named {spec.name!r} "
        f"({', '.join(nodes)}) has all the keys {', '.join(n for n, _ in spec.keys)}"
    )


class EvdevKeys:
    """Pointer buttons from the keys of one evdev device; see the module docstring.

    Attributes:
        path: the /dev/input/eventN node read.
        name: the device's name.
    """

    def __init__(self, device: Any, codes: dict[int, str], spec: EvdevSpec) -> None:
        self._dev = device
        self._codes = codes
        self._spec = spec.spec
        self.path: str = device.path
        self.name: str = device.name
        self._keys_down: set[int] = set()
        self._states = ButtonStates()
        self._dropping = False
        self._lost = False
        self._grabbed = False
        if spec.grab:
            try:
                device.grab()
            except OSError as exc:
                device.close()
                raise ButtonInputError(
                    f"evdev button input {spec.spec!r}: cannot grab {self.path} "
                    f"(another program holds it? {exc.strerror})"
                ) from None
            self._grabbed = True

    def _pressed(self) -> list[str]:
        return [self._codes[c] for c in self._keys_down]

    def poll(self) -> list[ButtonEvent]:
        """Button events from the key events read since the last poll (non-blocking)."""
        if self._dev is None:
            if self._lost:
                raise ButtonInputError(f"evdev button input {self._spec!r}: {self.path} went away")
            return []
        ecodes = _ecodes()
        events: list[ButtonEvent] = []
        while True:
            try:
                ev = self._dev.read_one()
            except OSError as exc:
                if exc.errno in (errno.EAGAIN, errno.EINTR):
                    break
                events += self._states.release_all()
                self._lost = True
                self._close_device()
                return events
            if ev is None:
                break
            if ev.type == ecodes.EV_SYN:
                if ev.code == ecodes.SYN_DROPPED:
                    self._dropping = True
                elif ev.code == ecodes.SYN_REPORT and self._dropping:
                    self._dropping = False
                    self._keys_down = set(self._dev.active_keys()) & set(self._codes)
                    events += self._states.set_pressed(self._pressed())
                continue
            if self._dropping or ev.type != ecodes.EV_KEY or ev.code not in self._codes:
                continue
            if ev.value == 1:
                self._keys_down.add(ev.code)
            elif ev.value == 0:
                self._keys_down.discard(ev.code)
            else:  # 2: autorepeat
                continue
            events += self._states.set_pressed(self._pressed())
        return events

    def _close_device(self) -> None:
        dev, self._dev = self._dev, None
        if dev is None:
            return
        if self._grabbed:
            # the device may be gone; the kernel dropped the grab with it then
            with contextlib.suppress(OSError):
                dev.ungrab()
        with contextlib.suppress(OSError):
            dev.close()

    def close(self) -> list[ButtonEvent]:
        """Release the device (and its grab); the releases of the buttons still down."""
        self._close_device()
        self._lost = False
        return self._states.release_all()

    def fileno(self) -> int:
        """The device's file descriptor (for select/poll), -1 once closed."""
        return -1 if self._dev is None else int(self._dev.fd)

    def __enter__(self) -> EvdevKeys:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_evdev_keys(spec: EvdevSpec) -> EvdevKeys:
    """Open the ``evdev:`` input of ``spec``; one-line ButtonInputError if it cannot."""
    codes = key_codes(spec)
    if spec.path is not None:
        if not os.path.exists(spec.path) and not os.path.isdir("/dev/input"):
            raise ButtonInputError(
                f"evdev button input {spec.spec!r}: {spec.path} does not exist and this "
                f"machine has no /dev/input (no input devices, or a container without them)"
            )
        dev = _open_node(spec.path, spec)
    else:
        dev = _find_by_name(spec, codes)
    return EvdevKeys(dev, codes, spec)

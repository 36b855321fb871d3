"""``hid:`` button input: input reports of a HID device (hidapi) as pointer buttons.

The device is found by vendor:product (and optionally serial number and USB
interface) with ``hid.enumerate``, opened by path, and read without blocking; each
input report is decoded by :class:`omnidev.buttons.hidmap.HidButtonMap` and the
changes of the pressed set become button events.

Backends of the ``hidapi`` Python package on Linux: ``hidraw`` (module ``hidraw``,
through the kernel's /dev/hidrawN, preferred) and ``libusb`` (module ``hid``).
With ``backend=auto`` the hidraw backend is used when the module exists. Reading
through the hidraw node leaves the kernel's driver attached, so a presenter's
keys also still reach the desktop (use an ``evdev:`` input with ``grab=1`` to
stop that). Through dummy_hcd the libusb backend was seen returning an empty
report after every real one, i.e. reading one report behind.

Which device when several match (a receiver often has a keyboard interface and a
mouse/consumer one): ``interface=N``, else, when keyboard usages are mapped, the
first whose top-level usage is Generic Desktop / Keyboard (0x01/0x06), else the
first listed.

hidapi is imported only when a device is opened, so this module imports on any
machine.
"""

from __future__ import annotations

import contextlib
import os
from typing import Any

from omnidev.buttons.inputs import ButtonEvent, ButtonInputError, ButtonStates
from omnidev.buttons.spec import HidSpec

MAX_REPORT = 64  # bytes asked for per read: a full-speed interrupt packet
PERMISSION_FIX = (
    "give the user read/write access to the device's /dev/hidrawN with a udev rule "
    '(see docs/buttons.md: SUBSYSTEM=="hidraw", ATTRS{idVendor}==..., GROUP="input", '
    'MODE="0660") and membership of group input; under omnidevd.service the unit must '
    "allow char-hidraw (sudo make install writes omnidevd.service.d/10-devices.conf from "
    "the configuration)"
)


def hid_module(backend: str) -> tuple[Any, str]:
    """The hidapi module for ``backend`` (auto, hidraw, libusb) and the backend's name."""
    if backend in ("auto", "hidraw"):
        try:
            import hidraw

            return hidraw, "hidraw"
        except ImportError:
            if backend == "hidraw":
                raise ButtonInputError(
                    "hid button input: hidapi's hidraw backend (module hidraw) is missing: "
                    "pip install hidapi (Linux wheels include it)"
                ) from None
    try:
        import hid

        return hid, "libusb"
    except ImportError:
        raise ButtonInputError(
            "hid button input: the hidapi package is not installed "
            "(pip install 'omnidev[hw]' or hidapi)"
        ) from None


def _id(spec: HidSpec) -> str:
    return f"{spec.vendor_id:04x}:{spec.product_id:04x}"


def choose_device(spec: HidSpec, found: list[dict[str, Any]]) -> dict[str, Any]:
    """The enumerated device (hidapi dict) the spec means; see the module docstring."""
    cands = found
    if spec.serial is not None:
        cands = [d for d in cands if d.get("serial_number") == spec.serial]
    if spec.interface is not None:
        cands = [d for d in cands if d.get("interface_number") == spec.interface]
    if not cands:
        have = ", ".join(
            f"serial {d.get('serial_number')!r} interface {d.get('interface_number')}"
            for d in found
        )
        raise ButtonInputError(
            f"hid button input {spec.spec!r}: {_id(spec)} is connected but not with "
            f"the serial/interface asked for (present: {have})"
        )
    if spec.interface is None and spec.map.keys:
        keyboards = [d for d in cands if (d.get("usage_page"), d.get("usage")) == (1, 6)]
        cands = keyboards or cands
    return cands[0]


class HidButtons:
    """Pointer buttons from the input reports of one HID device; see the module docstring.

    Attributes:
        path: the device path hidapi opened (``/dev/hidrawN`` with the hidraw backend).
        backend: ``hidraw`` or ``libusb``.
        product: the device's product string.
    """

    def __init__(self, device: Any, spec: HidSpec, info: dict[str, Any], backend: str) -> None:
        self._dev = device
        self._spec = spec
        raw = info.get("path", b"")
        self.path: str = raw.decode(errors="replace") if isinstance(raw, bytes) else str(raw)
        self.backend = backend
        self.product: str = info.get("product_string") or ""
        self._states = ButtonStates()
        self._lost = False

    def poll(self) -> list[ButtonEvent]:
        """Button events from the reports read since the last poll (non-blocking)."""
        if self._dev is None:
            if self._lost:
                raise ButtonInputError(
                    f"hid button input {self._spec.spec!r}: "
                    f"{_id(self._spec)} ({self.path}) went away"
                )
            return []
        events: list[ButtonEvent] = []
        while True:
            try:
                report = self._dev.read(MAX_REPORT)
            except (OSError, ValueError):
                events += self._states.release_all()
                self._lost = True
                self._close_device()
                return events
            if not report:
                return events
            pressed = self._spec.map.pressed(report)
            if pressed is not None:
                events += self._states.set_pressed(pressed)

    def _close_device(self) -> None:
        dev, self._dev = self._dev, None
        if dev is not None:
            with contextlib.suppress(OSError, ValueError):
                dev.close()

    def close(self) -> list[ButtonEvent]:
        """Close the device; the releases of the buttons still down."""
        self._close_device()
        self._lost = False
        return self._states.release_all()

    def __enter__(self) -> HidButtons:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_hid_buttons(spec: HidSpec) -> HidButtons:
    """Open the ``hid:`` input of ``spec``; one-line ButtonInputError if it cannot."""
    mod, backend = hid_module(spec.backend)
    found = list(mod.enumerate(spec.vendor_id, spec.product_id))
    if not found:
        others = sorted({f"{d['vendor_id']:04x}:{d['product_id']:04x}" for d in mod.enumerate()})
        raise ButtonInputError(
            f"hid button input {spec.spec!r}: no HID device {_id(spec)} is connected "
            f"({backend} backend lists: {', '.join(others) or 'none'})"
        )
    info = choose_device(spec, found)
    dev = mod.device()
    path = info["path"]
    try:
        dev.open_path(path)
    except OSError as exc:
        node = path.decode(errors="replace") if isinstance(path, bytes) else str(path)
        if node.startswith("/dev/") and not os.access(node, os.R_OK | os.W_OK):
            raise ButtonInputError(
                f"hid button input {spec.spec!r}: no permission to open {node}: {PERMISSION_FIX}"
            ) from None
        raise ButtonInputError(
            f"hid button input {spec.spec!r}: cannot open {_id(spec)} at {node} ({exc})"
        ) from None
    dev.set_nonblocking(1)
    return HidButtons(dev, spec, info, backend)

"""The systemd drop-in that lets ``omnidevd.service`` open the devices a configuration names.

The shipped unit (udev/omnidevd.service) has ``DevicePolicy=closed`` and allows only
what every configuration may need: /dev/uinput, V4L2 devices and /dev/hidgN. Button
inputs (``[buttons] input``) need more, and only then:

- ``evdev:/dev/input/eventN`` or ``evdev:name=...``: ``char-input r`` (python-evdev
  opens the node, read-only when it may not write; ``name=`` opens each node to read
  its name);
- ``hid:...&backend=hidraw``: ``char-hidraw rw`` (hidapi opens /dev/hidrawN read-write);
- ``hid:...&backend=libusb``: ``char-usb_device rw`` (libusb opens /dev/bus/usb/BBB/DDD);
- ``hid:...`` (``backend=auto``): both (auto takes hidraw when its module is installed).

:func:`device_allow` is pure (a configuration in, lines out); ``omnidev daemon
--device-allow`` prints :func:`dropin_text`, and ``sudo make install`` writes it to
/etc/systemd/system/omnidevd.service.d/10-devices.conf.
"""

from __future__ import annotations

from omnidev.buttons import parse_spec
from omnidev.buttons.spec import EvdevSpec
from omnidev.daemon.config import DaemonConfig


def device_allow(config: DaemonConfig) -> list[str]:
    """The ``DeviceAllow=`` values (``"char-input r"``...) the configuration's button
    input needs beyond the shipped unit's; empty when it names none."""
    if not config.buttons.input:
        return []
    spec = parse_spec(config.buttons.input)
    if isinstance(spec, EvdevSpec):
        return ["char-input r"]
    allow = []
    if spec.backend in ("auto", "hidraw"):
        allow.append("char-hidraw rw")
    if spec.backend in ("auto", "libusb"):
        allow.append("char-usb_device rw")
    return allow


def dropin_text(config: DaemonConfig) -> str:
    """A systemd drop-in for ``omnidevd.service`` with :func:`device_allow`'s lines (a
    comment alone when the configuration needs nothing more)."""
    lines = [
        f"# written from {config.path} by `omnidev daemon --device-allow`",
        "# (sudo make install writes it again; then: systemctl daemon-reload)",
        "[Service]",
    ]
    allow = device_allow(config)
    if allow:
        lines.insert(2, f"# [buttons] input = {config.buttons.input}")
    lines += [f"DeviceAllow={a}" for a in allow]
    return "\n".join(lines) + "\n"

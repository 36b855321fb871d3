"""``usb:VID:PID[:SERIAL]`` — a USB camera's capture node, found through sysfs, opened as V4L2."""

from __future__ import annotations

from pathlib import Path

from omnidev.devices import list_video_devices
from omnidev.errors import SourceError
from omnidev.sources.v4l2 import V4L2Source, parse_v4l2_options


def parse_usb_id(text: str) -> tuple[str, str, str | None]:
    """(vendor, product, serial or None), lower-case hex; SourceError when malformed.

    >>> parse_usb_id("046D:0825")
    ('046d', '0825', None)
    """
    parts = text.split(":", 2)
    if len(parts) < 2 or not all(len(p) == 4 for p in parts[:2]):
        raise SourceError(f"usb:{text}: expected usb:VID:PID[:SERIAL] with 4-digit hex ids")
    try:
        int(parts[0], 16), int(parts[1], 16)
    except ValueError:
        raise SourceError(f"usb:{text}: vendor and product must be hex") from None
    return parts[0].lower(), parts[1].lower(), parts[2] if len(parts) == 3 else None


def resolve_usb(text: str, sysfs: str | Path = "/sys", dev: str | Path = "/dev") -> str:
    """The /dev/videoN capture node of the USB camera ``VID:PID[:SERIAL]``."""
    vid, pid, serial = parse_usb_id(text)
    devices = list_video_devices(sysfs, dev)
    for d in devices:
        if d.usb_id is None or not d.capture:
            continue
        parts = d.usb_id.split(":", 2)
        if parts[0] == vid and parts[1] == pid and (serial is None or parts[2:] == [serial]):
            return d.node
    present = sorted({d.usb_id for d in devices if d.usb_id})
    listed = ", ".join(present) if present else "none"
    raise SourceError(f"usb:{text}: no such USB camera (USB cameras present: {listed})")


def open_usb(rest: str, options: dict[str, str]) -> V4L2Source:
    uri = f"usb:{rest}"
    settings = parse_v4l2_options(uri, options)
    return V4L2Source(resolve_usb(rest), settings)

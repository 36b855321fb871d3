"""V4L2 devices as sysfs shows them, with their USB vendor:product:serial.

Layout read (Linux): /sys/class/video4linux/videoN/{name,index} and the
``device`` link to the USB interface, whose parent holds idVendor, idProduct
and serial.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class VideoDevice:
    """One /dev/videoN node."""

    node: str  # /dev/videoN
    card: str  # sysfs name
    index: int | None  # sysfs index: 0 is the capture node of a UVC camera
    usb_id: str | None  # "vvvv:pppp[:serial]" when on USB
    node_exists: bool
    readable: bool

    @property
    def capture(self) -> bool:
        """True when the node is (most likely) the camera's capture node."""
        return self.index in (0, None)


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def usb_identity(device_dir: Path) -> str | None:
    """vendor:product[:serial] of the USB device above a sysfs device directory."""
    try:
        d = device_dir.resolve()
    except OSError:
        return None
    for cand in (d, *d.parents):
        vid, pid = _read(cand / "idVendor"), _read(cand / "idProduct")
        if vid and pid:
            serial = _read(cand / "serial")
            return f"{vid.lower()}:{pid.lower()}" + (f":{serial}" if serial else "")
        if cand.name == "devices":
            break
    return None


def list_video_devices(sysfs: str | Path = "/sys", dev: str | Path = "/dev") -> list[VideoDevice]:
    """Every video4linux node, sorted by number."""
    root = Path(sysfs) / "class" / "video4linux"
    if not root.is_dir():
        return []
    out = []

    def number(p: Path) -> int:
        m = re.search(r"(\d+)$", p.name)
        return int(m.group(1)) if m else 0

    for entry in sorted(root.glob("video*"), key=number):
        node = Path(dev) / entry.name
        idx = _read(entry / "index")
        out.append(
            VideoDevice(
                node=str(node),
                card=_read(entry / "name") or "?",
                index=int(idx) if idx and idx.isdigit() else None,
                usb_id=usb_identity(entry / "device"),
                node_exists=node.exists(),
                readable=node.exists() and os.access(node, os.R_OK),
            )
        )
    return out

"""Rig files (TOML): a camera bound to its calibration.

[camera]
name = "hall"                 # optional
source = "v4l2:/dev/video0"   # or: usb = "046d:0825[:SERIAL]"
calibration = "hall.yml.gz"   # relative to the rig file's folder
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from omnidev.errors import OmnidevError


class RigError(OmnidevError):
    """A rig file that cannot be used."""


@dataclass(frozen=True)
class Rig:
    name: str
    source_uri: str
    calibration: Path


def load_rig(path: Path | str) -> Rig:
    """Read a rig file; errors name the file and the key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RigError(f"{path}: rig file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise RigError(f"{path}: not valid TOML ({exc})") from None
    cam = data.get("camera")
    if not isinstance(cam, dict):
        raise RigError(f"{path}: missing table [camera]")

    def text(key: str) -> str | None:
        value = cam.get(key)
        if value is not None and not isinstance(value, str):
            raise RigError(f"{path}: camera.{key} must be a string")
        return value

    source, usb, calib = text("source"), text("usb"), text("calibration")
    if (source is None) == (usb is None):
        raise RigError(f"{path}: give exactly one of camera.source or camera.usb")
    if calib is None:
        raise RigError(f"{path}: missing key camera.calibration")
    unknown = sorted(set(cam) - {"name", "source", "usb", "calibration"})
    if unknown:
        raise RigError(f"{path}: unknown key camera.{unknown[0]}")
    calibration = Path(calib)
    if not calibration.is_absolute():
        calibration = path.parent / calibration
    uri = source if source is not None else f"usb:{usb}"
    return Rig(text("name") or path.stem, uri, calibration)

"""Rig files (TOML): a camera bound to its calibration.

[camera]
name = "hall"                 # optional
source = "v4l2:/dev/video0"   # or: usb = "046d:0825[:SERIAL]"
calibration = "hall.yml.gz"

Relative paths (the calibration, a file source such as ``video:hall.avi``) are
relative to the rig file's folder, wherever the command runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from omnidev.errors import OmnidevError
from omnidev.inputfile import read_toml
from omnidev.sources import resolve_uri


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
    data = read_toml(path, "rig file", error=RigError)
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
    uri = resolve_uri(source, path.parent) if source is not None else f"usb:{usb}"
    return Rig(text("name") or path.stem, uri, calibration)

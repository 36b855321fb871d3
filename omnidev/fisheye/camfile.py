"""Calibration files of kind ``fisheye`` (cv2.FileStorage: YAML, XML or JSON, optionally .gz).

Top-level nodes: ``kind: fisheye``, ``format_version: 1``, ``model`` (a lens model
name: kb4, mei, equidistant, equisolid, stereographic, orthographic, scaramuzza,
ds, eucm, fov), the model's parameters under the names of its dataclass fields in
:mod:`omnidev.fisheye.models` (numbers; tuples such as kb4's ``k`` or
scaramuzza's ``ss`` and optional ``invpol`` as 1xN matrices), ``image_width``,
``image_height`` (px), ``mount`` (3x3 orthonormal, ``x_opt = mount @ x_cam``;
optional, default up) and ``max_angle_deg`` (optional). Every error names the
file and the key.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev.calibfile import (
    check_header,
    open_storage,
    read_mat,
    read_real,
    read_string,
    write_storage,
)
from omnidev.errors import CalibrationError
from omnidev.fisheye.camera import KIND as KIND
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera, check_rotation
from omnidev.fisheye.models import (
    EUCM,
    DoubleSphere,
    FieldOfView,
    IdealFisheye,
    KannalaBrandt,
    LensModel,
    Scaramuzza,
    Unified,
)

VERSION = 1
OPTIONS = ("max_angle_deg", "mount")

_CLASSES: dict[str, type[Any]] = {
    "kb4": KannalaBrandt,
    "mei": Unified,
    "equidistant": IdealFisheye,
    "equisolid": IdealFisheye,
    "stereographic": IdealFisheye,
    "orthographic": IdealFisheye,
    "scaramuzza": Scaramuzza,
    "ds": DoubleSphere,
    "eucm": EUCM,
    "fov": FieldOfView,
}
_TUPLE_FIELDS = {"k", "ss", "invpol"}
_OPTIONAL = {"invpol"}


def lens_nodes(lens: LensModel) -> dict[str, Any]:
    """The file nodes of a lens: ``model`` and its parameters."""
    if lens.name not in _CLASSES or not dataclasses.is_dataclass(lens):
        raise ValueError(f"not a fisheye lens model: {lens!r}")
    nodes: dict[str, Any] = {"model": lens.name}
    for f in dataclasses.fields(lens):
        if f.name == "projection":
            continue
        value = getattr(lens, f.name)
        if f.name in _TUPLE_FIELDS:
            if value is not None:
                nodes[f.name] = np.asarray(value, np.float64).reshape(1, -1)
        else:
            nodes[f.name] = float(value)
    return nodes


def camera_nodes(camera: FisheyeCamera) -> dict[str, Any]:
    """All file nodes of ``camera`` (without the kind/version header)."""
    nodes = lens_nodes(camera.lens)
    nodes["image_width"] = int(camera.image_size[0])
    nodes["image_height"] = int(camera.image_size[1])
    nodes["mount"] = np.asarray(camera.mount, np.float64)
    if camera.max_angle_deg is not None:
        nodes["max_angle_deg"] = float(camera.max_angle_deg)
    return nodes


def write_camera_file(path: Path | str, camera: FisheyeCamera, *, force: bool = False) -> None:
    """Write ``camera`` as a ``fisheye`` calibration file (atomically; .yml, .xml, .json, .gz)."""
    write_storage(Path(path), KIND, VERSION, camera_nodes(camera), force=force)


def _read_lens(fs: cv2.FileStorage, path: Path) -> LensModel:
    name = read_string(fs, path, "model")
    cls = _CLASSES.get(name)
    if cls is None:
        raise CalibrationError(
            f"{path}: key 'model' is {name!r}; choose one of {', '.join(_CLASSES)}"
        )
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.name == "projection":
            kwargs["projection"] = name
            continue
        has_default = f.default is not dataclasses.MISSING
        if fs.getNode(f.name).empty() and (has_default or f.name in _OPTIONAL):
            continue
        if f.name in _TUPLE_FIELDS:
            values = tuple(float(x) for x in read_mat(fs, path, f.name).ravel())
            if f.name == "k" and len(values) != 4:
                raise CalibrationError(f"{path}: key 'k' needs 4 values, not {len(values)}")
            kwargs[f.name] = values
        else:
            kwargs[f.name] = read_real(fs, path, f.name)
    try:
        lens: LensModel = cls(**kwargs)
    except ValueError as exc:
        raise CalibrationError(f"{path}: model {name}: {exc}") from None
    return lens


def read_camera_file(path: Path | str) -> FisheyeCamera:
    """Read a ``fisheye`` calibration file; errors name the file and the key."""
    path = Path(path)
    with open_storage(path) as fs:
        check_header(fs, path, KIND, VERSION)
        lens = _read_lens(fs, path)
        w = read_real(fs, path, "image_width")
        h = read_real(fs, path, "image_height")
        if w != int(w) or h != int(h) or w <= 0 or h <= 0:
            raise CalibrationError(f"{path}: image_width/image_height must be positive integers")
        mount = MOUNTS["up"]
        if not fs.getNode("mount").empty():
            try:
                mount = check_rotation(read_mat(fs, path, "mount"))
            except ValueError as exc:
                raise CalibrationError(f"{path}: key 'mount': {exc}") from None
        max_angle = None
        if not fs.getNode("max_angle_deg").empty():
            max_angle = read_real(fs, path, "max_angle_deg")
            if not 0 < max_angle <= 180:
                raise CalibrationError(f"{path}: key 'max_angle_deg' must be in (0, 180]")
    return FisheyeCamera(lens, (int(w), int(h)), mount, max_angle)


def apply_options(camera: FisheyeCamera, options: Mapping[str, str]) -> FisheyeCamera:
    """``--camera-option`` settings: ``mount=up|down|forward``, ``max_angle_deg=DEG``."""
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise CalibrationError(
            f"fisheye has no option {unknown[0]!r} (options: {', '.join(OPTIONS)})"
        )
    mount, max_angle = camera.mount, camera.max_angle_deg
    if "mount" in options:
        if options["mount"] not in MOUNTS:
            raise CalibrationError(
                f"fisheye option mount={options['mount']!r}: choose one of {', '.join(MOUNTS)}"
            )
        mount = MOUNTS[options["mount"]]
    if "max_angle_deg" in options:
        text = options["max_angle_deg"]
        try:
            max_angle = float(text)
        except ValueError:
            max_angle = math.nan
        if not 0 < max_angle <= 180:
            raise CalibrationError(
                f"fisheye option max_angle_deg={text!r}: a number of degrees in (0, 180]"
            )
    return FisheyeCamera(camera.lens, camera.image_size, mount, max_angle)


def camera_from_file(path: Path | str, options: Mapping[str, str]) -> FisheyeCamera:
    """Load a ``fisheye`` camera and apply the ``--camera-option`` settings."""
    return apply_options(read_camera_file(Path(path)), options)

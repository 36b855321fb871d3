"""Camera models, unwarpers and remap maps: the contract between the core and unwarper plugins.

An *unwarper* plugin (entry-point group ``omnidev.unwarpers``, entry-point name =
the calibration ``kind`` it reads) loads a calibration file into a
:class:`CameraModel`. A camera model projects points of the camera frame
(docs/conventions.md) to omni-image pixels; from that the core builds maps that
``cv2.remap`` applies.

Pixel coordinates follow OpenCV: (u, v) = (column, row), the center of the
top-left pixel is (0, 0).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol, runtime_checkable

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.views import View

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

Interpolation = Literal["linear", "nearest", "cubic"]
INVALID = -8.0
"""Map value of pixels the camera does not see: far enough outside for any interpolation."""

_CV_INTERP = {"linear": cv2.INTER_LINEAR, "nearest": cv2.INTER_NEAREST, "cubic": cv2.INTER_CUBIC}


@runtime_checkable
class CameraModel(Protocol):
    """A calibrated camera that can say where scene points land in its image."""

    @property
    def kind(self) -> str:
        """The calibration kind (the unwarper plugin's entry-point name)."""
        ...

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) of the camera's images, px."""
        ...

    def default_elevation_deg(self) -> tuple[float, float] | None:
        """Elevation band (bottom, top) a :class:`~omnidev.views.Panorama` uses by default."""
        ...

    def project(self, points: FloatArray, *, finite: bool) -> tuple[FloatArray, BoolArray]:
        """Project (..., 3) camera-frame points (or directions if not finite) to pixels.

        Returns (..., 2) float64 pixel coordinates (u, v) and a (...) validity mask
        (False where the camera does not see the point or the pixel is outside
        the image).
        """
        ...


@runtime_checkable
class Unwarper(Protocol):
    """An entry point of group ``omnidev.unwarpers``: loads calibrations of one kind."""

    kind: str

    def load(self, path: Path, options: Mapping[str, str]) -> CameraModel:
        """Read a calibration file; raise :class:`omnidev.errors.CalibrationError` on bad input.

        ``options`` are the user's ``--camera-option KEY=VALUE`` settings; an
        unwarper rejects keys it does not know with a CalibrationError.
        """
        ...


@dataclass(frozen=True)
class Maps:
    """Maps from an output view to source-image pixels, for ``cv2.remap``.

    Attributes:
        map_x, map_y: (H, W) float32 source pixel coordinates (u, v); invalid
            pixels hold ``INVALID`` (-8, outside any image) so that
            ``cv2.remap`` with a constant border writes
            the border value there.
        valid: (H, W) bool, True where the camera sees the view's point.
        source_size: (width, height) of the source image the maps expect.
    """

    map_x: NDArray[np.float32]
    map_y: NDArray[np.float32]
    valid: BoolArray
    source_size: tuple[int, int]

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.map_x.shape[0]), int(self.map_x.shape[1]))

    def fixed_point(self) -> tuple[NDArray[np.int16], NDArray[np.uint16]]:
        """The same maps as OpenCV's fixed-point pair (CV_16SC2 + CV_16UC1), faster to apply.

        For bilinear and bicubic interpolation: positions are kept to 1/32 px
        (OpenCV's ``INTER_TAB_SIZE``). Computed once per :class:`Maps` and kept.
        """
        cached = self.__dict__.get("_fixed")
        if cached is None:
            m1, m2 = cv2.convertMaps(self.map_x, self.map_y, cv2.CV_16SC2)
            cached = (np.asarray(m1, np.int16), np.asarray(m2, np.uint16))
            self.__dict__["_fixed"] = cached  # frozen dataclass: a cache, not a field
        return cached

    def fixed_point_nearest(self) -> NDArray[np.int16]:
        """Integer maps (CV_16SC2, each position rounded) for nearest-neighbour remapping.

        ``cv2.remap(image, m, None, cv2.INTER_NEAREST)`` gives exactly what the float
        maps give. (With the bilinear pair of :meth:`fixed_point`, OpenCV's nearest
        interpolation reads the wrong pixels.)
        """
        cached = self.__dict__.get("_fixed_nearest")
        if cached is None:
            m1, _ = cv2.convertMaps(self.map_x, self.map_y, cv2.CV_16SC2, nninterpolation=True)
            cached = np.asarray(m1, np.int16)
            self.__dict__["_fixed_nearest"] = cached
        return cached

    def remap_args(self, interpolation: Interpolation) -> tuple[NDArray[np.int16], Any, int]:
        """(map1, map2, flag) for ``cv2.remap`` with fixed-point maps and ``interpolation``."""
        if interpolation == "nearest":
            return self.fixed_point_nearest(), None, cv2.INTER_NEAREST
        m1, m2 = self.fixed_point()
        return m1, m2, _CV_INTERP[interpolation]


def maps_from_pixels(uv: FloatArray, valid: BoolArray, source_size: tuple[int, int]) -> Maps:
    """Pack (H, W, 2) pixel positions and a validity mask into :class:`Maps`.

    Positions outside the source image (with a half-pixel margin) are marked invalid.
    """
    w, h = source_size
    u, v = uv[..., 0], uv[..., 1]
    inside = (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
    ok = valid & inside & np.isfinite(u) & np.isfinite(v)
    map_x = np.where(ok, u, INVALID).astype(np.float32)
    map_y = np.where(ok, v, INVALID).astype(np.float32)
    return Maps(map_x, map_y, ok, (w, h))


DEFAULT_MAP_BYTES_PER_PIXEL = 200.0
"""Peak bytes per output pixel of building a view's maps when a camera model does not say
(measured: the pano-table route about 180; a model with a fast route sets its own
``map_bytes_per_pixel`` attribute)."""


def map_bytes_per_pixel(camera: CameraModel) -> float:
    """Peak memory of :func:`build_maps` plus :class:`Remapper` per output pixel, bytes.

    A camera model may set ``map_bytes_per_pixel``; otherwise
    :data:`DEFAULT_MAP_BYTES_PER_PIXEL`. The CLI checks views against the memory limit
    with it before building them (:mod:`omnidev.budget`).
    """
    value = getattr(camera, "map_bytes_per_pixel", None)
    return (
        float(value)
        if isinstance(value, int | float) and value > 0
        else DEFAULT_MAP_BYTES_PER_PIXEL
    )


def project_maps(camera: CameraModel, view: View) -> Maps:
    """Maps by the plain route: the view's points through ``camera.project``."""
    pts = view.points(camera.default_elevation_deg())
    uv, valid = camera.project(pts, finite=view.finite)
    return maps_from_pixels(uv, valid, camera.image_size)


def build_maps(camera: CameraModel, view: View) -> Maps:
    """Remap maps that turn images of ``camera`` into ``view``.

    A camera model may offer a faster route to the same maps as an optional
    method ``view_maps(view) -> Maps`` (it returns what :func:`project_maps`
    would, up to float32 rounding); otherwise the view's points go through
    ``camera.project``.
    """
    fast = getattr(camera, "view_maps", None)
    if callable(fast):
        maps = fast(view)
        if isinstance(maps, Maps):
            return maps
    return project_maps(camera, view)


def unwarp(
    image: NDArray[np.uint8],
    maps: Maps,
    *,
    interpolation: Interpolation = "linear",
    border_value: int = 0,
    precise: bool = False,
) -> NDArray[np.uint8]:
    """Apply ``maps`` to one image (pixels the camera does not see get ``border_value``).

    The maps are applied in OpenCV's fixed-point form (:meth:`Maps.fixed_point`,
    converted on the first call and kept with the maps), at the speed of a bare
    fixed-point ``cv2.remap``. Nearest-neighbour output is exactly that of the
    float maps; bilinear and bicubic sample positions are rounded to 1/32 px.
    ``precise=True`` applies the float maps instead (1.4-1.6 times slower).
    """
    w, h = maps.source_size
    if image.shape[1] != w or image.shape[0] != h:
        raise ValueError(
            f"image is {image.shape[1]}x{image.shape[0]}, the calibration expects {w}x{h}"
        )
    m1: NDArray[Any]
    if precise:
        m1, m2, flag = maps.map_x, maps.map_y, _CV_INTERP[interpolation]
    else:
        m1, m2, flag = maps.remap_args(interpolation)
    out = cv2.remap(image, m1, m2, flag, borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)
    return np.asarray(out, dtype=np.uint8)


class Remapper:
    """Applies one set of maps to many frames at the speed of bare ``cv2.remap``.

    The maps are converted once to OpenCV's fixed-point form; invalid pixels
    read outside the image and get ``border_value``.
    """

    def __init__(
        self, maps: Maps, *, interpolation: Interpolation = "linear", border_value: int = 0
    ) -> None:
        self.maps = maps
        self._m1, self._m2, self._interp = maps.remap_args(interpolation)
        self._border = border_value

    def __call__(self, image: NDArray[np.uint8]) -> NDArray[np.uint8]:
        out = cv2.remap(
            image,
            self._m1,
            self._m2,
            self._interp,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=self._border,
        )
        return np.asarray(out, np.uint8)

"""Unwarping 4:2:0 frames plane by plane, without converting them to BGR.

Video decoders (MJPEG, H.264) produce planar YUV 4:2:0: a full-size Y plane and
half-size U and V planes. :class:`PlanarRemapper` applies a view's maps to the
Y plane and derived half-size maps to U and V, so that a frame goes from the
decoder to the encoder with no colour conversion and half the bytes of BGR to
remap. Arrays are in OpenCV's I420 memory layout ((H * 3 / 2) x W: Y, U, V;
omnidev.outputs.pixels).

Chroma maps: a chroma pixel covers a 2 x 2 block of luma pixels (centred
siting, as JPEG and MPEG-2 vertically); its source position is the mean of the
block's luma map positions over the block's valid pixels, carried to chroma
coordinates by ``c = (x + 0.5) / 2 - 0.5``. A block with no valid pixel is
invalid. Pixels the camera does not see get black: Y 16 (limited range) or 0
(full range), U = V = 128.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.camera import INVALID, Interpolation, Maps


def chroma_maps(maps: Maps) -> Maps:
    """Half-size maps for the U and V planes of a 4:2:0 frame (see the module docstring).

    ``maps`` must have an even width and height, and so must its source size.
    """
    h, w = maps.shape
    sw, sh = maps.source_size
    if w % 2 or h % 2 or sw % 2 or sh % 2:
        raise ValueError(f"4:2:0 needs even sizes, got view {w}x{h} and source {sw}x{sh}")
    valid = maps.valid.reshape(h // 2, 2, w // 2, 2)
    count = valid.sum(axis=(1, 3))
    ok = count > 0
    n = np.maximum(count, 1)

    def block_mean(m: NDArray[np.float32]) -> NDArray[np.float64]:
        blocks = np.where(maps.valid, m, 0.0).reshape(h // 2, 2, w // 2, 2)
        return np.asarray(blocks.sum(axis=(1, 3), dtype=np.float64) / n)

    cx = (block_mean(maps.map_x) + 0.5) / 2 - 0.5
    cy = (block_mean(maps.map_y) + 0.5) / 2 - 0.5
    map_x = np.where(ok, cx, INVALID).astype(np.float32)
    map_y = np.where(ok, cy, INVALID).astype(np.float32)
    return Maps(map_x, map_y, ok, (sw // 2, sh // 2))


class PlanarRemapper:
    """Applies one view's maps to I420 frames, plane by plane, with fixed-point maps.

    Args:
        maps: the view's maps (even width and height, even source size).
        full_range: the frames are full range (``yuvj420p``); else limited (``yuv420p``).
    """

    def __init__(
        self, maps: Maps, *, interpolation: Interpolation = "linear", full_range: bool = False
    ) -> None:
        self.maps = maps
        self.size = (maps.shape[1], maps.shape[0])
        self._luma = maps.remap_args(interpolation)
        self._chroma = chroma_maps(maps).remap_args(interpolation)
        self._black = 0 if full_range else 16

    def __call__(self, image: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """The view of one I420 frame, as an I420 array."""
        sw, sh = self.maps.source_size
        if image.shape != (sh * 3 // 2, sw):
            raise ValueError(
                f"I420 frame is {image.shape[1]}x{image.shape[0] * 2 // 3}, "
                f"the maps expect {sw}x{sh}"
            )
        w, h = self.size
        out = np.empty((h * 3 // 2, w), np.uint8)
        flat_in, flat_out = image.reshape(-1), out.reshape(-1)
        cn_in, cn_out = (sh // 2) * (sw // 2), (h // 2) * (w // 2)
        y_in, y_out = image[:sh], out[:h]
        u_in = flat_in[sw * sh : sw * sh + cn_in].reshape(sh // 2, sw // 2)
        v_in = flat_in[sw * sh + cn_in :].reshape(sh // 2, sw // 2)
        u_out = flat_out[w * h : w * h + cn_out].reshape(h // 2, w // 2)
        v_out = flat_out[w * h + cn_out :].reshape(h // 2, w // 2)
        border = cv2.BORDER_CONSTANT
        cv2.remap(y_in, *self._luma, dst=y_out, borderMode=border, borderValue=self._black)
        cv2.remap(u_in, *self._chroma, dst=u_out, borderMode=border, borderValue=128)
        cv2.remap(v_in, *self._chroma, dst=v_out, borderMode=border, borderValue=128)
        return out

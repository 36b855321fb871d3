"""Pixel layout conversions between what omnidev computes and what outputs take.

Pure: numpy arrays in, numpy arrays out. Layouts (omnidev.outputs): ``bgr``
(H x W x 3), ``gray`` (H x W), ``yuv420p`` / ``yuvj420p`` (OpenCV's I420
memory layout, (H * 3 / 2) x W: Y, then U, then V at half width and height).
YUV is BT.601 (what V4L2, Y4M and H.264 assume for standard-definition and
webcam video, and what OpenCV's ``COLOR_BGR2YUV_I420`` computes): ``yuv420p``
limited range (Y 16..235, U V 16..240), ``yuvj420p`` full range (0..255, the
JPEG convention, as MJPEG cameras send).

>>> import numpy as np
>>> white = np.full((2, 2, 3), 255, np.uint8)
>>> to_layout(white, "bgr", "yuv420p")[:, 0].tolist()  # Y Y U V rows
[235, 235, 128]
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

U8 = NDArray[np.uint8]

# Full range (0..255) -> limited range: Y' = 16 + Y * 219 / 255, C' = 128 + (C - 128) * 224 / 255.
_FULL_TO_LIMITED_Y = np.clip(np.round(16 + np.arange(256) * 219 / 255), 0, 255).astype(np.uint8)
_FULL_TO_LIMITED_C = np.clip(np.round(128 + (np.arange(256) - 128) * 224 / 255), 0, 255).astype(
    np.uint8
)
_LIMITED_TO_FULL_Y = np.clip(np.round((np.arange(256) - 16) * 255 / 219), 0, 255).astype(np.uint8)
_LIMITED_TO_FULL_C = np.clip(np.round(128 + (np.arange(256) - 128) * 255 / 224), 0, 255).astype(
    np.uint8
)
# BT.601 limited range from B, G, R (rows Y, U, V; last column the offset).
_BGR_TO_YUV_LIMITED = np.array(
    [
        [0.098, 0.504, 0.257, 16.0],
        [0.439, -0.291, -0.148, 128.0],
        [-0.071, -0.368, 0.439, 128.0],
    ]
)


def i420_planes(image: U8) -> tuple[U8, U8, U8]:
    """Views of the Y (H x W), U and V (H/2 x W/2) planes of an I420 array."""
    h = image.shape[0] * 2 // 3
    w = image.shape[1]
    flat = image.reshape(-1)
    y = flat[: h * w].reshape(h, w)
    n = (h // 2) * (w // 2)
    u = flat[h * w : h * w + n].reshape(h // 2, w // 2)
    v = flat[h * w + n : h * w + 2 * n].reshape(h // 2, w // 2)
    return y, u, v


def i420_size(image: U8) -> tuple[int, int]:
    """(width, height) of the picture an I420 array holds."""
    return int(image.shape[1]), int(image.shape[0] * 2 // 3)


def empty_i420(width: int, height: int) -> U8:
    """An uninitialised I420 array for a width x height picture (both even)."""
    if width % 2 or height % 2:
        raise ValueError(f"4:2:0 needs an even width and height, got {width}x{height}")
    return np.empty((height * 3 // 2, width), np.uint8)


def full_to_limited(image: U8) -> U8:
    """``yuvj420p`` -> ``yuv420p`` (the same picture in limited range)."""
    out = np.empty_like(image)
    h = image.shape[0] * 2 // 3
    cv2.LUT(image[:h], _FULL_TO_LIMITED_Y, dst=out[:h])
    cv2.LUT(image[h:], _FULL_TO_LIMITED_C, dst=out[h:])
    return out


def limited_to_full(image: U8) -> U8:
    """``yuv420p`` -> ``yuvj420p``."""
    out = np.empty_like(image)
    h = image.shape[0] * 2 // 3
    cv2.LUT(image[:h], _LIMITED_TO_FULL_Y, dst=out[:h])
    cv2.LUT(image[h:], _LIMITED_TO_FULL_C, dst=out[h:])
    return out


def to_layout(image: U8, source: str, target: str) -> U8:
    """Convert ``image`` from layout ``source`` to ``target`` (see the module docstring).

    Gray becomes colour with U = V = 128; colour becomes gray by BT.601 luma.
    """
    if source == target:
        return image
    if source == "yuvj420p":
        image, source = full_to_limited(image), "yuv420p"
        if target == "yuv420p":
            return image
    if target == "yuvj420p":
        return limited_to_full(to_layout(image, source, "yuv420p"))
    if source == "bgr":
        if target == "gray":
            return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), np.uint8)
        if target == "yuv420p":
            _check_even(image.shape[1], image.shape[0])
            return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2YUV_I420), np.uint8)
    if source == "gray":
        if target == "bgr":
            return np.asarray(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR), np.uint8)
        if target == "yuv420p":
            h, w = image.shape
            _check_even(w, h)
            out = np.full((h * 3 // 2, w), 128, np.uint8)
            cv2.LUT(image, _FULL_TO_LIMITED_Y, dst=out[:h])
            return out
    if source == "yuv420p":
        if target == "bgr":
            return np.asarray(cv2.cvtColor(image, cv2.COLOR_YUV2BGR_I420), np.uint8)
        if target == "gray":
            h = image.shape[0] * 2 // 3
            return np.asarray(cv2.LUT(image[:h], _LIMITED_TO_FULL_Y), np.uint8)
    raise ValueError(f"no conversion from layout {source!r} to {target!r}")


def _check_even(width: int, height: int) -> None:
    if width % 2 or height % 2:
        raise ValueError(f"4:2:0 needs an even width and height, got {width}x{height}")


def bgr_to_yuyv(image: U8) -> U8:
    """BGR (H x W x 3, W even) -> packed YUYV 4:2:2 (H x 2W), BT.601 limited range.

    Each pair of pixels shares the mean of their U and V: bytes Y0 U Y1 V.
    """
    h, w = image.shape[:2]
    if w % 2:
        raise ValueError(f"YUYV needs an even width, got {w}")
    yuv = cv2.transform(image.astype(np.float32), _BGR_TO_YUV_LIMITED)
    out = np.empty((h, w * 2), np.uint8)
    out[:, 0::2] = np.clip(yuv[:, :, 0] + 0.5, 0, 255)
    pairs = yuv[:, :, 1:].reshape(h, w // 2, 2, 2).mean(axis=2)
    out[:, 1::4] = np.clip(pairs[:, :, 0] + 0.5, 0, 255)
    out[:, 3::4] = np.clip(pairs[:, :, 1] + 0.5, 0, 255)
    return out


def i420_to_yuyv(image: U8) -> U8:
    """``yuv420p`` (I420) -> packed YUYV 4:2:2: each chroma row serves two picture rows."""
    y, u, v = i420_planes(image)
    h, w = y.shape
    out = np.empty((h, w * 2), np.uint8)
    out[:, 0::2] = y
    out[:, 1::4] = np.repeat(u, 2, axis=0)
    out[:, 3::4] = np.repeat(v, 2, axis=0)
    return out


def yuyv_to_bgr(data: U8) -> U8:
    """Packed YUYV (H x 2W) -> BGR (H x W x 3), BT.601 limited range (OpenCV's)."""
    h, w2 = data.shape[:2]
    return np.asarray(cv2.cvtColor(data.reshape(h, w2 // 2, 2), cv2.COLOR_YUV2BGR_YUYV), np.uint8)

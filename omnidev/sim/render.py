"""Render omni-images and true views of a scene, area-averaged over each pixel."""

from __future__ import annotations

import dataclasses
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.camera import BoolArray, CameraModel, FloatArray
from omnidev.views import View

OUTSIDE = 10.0  # grey level outside the mirror disc
REFLECTION = 25.0  # grey level of the camera's own reflection in the middle
CHUNK = 1 << 20


class Scene(Protocol):
    def shade(self, origins: FloatArray, dirs: FloatArray, t: float = 0.0) -> FloatArray: ...


class BackProjecting(CameraModel, Protocol):
    @property
    def center(self) -> tuple[float, float]: ...

    def back_project(self, uv: FloatArray) -> FloatArray: ...


def _shade_dirs(scene: Scene, dirs: FloatArray, t: float) -> FloatArray:
    out = np.empty((len(dirs), 3))
    origin = np.zeros(3)
    for i in range(0, len(dirs), CHUNK):
        out[i : i + CHUNK] = scene.shade(origin, dirs[i : i + CHUNK], t)
    return out


def render_omni(
    camera: BackProjecting,
    scene: Scene,
    *,
    supersample: int = 3,
    t: float = 0.0,
    noise_sigma: float = 0.0,
    seed: int = 0,
) -> NDArray[np.uint8]:
    """An omni-image (H, W, 3) BGR uint8; each pixel the mean of supersample^2 samples.

    Samples the camera does not see (outside the mirror rim, inside the
    cut-off disc) are dark: :data:`OUTSIDE` beyond the rim, :data:`REFLECTION`
    in the middle.
    """
    w, h = camera.image_size
    n = supersample
    offs = (np.arange(n) + 0.5) / n - 0.5
    acc = np.zeros((h, w, 3))
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
    for dy in offs:
        for dx in offs:
            uv = np.stack([uu + dx, vv + dy], -1).reshape(-1, 2)
            dirs = camera.back_project(uv)
            _, ok = camera.project(dirs, finite=False)
            col = np.empty((len(uv), 3))
            r = np.hypot(uv[:, 0] - camera.center[0], uv[:, 1] - camera.center[1])
            col[:] = OUTSIDE
            inner = ~ok & (r < 0.3 * min(w, h))
            col[inner] = REFLECTION
            if np.any(ok):
                col[ok] = _shade_dirs(scene, dirs[ok], t)
            acc += col.reshape(h, w, 3)
    img = acc / (n * n)
    if noise_sigma > 0:
        img += np.random.default_rng(seed).normal(0, noise_sigma, img.shape)
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def render_view(
    view: View,
    scene: Scene,
    *,
    supersample: int = 3,
    t: float = 0.0,
    camera: CameraModel | None = None,
) -> tuple[NDArray[np.uint8], BoolArray]:
    """The true image of ``view`` (what the viewpoint sees through each view pixel).

    The view is rendered at ``supersample`` times its size and area-averaged.
    The mask is where ``camera`` (if given) sees the pixel's point; all True
    otherwise.
    """
    big = dataclasses.replace(
        view,
        width=view.width * supersample,  # type: ignore[type-var]
        height=view.height * supersample,
    )
    pts = big.points(camera.default_elevation_deg() if camera else None)
    dirs = pts.reshape(-1, 3)
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    col = _shade_dirs(scene, dirs, t).reshape(pts.shape)
    img = cv2.resize(col, (view.width, view.height), interpolation=cv2.INTER_AREA)
    out = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    if camera is None:
        return out, np.ones((view.height, view.width), bool)
    _, ok = camera.project(view.points(camera.default_elevation_deg()), finite=view.finite)
    return out, ok

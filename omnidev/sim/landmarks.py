"""Exact landmark pairs for a rendered camera: world points on the scene and their pixels."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omnidev.atomic import atomic_path
from omnidev.camera import CameraModel
from omnidev.sim.scene import RoomScene


@dataclass(frozen=True)
class Landmark:
    """Pixel (u, v) and world point (X, Y, Z) (world = camera frame + mirror center)."""

    u: float
    v: float
    X: float
    Y: float
    Z: float


def make_landmarks(
    camera: CameraModel, scene: RoomScene, *, n: int = 16, seed: int = 0, margin_deg: float = 1.0
) -> list[Landmark]:
    """n landmarks on the room's surfaces, spread evenly over the visible elevation band
    (``margin_deg`` inside its ends) and over all azimuths, pixels exact."""
    rng = np.random.default_rng(seed)
    lo, hi = camera.default_elevation_deg() or (-60.0, 10.0)
    rho = np.radians(np.linspace(lo + margin_deg, hi - margin_deg, n))
    theta = (np.arange(n) * 2.39996 + rng.uniform(0, 2 * math.pi)) % (2 * math.pi)  # golden angle
    dirs = np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], 1)
    dist, _ = scene.intersect(np.zeros_like(dirs), dirs)
    pts = dirs * dist[:, None]
    uv, ok = camera.project(pts, finite=True)
    assert ok.all(), "landmarks must be visible"
    world = pts + np.asarray(scene.mirror_center_world)
    return [
        Landmark(float(a), float(b), *map(float, p)) for (a, b), p in zip(uv, world, strict=True)
    ]


def write_landmarks_csv(path: Path, landmarks: list[Landmark], *, force: bool = False) -> None:
    """CSV with header ``u,v,X,Y,Z``, 6 decimals, written atomically."""
    lines = ["u,v,X,Y,Z"] + [
        f"{m.u:.6f},{m.v:.6f},{m.X:.6f},{m.Y:.6f},{m.Z:.6f}" for m in landmarks
    ]
    with atomic_path(Path(path), force=force) as tmp:
        tmp.write_text("\n".join(lines) + "\n")

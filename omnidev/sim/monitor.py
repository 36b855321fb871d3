"""A monitor with four corner landmarks seen by a hand-held camera, with exact truth.

The camera-mouse fixture (issue 4; dissertation chapter 6): a monitor of known
size whose screen shows changing content (with black and white regions, the
landmarks' own colours), a landmark on each corner of its bezel (a black disc
on a white square), and a textured wall behind. A hand-held camera
(:class:`~omnidev.sim.handcam.HandCamera`, radial distortion) follows a named
trajectory; frames get motion blur (the mean of sub-frame renders over the
exposure), exposure gain jitter and sensor noise.

Geometry (metres, world frame of :mod:`omnidev.sim.handcam`): the screen's
lit area is the rectangle [0, SCREEN_W] x [0, SCREEN_H] of the plane z = 0;
the bezel extends it by :data:`BEZEL` on every side; the wall is the plane
z = :data:`WALL_Z`. Each sample ray is intersected with both planes exactly,
the plane point looked up in a texture (bilinear), and each output pixel is
the mean of supersample^2 samples.

Screen coordinates of the truth: screen pixel ``px = X / pitch - 0.5`` with
``pitch = SCREEN_W / 1920`` (pixel centres; the same for y with 1080), and
normalized ``nx = px / (1920 - 1)`` as :class:`omnidev.screen.ScreenMapping`
uses.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.atomic import atomic_dir, check_output_dir
from omnidev.errors import OutputError
from omnidev.sim.handcam import FloatArray, HandCamera, Pose, look_at, project_points

SCREEN_W = 0.53  # m, lit area
SCREEN_H = 0.30  # m
SCREEN_PX = (1920, 1080)
BEZEL = 0.04  # m on every side
LANDMARK_SQUARE = 0.032  # m, side of the white square
LANDMARK_RADIUS = 0.010  # m, radius of the black disc
LANDMARK_INSET = 0.02  # m, landmark centre from the screen corner, along x and y
WALL_Z = 0.5  # m behind the screen
TEXEL = 0.0005  # m per monitor texel
WALL_TEXEL = 0.002  # m per wall texel
WHITE, BLACK, BEZEL_GREY = 235.0, 12.0, 45.0

LANDMARK_NAMES = ("top_left", "top_right", "bottom_right", "bottom_left")
# Landmark centre minus the matching screen corner (m, world x and y).
LANDMARK_OFFSETS = (
    (-LANDMARK_INSET, -LANDMARK_INSET),
    (LANDMARK_INSET, -LANDMARK_INSET),
    (LANDMARK_INSET, LANDMARK_INSET),
    (-LANDMARK_INSET, LANDMARK_INSET),
)
SCREEN_CORNERS = ((0.0, 0.0), (SCREEN_W, 0.0), (SCREEN_W, SCREEN_H), (0.0, SCREEN_H))
TRAJECTORIES = ("drift", "sweep", "roll", "oblique", "partial", "still", "excursion")
# Scenes: the full monitor; the wall alone; the monitor with bottom_left's landmark removed.
VARIANTS = ("normal", "no-monitor", "three-landmarks")
SCREEN_CENTER = np.array([SCREEN_W / 2, SCREEN_H / 2, 0.0])


def landmark_layout() -> dict[str, Any]:
    """The scene's landmark layout in the form of omnidev.mouse.landmarks.LandmarkLayout
    (mm): what ``omnidev mouse --layout`` reads for these fixtures."""
    return {
        "screen_width_mm": SCREEN_W * 1000,
        "screen_height_mm": SCREEN_H * 1000,
        "offsets_mm": {
            k: [ox * 1000, oy * 1000]
            for k, (ox, oy) in zip(("tl", "tr", "br", "bl"), LANDMARK_OFFSETS, strict=True)
        },
        "circle_diameter_mm": LANDMARK_RADIUS * 2000,
        "square_side_mm": LANDMARK_SQUARE * 1000,
    }


def landmark_centers() -> FloatArray:
    """The four landmark disc centres (4, 3) in world metres, in LANDMARK_NAMES order."""
    return np.array(
        [
            [cx + ox, cy + oy, 0.0]
            for (cx, cy), (ox, oy) in zip(SCREEN_CORNERS, LANDMARK_OFFSETS, strict=True)
        ]
    )


def trajectory_pose(name: str, t: float) -> Pose:
    """The camera pose at time ``t`` (s) along trajectory ``name`` (see TRAJECTORIES).

    - drift: 0.9 m away, slow wander of aim (a few cm/s) and position, roll <= 4 deg.
    - sweep: 0.9 m away, aim swings +-0.2 m across the screen every 1.2 s (~1 m/s).
    - roll: 0.9 m away, roll about the optical axis +-30 deg over 4 s.
    - oblique: 0.9 m from the screen centre, view angle to the screen normal 0..45
      deg, the direction of the tilt turning around over 9 s.
    - partial: 0.6 m away, aim wanders towards the edges so one or two
      landmarks leave the picture.
    - excursion: 0.6 m away, the aim leaves the screen towards its bottom-right
      corner and comes back every 3 s (0.45 m right, 0.3 m down at the
      farthest): three or four landmarks leave the picture, then return.
    - still: 0.9 m away, a hand held still aiming near the screen centre: a slow
      sway below 0.3 Hz (aim angle ~0.1 deg plus a few mm of hand position:
      ~0.15-0.2 deg RMS of the optical axis per axis) and physiological tremor
      (three sines per axis at 8-12 Hz, ~0.1 deg peak, ~0.04 deg RMS per axis).
    """
    s = SCREEN_CENTER
    tau = 2 * math.pi
    if name == "drift":
        C = s + np.array(
            [
                0.05 * math.sin(0.3 * t),
                0.03 * math.sin(0.4 * t + 1),
                -0.9 + 0.03 * math.sin(0.2 * t),
            ]
        )
        aim = s + np.array([0.12 * math.sin(0.5 * t), 0.06 * math.sin(0.7 * t + 0.5), 0.0])
        return look_at(C, aim, 4.0 * math.sin(0.3 * t))
    if name == "sweep":
        C = s + np.array([0.0, 0.0, -0.9])
        aim = s + np.array([0.2 * math.sin(tau * t / 1.2), 0.04 * math.sin(tau * t / 2.9), 0.0])
        return look_at(C, aim, 3.0 * math.sin(tau * t / 3.0))
    if name == "roll":
        C = s + np.array([0.02 * math.sin(0.5 * t), 0.0, -0.9])
        aim = s + np.array([0.03 * math.sin(0.8 * t), 0.02 * math.sin(0.6 * t), 0.0])
        return look_at(C, aim, 30.0 * math.sin(tau * t / 4.0))
    if name == "oblique":
        theta = math.radians(45.0) * (0.5 - 0.5 * math.cos(tau * t / 6.0))
        phi = tau * t / 9.0
        d = np.array(
            [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), -math.cos(theta)]
        )
        return look_at(s + 0.9 * d, s, 2.0 * math.sin(t))
    if name == "partial":
        C = s + np.array([0.03 * math.sin(0.4 * t), 0.0, -0.6])
        aim = s + np.array([0.17 * math.sin(tau * t / 5.0), 0.03 * math.sin(tau * t / 3.3), 0.0])
        return look_at(C, aim, 5.0 * math.sin(tau * t / 7.0))
    if name == "still":
        return _still_pose(t)
    if name == "excursion":
        C = s + np.array([0.02 * math.sin(0.5 * t), 0.0, -0.6])
        out = math.sin(math.pi * t / 3.0) ** 2
        aim = s + np.array([0.45 * out, 0.3 * out, 0.0])
        return look_at(C, aim, 3.0 * math.sin(t))
    raise OutputError(f"unknown camera-mouse trajectory {name!r} ({', '.join(TRAJECTORIES)})")


# Physiological tremor of an outstretched hand: 8-12 Hz. Its angular amplitude
# here (~0.04 deg RMS per axis, ~0.1 deg peak, i.e. ~0.7 mm RMS of aim at 0.9 m)
# is an assumption of the order reported for hand-held pointers, not a measured
# figure. Rows: (frequency Hz, amplitude deg, phase rad), yaw then pitch.
_TREMOR_YAW = ((8.3, 0.045, 0.3), (9.7, 0.035, 2.1), (11.4, 0.025, 4.0))
_TREMOR_PITCH = ((8.9, 0.040, 1.2), (10.3, 0.035, 5.1), (11.9, 0.020, 0.7))


def _still_pose(t: float) -> Pose:
    """The "still" trajectory: sway plus tremor as angles of the aim (see trajectory_pose)."""
    s = SCREEN_CENTER
    tau = 2 * math.pi
    dist = 0.9
    yaw = 0.10 * math.sin(tau * 0.21 * t + 0.4) + sum(
        a * math.sin(tau * f * t + p) for f, a, p in _TREMOR_YAW
    )
    pitch = 0.08 * math.sin(tau * 0.29 * t + 1.3) + sum(
        a * math.sin(tau * f * t + p) for f, a, p in _TREMOR_PITCH
    )
    C = s + np.array([0.004 * math.sin(0.7 * t), 0.003 * math.sin(0.5 * t + 1.0), -dist])
    # aim near (not exactly at) the centre, turned by the sway and tremor angles
    aim = s + np.array(
        [
            0.012 + dist * math.tan(math.radians(yaw)),
            -0.008 + dist * math.tan(math.radians(pitch)),
            0.0,
        ]
    )
    return look_at(C, aim, 1.0 * math.sin(tau * 0.17 * t))


@dataclass(frozen=True)
class MouseTruth:
    """One frame's truth.

    ``screen_xy``: the point of the screen plane on the optical axis (image
    centre), normalized (may lie outside [0, 1] beside the screen), None when
    the axis does not meet the plane in front of the camera; ``screen_px`` the
    same in pixels of a 1920x1080 screen; ``on_screen`` whether it is inside
    the lit area. ``landmarks_uv``: each landmark centre's image position (px,
    after distortion; None behind the camera); ``visible``: whether the
    landmark's whole white square is inside the picture. ``view_angle_deg``:
    optical axis against the screen normal; ``roll_deg`` as set.
    """

    index: int
    t: float
    screen_xy: tuple[float, float] | None
    screen_px: tuple[float, float] | None
    on_screen: bool
    landmarks_uv: list[tuple[float, float] | None]
    visible: list[bool]
    view_angle_deg: float
    camera_center: tuple[float, float, float]
    rotation: list[list[float]]


def screen_point(pose: Pose) -> FloatArray | None:
    """World point (3,) where the optical axis meets the plane z = 0, or None."""
    d = pose.optical_axis()
    if abs(d[2]) < 1e-12:
        return None
    s = -pose.C[2] / d[2]
    if s <= 0:
        return None
    out: FloatArray = pose.C + s * d
    return out


def frame_truth(
    cam: HandCamera, pose: Pose, index: int = 0, t: float = 0.0, *, variant: str = "normal"
) -> MouseTruth:
    """Compute :class:`MouseTruth` for one pose in a scene of ``variant`` (VARIANTS).

    "no-monitor": no screen point and no landmark. "three-landmarks": the
    screen point is the physical one (a tracker should still give no cursor);
    bottom_left has no position and is not visible.
    """
    present = landmarks_present(variant)
    p = screen_point(pose) if variant != "no-monitor" else None
    xy: tuple[float, float] | None = None
    px: tuple[float, float] | None = None
    on = False
    if p is not None:
        pitch_x, pitch_y = SCREEN_W / SCREEN_PX[0], SCREEN_H / SCREEN_PX[1]
        px = (float(p[0] / pitch_x - 0.5), float(p[1] / pitch_y - 0.5))
        xy = (px[0] / (SCREEN_PX[0] - 1), px[1] / (SCREEN_PX[1] - 1))
        on = bool(0.0 <= p[0] <= SCREEN_W and 0.0 <= p[1] <= SCREEN_H)
    centers = landmark_centers()
    uv, _ = project_points(cam, pose, centers)
    front = pose.to_camera(centers)[:, 2] > 0
    h = LANDMARK_SQUARE / 2
    edge = np.linspace(-h, h, 9)
    ring = np.concatenate(
        [
            np.stack([edge, np.full(9, -h)], 1),
            np.stack([edge, np.full(9, h)], 1),
            np.stack([np.full(9, -h), edge], 1),
            np.stack([np.full(9, h), edge], 1),
        ]
    )
    visible = []
    for c in centers:
        pts = np.concatenate([c[:2] + ring, np.zeros((len(ring), 1))], 1)
        _, inside = project_points(cam, pose, pts)
        visible.append(bool(np.all(inside)))
    axis = pose.optical_axis()
    return MouseTruth(
        index=index,
        t=t,
        screen_xy=xy,
        screen_px=px,
        on_screen=on,
        landmarks_uv=[
            (float(a), float(b)) if f and q else None
            for (a, b), f, q in zip(uv, front, present, strict=True)
        ],
        visible=[v and q for v, q in zip(visible, present, strict=True)],
        view_angle_deg=math.degrees(math.acos(min(1.0, abs(float(axis[2]))))),
        camera_center=(float(pose.C[0]), float(pose.C[1]), float(pose.C[2])),
        rotation=pose.R.tolist(),
    )


def landmarks_present(variant: str) -> tuple[bool, bool, bool, bool]:
    """Which landmarks (LANDMARK_NAMES order) scene ``variant`` has."""
    if variant not in VARIANTS:
        raise OutputError(f"unknown camera-mouse scene {variant!r} ({', '.join(VARIANTS)})")
    if variant == "no-monitor":
        return (False, False, False, False)
    return (True, True, True, variant != "three-landmarks")


class MonitorScene:
    """The monitor (bezel, landmarks, screen content) and the wall, from a seed.

    ``content=False`` shows a flat grey screen; ``variant`` (VARIANTS) removes
    the monitor or one landmark (the no-false-lock fixtures).
    """

    def __init__(self, seed: int = 0, *, content: bool = True, variant: str = "normal") -> None:
        self.seed = seed
        self.content = content
        self.variant = variant
        self.present = landmarks_present(variant)
        rng = np.random.default_rng(seed)
        tw = round((SCREEN_W + 2 * BEZEL) / TEXEL)
        th = round((SCREEN_H + 2 * BEZEL) / TEXEL)
        base = np.full((th, tw, 3), BEZEL_GREY, np.float32)
        corners = zip(SCREEN_CORNERS, LANDMARK_OFFSETS, self.present, strict=True)
        for (cx, cy), (ox, oy), here in corners:
            if not here:
                continue
            u, v = self._texel(cx + ox, cy + oy)
            hs = LANDMARK_SQUARE / 2 / TEXEL
            cv2.rectangle(
                base,
                (round((u - hs) * 16), round((v - hs) * 16)),
                (round((u + hs) * 16), round((v + hs) * 16)),
                (WHITE,) * 3,
                -1,
                cv2.LINE_AA,
                4,
            )
            cv2.circle(
                base,
                (round(u * 16), round(v * 16)),
                round(LANDMARK_RADIUS / TEXEL * 16),
                (BLACK,) * 3,
                -1,
                cv2.LINE_AA,
                4,
            )
        self.monitor_base = base
        self.screen_box = (round(BEZEL / TEXEL), round(BEZEL / TEXEL))
        self.screen_shape = (round(SCREEN_H / TEXEL), round(SCREEN_W / TEXEL))
        n = 512
        noise = rng.normal(0, 1, (n // 16, n // 16, 3)).astype(np.float32)
        wall = cv2.resize(noise, (n, n), interpolation=cv2.INTER_CUBIC) * 25 + 140
        fine = cv2.GaussianBlur(rng.normal(0, 12, (n, n, 3)).astype(np.float32), (0, 0), 1.5)
        wall = wall + fine
        for _ in range(6):
            x0, y0 = rng.integers(0, n - 120, 2)
            w, h = rng.integers(40, 120, 2)
            col = tuple(float(c) for c in rng.uniform(60, 220, 3))
            cv2.rectangle(wall, (int(x0), int(y0)), (int(x0 + w), int(y0 + h)), col, -1)
        self.wall = np.clip(wall, 0, 255).astype(np.float32)
        self.blobs = rng.uniform(0, 1, (4, 4))

    @staticmethod
    def _texel(x: float, y: float) -> tuple[float, float]:
        """World (x, y) on the monitor plane -> monitor texture (u, v) of texel centres."""
        return (x + BEZEL) / TEXEL - 0.5, (y + BEZEL) / TEXEL - 0.5

    def monitor_texture(self, t: float) -> NDArray[np.float32]:
        """The monitor texture at time ``t`` (s): bezel, landmarks, and screen content.

        Content: a drifting colour gradient, a moving black disc and black bar,
        a white rectangle and a dark band (the landmarks' colours on screen).
        """
        tex = self.monitor_base.copy()
        if not self.content:
            tex[
                self.screen_box[1] : self.screen_box[1] + self.screen_shape[0],
                self.screen_box[0] : self.screen_box[0] + self.screen_shape[1],
            ] = 90.0
            return tex
        h, w = self.screen_shape
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        ph = 0.7 * t + 6 * float(self.blobs[0, 0])
        scr = np.empty((h, w, 3), np.float32)
        scr[..., 0] = 128 + 100 * np.sin(xx / w * 3 + ph)
        scr[..., 1] = 128 + 100 * np.sin(yy / h * 2.5 - ph * 0.8)
        scr[..., 2] = 128 + 100 * np.sin((xx + yy) / w * 2 + ph * 1.3)
        b = self.blobs
        for k in range(2):
            cx = w * (0.5 + 0.4 * math.sin(0.9 * t * (1 + b[k, 1]) + 6 * b[k, 2]))
            cy = h * (0.5 + 0.4 * math.sin(1.1 * t * (1 + b[k, 3]) + 6 * b[k, 0]))
            cv2.circle(
                scr,
                (int(cx * 16), int(cy * 16)),
                int((25 + 30 * k) * 16),
                (0.0,) * 3,
                -1,
                cv2.LINE_AA,
                4,
            )
        x0 = int(w * (0.2 + 0.15 * math.sin(0.5 * t)))
        cv2.rectangle(scr, (x0, int(h * 0.1)), (x0 + 180, int(h * 0.35)), (255.0,) * 3, -1)
        cv2.rectangle(
            scr, (int(w * 0.6), int(h * 0.7)), (int(w * 0.95), int(h * 0.78)), (0.0,) * 3, -1
        )
        scr[int(h * 0.85) :, :, :] *= 0.15
        tex[
            self.screen_box[1] : self.screen_box[1] + h, self.screen_box[0] : self.screen_box[0] + w
        ] = scr
        return tex


_GRIDS: dict[tuple[HandCamera, int], FloatArray] = {}


def _sample_rays(cam: HandCamera, supersample: int) -> FloatArray:
    """Undistorted normalized (x, y, 1) of every sub-pixel sample, (H*n, W*n, 3), cached."""
    key = (cam, supersample)
    if key not in _GRIDS:
        n = supersample
        offs = (np.arange(n) + 0.5) / n - 0.5
        u = (np.arange(cam.width)[:, None] + offs[None, :]).reshape(-1)
        v = (np.arange(cam.height)[:, None] + offs[None, :]).reshape(-1)
        uu, vv = np.meshgrid(u, v)
        xy = cam.pixel_to_normalized(np.stack([uu, vv], -1))
        _GRIDS[key] = np.concatenate([xy, np.ones((*xy.shape[:2], 1))], -1)
    return _GRIDS[key]


_GRIDS32: dict[tuple[HandCamera, int], NDArray[np.float32]] = {}


def _sample_rays32(cam: HandCamera, supersample: int) -> NDArray[np.float32]:
    """:func:`_sample_rays` in float32 (for the per-frame texture maps), cached."""
    key = (cam, supersample)
    if key not in _GRIDS32:
        _GRIDS32[key] = np.ascontiguousarray(_sample_rays(cam, supersample), np.float32)
    return _GRIDS32[key]


def _plane_hits(
    rays: FloatArray, pose: Pose, z: float
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """World (X, Y) where camera rays (x, y, 1) meet the plane z, and whether in front."""
    x, y = rays[..., 0], rays[..., 1]
    R = pose.R  # world direction d = R^T (x, y, 1)
    dz = R[0, 2] * x + R[1, 2] * y + R[2, 2]
    s = (z - pose.C[2]) / np.where(np.abs(dz) < 1e-12, 1e-12, dz)
    X = pose.C[0] + s * (R[0, 0] * x + R[1, 0] * y + R[2, 0])
    Y = pose.C[1] + s * (R[0, 1] * x + R[1, 1] * y + R[2, 1])
    return X, Y, s > 0


def _plane_homography(pose: Pose, z: float, origin: float, texel: float) -> FloatArray:
    """3x3 map from camera rays (x, y, 1) to texture (u, v, w) on the plane z.

    Texture coordinates are ((X - origin) / texel - 0.5, (Y - origin) / texel - 0.5)
    for the world point (X, Y, z) on the ray; w > 0 exactly when that point is
    in front of the camera.
    """
    R, C = pose.R, pose.C
    dz = z - C[2]
    world = np.stack([dz * R[:, 0] + C[0] * R[:, 2], dz * R[:, 1] + C[1] * R[:, 2], R[:, 2]])
    world *= 1.0 if dz > 0 else -1.0
    tex = np.array([[1 / texel, 0, -origin / texel - 0.5], [0, 1 / texel, -origin / texel - 0.5]])
    out: FloatArray = np.vstack([tex @ world, world[2:]])
    return out


def _texture_maps(
    rays: NDArray[np.float32], H: FloatArray
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.bool_]]:
    """Texture maps (u, v) for cv2.remap and the in-front mask, in float32."""
    x, y = rays[..., 0], rays[..., 1]
    h = [[float(c) for c in row] for row in H]
    w = h[2][0] * x + h[2][1] * y + h[2][2]
    front = w > 0
    inv = 1.0 / np.where(front, w, np.float32(1.0))
    u = (h[0][0] * x + h[0][1] * y + h[0][2]) * inv
    v = (h[1][0] * x + h[1][1] * y + h[1][2]) * inv
    return u.astype(np.float32, copy=False), v.astype(np.float32, copy=False), front


def render_pose(
    cam: HandCamera,
    scene: MonitorScene,
    pose: Pose,
    t: float,
    *,
    supersample: int = 3,
    texture: NDArray[np.float32] | None = None,
) -> FloatArray:
    """The noiseless picture (H, W, 3) float BGR of ``scene`` at time ``t`` from ``pose``.

    ``texture``: the monitor texture of time t if already made.
    """
    tex = scene.monitor_texture(t) if texture is None else texture
    rays32 = _sample_rays32(cam, supersample)
    wu, wv, wok = _texture_maps(rays32, _plane_homography(pose, WALL_Z, 0.0, WALL_TEXEL))
    # the wall texture tiles; BORDER_WRAP repeats it (coordinates stay small in float32)
    img = cv2.remap(scene.wall, wu, wv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    if not wok.all():
        img[~wok] = 60.0
    if scene.variant != "no-monitor":
        mu, mv, mok = _texture_maps(rays32, _plane_homography(pose, 0.0, -BEZEL, TEXEL))
        th, tw = tex.shape[:2]
        inside = mok & (mu >= -0.5) & (mu <= tw - 0.5) & (mv >= -0.5) & (mv <= th - 0.5)
        mon = cv2.remap(tex, mu, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        np.copyto(img, mon, where=inside[..., None])
    out: FloatArray = cv2.resize(img, (cam.width, cam.height), interpolation=cv2.INTER_AREA).astype(
        np.float64
    )
    return out


def landmark_labels(cam: HandCamera, pose: Pose, variant: str = "normal") -> NDArray[np.int8]:
    """Per pixel (H, W): which landmark's white square its centre sees (0..3), else -1."""
    present = landmarks_present(variant)
    rays = _sample_rays(cam, 1)
    x, y, ok = _plane_hits(rays, pose, 0.0)
    lab = np.full((cam.height, cam.width), -1, np.int8)
    h = LANDMARK_SQUARE / 2
    for k, c in enumerate(landmark_centers()):
        if not present[k]:
            continue
        lab[ok & (np.abs(x - c[0]) <= h) & (np.abs(y - c[1]) <= h)] = k
    return lab


def render_frame(
    cam: HandCamera,
    scene: MonitorScene,
    trajectory: str,
    index: int,
    *,
    fps: float = 30.0,
    exposure: float = 0.5,
    blur_samples: int = 5,
    supersample: int = 3,
    noise_sigma: float = 2.0,
    seed: int = 0,
) -> tuple[NDArray[np.uint8], MouseTruth]:
    """Frame ``index`` (BGR uint8) along ``trajectory`` and its truth.

    The frame's time is ``t = index / fps``; the shutter is open over
    ``exposure / fps`` seconds centred on t, rendered as ``blur_samples``
    sub-frames averaged (motion blur). Truth is the pose at t. Noise: a gain
    of 1 + N(0, 0.02) per frame and N(0, noise_sigma) grey levels per pixel,
    from ``seed`` and ``index``.
    """
    t = index / fps
    m = max(1, blur_samples)
    acc = np.zeros((cam.height, cam.width, 3))
    tex = scene.monitor_texture(t)
    for k in range(m):
        tk = t + exposure / fps * ((k + 0.5) / m - 0.5) if m > 1 else t
        acc += render_pose(
            cam, scene, trajectory_pose(trajectory, tk), t, supersample=supersample, texture=tex
        )
    img = acc / m
    if noise_sigma > 0:
        rng = np.random.default_rng([seed, index])
        img = img * (1.0 + rng.normal(0, 0.02)) + rng.normal(0, noise_sigma, img.shape)
    frame = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    return frame, frame_truth(cam, trajectory_pose(trajectory, t), index, t, variant=scene.variant)


def make_mouse_fixture(
    outdir: Path,
    *,
    trajectory: str = "drift",
    size: tuple[int, int] = (640, 480),
    frames: int = 60,
    fps: float = 30.0,
    seed: int = 0,
    variant: str = "normal",
    force: bool = False,
) -> dict[str, Any]:
    """Render a camera-mouse fixture folder atomically; returns what truth.json holds.

    Files: mouse.avi (MJPG), mouse_0000.png (frame 0, lossless), truth.json
    (camera intrinsics and distortion, monitor and landmark geometry, per-frame
    truth, the command that regenerates the folder) and landmarks.json (the
    landmark layout ``omnidev mouse --layout`` reads).
    """
    if trajectory not in TRAJECTORIES:
        raise OutputError(
            f"unknown camera-mouse trajectory {trajectory!r} ({', '.join(TRAJECTORIES)})"
        )
    outdir = Path(outdir)
    check_output_dir(outdir, force=force)  # before the rendering, not after
    cam = HandCamera.default(*size)
    landmarks_present(variant)
    scene = MonitorScene(seed, variant=variant)
    with atomic_dir(outdir, force=force) as tmp:
        video = cv2.VideoWriter(str(tmp / "mouse.avi"), cv2.VideoWriter.fourcc(*"MJPG"), fps, size)
        if not video.isOpened():
            raise OutputError(f"cannot write MJPG video in {tmp}")
        video.set(cv2.VIDEOWRITER_PROP_QUALITY, 90)
        per_frame = []
        for i in range(frames):
            img, truth = render_frame(cam, scene, trajectory, i, fps=fps, seed=seed)
            if i == 0:
                cv2.imwrite(str(tmp / "mouse_0000.png"), img)
            video.write(img)
            per_frame.append(asdict(truth))
        video.release()
        doc: dict[str, Any] = {
            "camera": {
                **asdict(cam),
                "matrix": cam.matrix().tolist(),
                "distortion": cam.distortion().tolist(),
                "model": "OpenCV pinhole, radial k1 k2 on normalized coordinates",
                "image_center": [(size[0] - 1) / 2, (size[1] - 1) / 2],
            },
            "monitor": {
                "screen_m": [SCREEN_W, SCREEN_H],
                "screen_px": list(SCREEN_PX),
                "bezel_m": BEZEL,
                "wall_z_m": WALL_Z,
            },
            "landmarks": {
                "names": list(LANDMARK_NAMES),
                "offsets_m": [list(o) for o in LANDMARK_OFFSETS],
                "offsets_note": "landmark disc centre minus matching screen corner; "
                "world x right, y down",
                "offsets_screen_px": [
                    [o[0] / SCREEN_W * SCREEN_PX[0], o[1] / SCREEN_H * SCREEN_PX[1]]
                    for o in LANDMARK_OFFSETS
                ],
                "square_m": LANDMARK_SQUARE,
                "disc_radius_m": LANDMARK_RADIUS,
            },
            "trajectory": trajectory,
            "scene": variant,
            "frames": frames,
            "fps": fps,
            "seed": seed,
            "conventions": (
                "world: origin screen top-left (lit area), x right, y down, "
                "z into the screen, metres; "
                "image pixel (0,0) = centre of top-left pixel; screen_px = X/pitch - 0.5, "
                "screen_xy = screen_px / (1920-1, 1080-1); truth is the pose at t = index/fps, "
                "the exposure (0.5/fps) is centred on t"
            ),
            "per_frame": per_frame,
            "regenerate": f"omnidev sim mouse {outdir} --trajectory {trajectory} "
            f"--size {size[0]}x{size[1]} "
            f"--frames {frames} --fps {fps:g} --seed {seed} --scene {variant} --force",
        }
        (tmp / "truth.json").write_text(json.dumps(doc, indent=1) + "\n")
        (tmp / "landmarks.json").write_text(json.dumps(landmark_layout(), indent=2) + "\n")
    return doc

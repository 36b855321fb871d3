"""Synthetic truth for the camera-mouse tests: a pinhole camera in front of a monitor plane.

World = the monitor plane frame of omnidev.mouse (mm, X right, Y down, screen TL at the
origin, Z = 0 the plane, the camera at Z < 0 looking towards +Z). Camera frame: x right,
y down, z forward. Image pixels with the origin at the center of the top-left pixel.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from omnidev.mouse.landmarks import LandmarkLayout

LAYOUT = LandmarkLayout.symmetric(
    520.0, 292.5, margin_mm=(25.0, 25.0), circle_diameter_mm=20.0, square_side_mm=34.0
)


def look_at(C, T, roll_deg=0.0):
    """World->camera rotation of a camera at C looking at T, rolled about its axis."""
    z = np.asarray(T, float) - np.asarray(C, float)
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    a = math.radians(roll_deg)
    Rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    return Rz @ R


class Camera:
    """A pinhole camera (no distortion): focal length f (pixels), image size, pose R, C."""

    def __init__(self, R, C, *, f=560.0, size=(640, 480)):
        self.R = np.asarray(R, float)
        self.C = np.asarray(C, float)
        self.size = size
        w, h = size
        self.K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])

    def project(self, X):
        X = np.atleast_2d(np.asarray(X, float))
        if X.shape[1] == 2:
            X = np.column_stack([X, np.zeros(len(X))])
        pc = (X - self.C) @ self.R.T
        q = pc @ self.K.T
        return q[:, :2] / q[:, 2:3]

    def plane_to_image(self):
        """3x3 homography monitor plane (mm) -> image pixels."""
        t = -self.R @ self.C
        return self.K @ np.column_stack([self.R[:, 0], self.R[:, 1], t])

    def true_cursor(self, layout=LAYOUT):
        """Normalized screen point under the image center, by ray-plane intersection."""
        w, h = self.size
        d_cam = np.linalg.solve(self.K, [(w - 1) / 2, (h - 1) / 2, 1.0])
        d = self.R.T @ d_cam
        lam = -self.C[2] / d[2]
        P = self.C + lam * d
        return np.array([P[0] / layout.screen_width_mm, P[1] / layout.screen_height_mm])


def oblique_camera(yaw_deg, *, pitch_deg=0.0, roll_deg=0.0, dist=800.0, aim=(0.58, 0.43)):
    """A camera ``dist`` mm from the screen point ``aim`` (normalized), seen at yaw/pitch."""
    T = np.array([aim[0] * LAYOUT.screen_width_mm, aim[1] * LAYOUT.screen_height_mm, 0.0])
    a, b = math.radians(yaw_deg), math.radians(pitch_deg)
    direction = np.array([math.sin(a) * math.cos(b), math.sin(b), -math.cos(a) * math.cos(b)])
    C = T + dist * direction
    # Aim a little off T so the image center does not sit on a symmetric point.
    return Camera(look_at(C, T + np.array([13.0, -7.0, 0.0]), roll_deg), C)


def render(
    cam,
    *,
    layout=LAYOUT,
    hide=(),
    distractors=True,
    monitor=True,
    decoy=True,
    ss=2,
    seed=0,
):
    """Grey uint8 image of the scene seen by ``cam``.

    The monitor plane (bezel, screen content, landmarks except those in ``hide``) is drawn
    at 4 px/mm and warped into the image at ``ss`` x resolution, then area-averaged.
    ``distractors`` adds dark landmark-sized blobs on the room background and on the
    screen content; ``decoy`` adds four dark dots on the screen in a rectangle of the
    landmarks' aspect ratio (content in the landmarks' colours).
    """
    rng = np.random.default_rng(seed)
    s = 4.0  # plane pixels per mm
    lm = layout.landmark_centers_mm()
    x_lo, y_lo = lm.min(axis=0) - 60.0
    x_hi, y_hi = lm.max(axis=0) + 60.0
    pw, ph = int((x_hi - x_lo) * s), int((y_hi - y_lo) * s)
    plane = np.full((ph, pw), 255, np.uint8)
    to_px = np.array([[s, 0, -x_lo * s], [0, s, -y_lo * s], [0, 0, 1.0]])

    def to_plane(x, y):
        return (round((x - x_lo) * s * 16), round((y - y_lo) * s * 16))

    W, H = layout.screen_width_mm, layout.screen_height_mm
    sh = 4
    # Bezel: dark frame 45 mm wide around the screen.
    cv2.rectangle(plane, to_plane(-45, -45), to_plane(W + 45, H + 45), 60, -1, cv2.LINE_AA, sh)
    # Screen content: a bright gradient with some soft shapes.
    xs = np.linspace(0, 1, pw)[None, :]
    ys = np.linspace(0, 1, ph)[:, None]
    content = (170 + 50 * xs * ys + 20 * np.sin(6 * xs)).astype(np.uint8)
    content = np.broadcast_to(content, plane.shape).copy()
    scr = np.zeros_like(plane)
    cv2.rectangle(scr, to_plane(0, 0), to_plane(W, H), 255, -1, cv2.LINE_AA, sh)
    a = scr.astype(np.float64) / 255.0
    plane = np.round(a * content + (1 - a) * plane).astype(np.uint8)
    cv2.circle(plane, to_plane(0.3 * W, 0.6 * H), int(40 * s * 16), 210, -1, cv2.LINE_AA, sh)
    if distractors:
        for _ in range(5):
            x, y = rng.uniform([0.1 * W, 0.15 * H], [0.9 * W, 0.85 * H])
            cv2.circle(
                plane, to_plane(x, y), int(rng.uniform(8, 11) * s * 16), 20, -1, cv2.LINE_AA, sh
            )
    if decoy:
        for x, y in ((0.35, 0.3), (0.65, 0.3), (0.65, 0.6), (0.35, 0.6)):
            cv2.circle(plane, to_plane(x * W, y * H), int(10 * s * 16), 15, -1, cv2.LINE_AA, sh)
    if monitor:
        half = layout.square_side_mm / 2
        r = layout.circle_diameter_mm / 2
        for i, (x, y) in enumerate(lm):
            if i in hide:
                continue
            cv2.rectangle(
                plane, to_plane(x - half, y - half), to_plane(x + half, y + half), 255, -1, 16, sh
            )
            cv2.circle(plane, to_plane(x, y), int(r * s * 16), 0, -1, cv2.LINE_AA, sh)
    w, h = cam.size
    # Full-res pixel x has its center at ss*x + (ss-1)/2 in the supersampled grid.
    T = np.array([[ss, 0, (ss - 1) / 2], [0, ss, (ss - 1) / 2], [0, 0, 1.0]])
    Hm = T @ cam.plane_to_image() @ np.linalg.inv(to_px)
    room = np.full((h * ss, w * ss), 140, np.uint8)
    room[:, :] = (120 + 40 * np.linspace(0, 1, w * ss)[None, :]).astype(np.uint8)
    if distractors:
        for _ in range(7):
            x, y = rng.uniform([0, 0], [w * ss, h * ss])
            cv2.circle(room, (int(x), int(y)), int(rng.uniform(5, 8) * ss), 10, -1, cv2.LINE_AA)
    if monitor:
        warped = cv2.warpPerspective(plane, Hm, (w * ss, h * ss), flags=cv2.INTER_LINEAR)
        frame = np.zeros_like(plane)
        cv2.rectangle(frame, to_plane(-45, -45), to_plane(W + 45, H + 45), 255, -1, cv2.LINE_AA, sh)
        mask = cv2.warpPerspective(frame, Hm, (w * ss, h * ss), flags=cv2.INTER_LINEAR)
        m = mask.astype(np.float64) / 255.0
        room = np.round(m * warped + (1 - m) * room).astype(np.uint8)
    img = cv2.resize(room, (w, h), interpolation=cv2.INTER_AREA)
    noise = rng.normal(0, 2.0, img.shape)
    return np.clip(img + noise, 0, 255).astype(np.uint8)

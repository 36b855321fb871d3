"""Randomized rendered cases for the pano-mapping tables, each with exact maps and truth views.

Every case is drawn from a seed: the camera (optics, misalignment, tilt, pixel
aspect), the scene's texture, the landmarks, and the views. A case holds

- the omni-image (BGR uint8) and the mask of pixels that see the scene;
- ``n_landmarks`` exact landmark pairs: pixel and direction from the mirror
  center O_m (world frame, Z up), and each landmark's distance;
- for each view (``panorama``, ``perspective``, ``top``) the truth image
  (rendered from the scene, supersampled), the mask where the camera sees it,
  and the renderer's exact maps (the ceiling of any unwarp).

Kinds (:data:`KINDS`):

- ``svp-aligned``: an SVP hyperbolic mirror (eq. 2.1), mirror shape and focal
  length varied, center off the image middle;
- ``svp-aspect``: the same with non-square pixels (a 4:3 sensor read out at
  another aspect: v scale 0.72-0.92 of u);
- ``fisheye-tilt``: a fisheye looking up, r = f (a + k1 a^3 + k2 a^5), its axis
  tilted 3-10 degrees from the vertical;
- ``mirror-misaligned``: the non-SVP hyperbolic-mirror ray tracer of
  :mod:`omnidev.sim.nonsvp` with the lens 1-3 mm off the mirror axis and its
  axis 1-3 degrees off, in the textured room (mm).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.camera import Maps, project_maps
from omnidev.sim.imperfect import ImperfectCamera, PolyFisheyeCamera, rotation_vector
from omnidev.sim.mirrors import SvpHyperbolicCamera
from omnidev.sim.render import render_omni, render_view
from omnidev.sim.scene import RoomScene
from omnidev.views import Panorama, Perspective, PlaneView, TopView, View

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Image = NDArray[np.uint8]

Kind = Literal["svp-aligned", "svp-aspect", "fisheye-tilt", "mirror-misaligned"]
KINDS: tuple[Kind, ...] = ("svp-aligned", "svp-aspect", "fisheye-tilt", "mirror-misaligned")


@dataclass(frozen=True)
class TruthView:
    """One view: the truth image, where the camera sees it, and the exact maps."""

    view: View
    truth: Image
    seen: BoolArray
    exact: Maps


@dataclass(frozen=True)
class PanoCase:
    """A rendered case (see the module docstring)."""

    kind: Kind
    seed: int
    omni: Image
    omni_valid: BoolArray  # (H, W) pixels that see the scene
    uv: FloatArray  # (n, 2) exact landmark pixels
    dirs: FloatArray  # (n, 3) landmark directions from O_m, world frame
    distance: FloatArray  # (n,) landmark distance from O_m (scene unit)
    image_center: tuple[float, float]  # the pixel of the direction along the camera axis
    image_size: tuple[int, int]
    views: dict[str, TruthView]
    params: dict[str, Any]  # what was drawn


def _room_landmarks(
    cam: Any, scene: RoomScene, band: tuple[float, float], n: int, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, FloatArray]:
    lo, hi = band
    uvs: list[FloatArray] = []
    dirs: list[FloatArray] = []
    dist: list[FloatArray] = []
    while sum(len(u) for u in uvs) < n:
        k = 4 * n
        th = rng.uniform(0, 2 * math.pi, k)
        rho = np.radians(rng.uniform(lo + 0.5, hi - 0.5, k))
        d = np.stack([np.cos(rho) * np.cos(th), np.cos(rho) * np.sin(th), np.sin(rho)], 1)
        t, _ = scene.intersect(np.zeros_like(d), d)
        p = d * t[:, None]
        uv, ok = cam.project(p, finite=True)
        uvs.append(uv[ok])
        dirs.append(d[ok])
        dist.append(t[ok])
    return (
        np.concatenate(uvs)[:n],
        np.concatenate(dirs)[:n],
        np.concatenate(dist)[:n],
    )


def _omni_valid(cam: Any) -> BoolArray:
    w, h = cam.image_size
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
    uv = np.stack([uu, vv], -1)
    _, ok = cam.project(cam.back_project(uv), finite=False)
    return np.asarray(ok, np.bool_)


def _svp_case(
    kind: Kind, seed: int, rng: np.random.Generator, size: int, n: int, ss: int
) -> PanoCase:
    scene = RoomScene(seed)
    base = SvpHyperbolicCamera.default(size)
    a = base.a * rng.uniform(0.85, 1.15)
    b = base.b * rng.uniform(0.85, 1.15)
    params: dict[str, Any] = {"a_mm": a, "b_mm": b}
    if kind == "svp-aligned":
        w, h = size, size
        center = (w / 2 - 0.5 + rng.uniform(-6, 6), h / 2 - 0.5 + rng.uniform(-6, 6))
        cam0 = dataclasses.replace(base, a=a, b=b, center=center)
        f = _rim_focal(cam0, 0.47 * min(w, h))
        cam: Any = dataclasses.replace(cam0, f=f)
    else:
        aspect = float(rng.uniform(0.72, 0.92))
        w, h = size, size * 3 // 4  # the 4:3 sensor
        cb = (w / 2 - 0.5 + rng.uniform(-6, 6), h / 2 - 0.5 + rng.uniform(-6, 6))
        cam0 = dataclasses.replace(base, a=a, b=b, center=cb, image_size=(w, h))
        f = _rim_focal(cam0, 0.47 * h)
        hh = round(h * aspect)
        cam = ImperfectCamera(
            dataclasses.replace(cam0, f=f, cutoff_radius=0.12 * h),
            np.eye(3),
            aspect=hh / h,
            center_px=(cb[0], (cb[1] + 0.5) * hh / h - 0.5),
            size=(w, hh),
        )
        params["aspect"] = hh / h
    band = cam.default_elevation_deg()
    uv, dirs, dist = _room_landmarks(cam, scene, band, n, rng)
    omni = render_omni(cam, scene, supersample=ss, noise_sigma=1.0, seed=seed)
    pan = float(rng.uniform(0, 360))
    views: dict[str, View] = {
        "panorama": Panorama(720, 200, band),
        "perspective": Perspective(320, 240, fov_deg=80, pan_deg=pan, tilt_deg=-25),
        "top": TopView(240, 240, 3.0, 3.0, -scene.floor_depth),
    }
    return PanoCase(
        kind,
        seed,
        omni,
        _omni_valid(cam),
        uv,
        dirs,
        dist,
        cam.center,
        cam.image_size,
        {k: _truth(v, scene, cam, ss) for k, v in views.items()},
        params,
    )


def _rim_focal(cam: SvpHyperbolicCamera, r_px: float) -> float:
    """f putting the mirror's rim at ``r_px`` from the center."""
    unit = cam.radius_of_elevation(np.array(cam.top_elevation)) / cam.f
    return float(r_px / unit)


def _fisheye_case(seed: int, rng: np.random.Generator, size: int, n: int, ss: int) -> PanoCase:
    scene = RoomScene(seed)
    max_angle = math.radians(rng.uniform(92, 100))
    k1 = float(rng.uniform(-0.06, 0.03))
    k2 = float(rng.uniform(-0.01, 0.01))
    unit = max_angle + k1 * max_angle**3 + k2 * max_angle**5
    center = (size / 2 - 0.5 + rng.uniform(-6, 6), size / 2 - 0.5 + rng.uniform(-6, 6))
    lens = PolyFisheyeCamera(0.47 * size / unit, k1, k2, (size, size), center, max_angle)
    tilt = float(rng.uniform(3, 10))
    axis = float(rng.uniform(0, 360))
    cam = ImperfectCamera(lens, rotation_vector(axis, tilt))
    band = cam.default_elevation_deg()
    uv, dirs, dist = _room_landmarks(cam, scene, band, n, rng)
    omni = render_omni(cam, scene, supersample=ss, noise_sigma=1.0, seed=seed)
    pan = float(rng.uniform(0, 360))
    views: dict[str, View] = {
        "panorama": Panorama(720, 200, (band[0], 60.0)),
        "perspective": Perspective(320, 240, fov_deg=80, pan_deg=pan, tilt_deg=30),
        "top": TopView(240, 240, 3.0, 3.0, scene.ceiling_height),
    }
    return PanoCase(
        "fisheye-tilt",
        seed,
        omni,
        _omni_valid(cam),
        uv,
        dirs,
        dist,
        cam.center,
        cam.image_size,
        {k: _truth(v, scene, cam, ss) for k, v in views.items()},
        {
            "tilt_deg": tilt,
            "tilt_axis_deg": axis,
            "k1": k1,
            "k2": k2,
            "max_angle_deg": math.degrees(max_angle),
        },
    )


def _truth(view: View, scene: RoomScene, cam: Any, ss: int) -> TruthView:
    img, seen = render_view(view, scene, supersample=ss, camera=cam)
    return TruthView(view, img, seen, project_maps(cam, view))


# ---------------------------------------------------------------- the misaligned mirror


def _misaligned_case(
    seed: int, rng: np.random.Generator, size: tuple[int, int], n: int, ss: int
) -> PanoCase:
    from omnidev.nonsvp.model import DISSERTATION_CAMERA, NonSvpCamera, Pose
    from omnidev.sim import nonsvp as ns
    from omnidev.sim.pseudo_target import TexturedRoom

    base = DISSERTATION_CAMERA
    svp = NonSvpCamera.svp(base.mirror, dataclasses.replace(base.lens, size=size))
    off = float(rng.uniform(1, 3))
    oa = float(rng.uniform(0, 2 * math.pi))
    ang = math.radians(float(rng.uniform(1, 3)))
    aa = float(rng.uniform(0, 2 * math.pi))
    tz = svp.pose.T[2] + float(rng.uniform(-1, 1))
    pose = Pose(
        pitch=ang * math.cos(aa),
        yaw=ang * math.sin(aa),
        tilt=float(rng.uniform(-0.02, 0.02)),
        T=(off * math.cos(oa), off * math.sin(oa), tz),
    )
    cam = NonSvpCamera(base.mirror, svp.lens, pose)
    tc = ns.TracedCamera.from_camera(cam)
    scene = TexturedRoom(seed)
    omni, omni_valid = ns.render_omni(tc, scene, supersample=ss, noise_sigma=1.0, seed=seed)
    # landmarks on the walls and the floor, pixels by Fermat's principle
    uvs: list[FloatArray] = []
    dirs: list[FloatArray] = []
    dist: list[FloatArray] = []
    while sum(len(u) for u in uvs) < n:
        k = 4 * n
        th = rng.uniform(0, 2 * math.pi, k)
        rho = np.radians(rng.uniform(-88, 5, k))
        d = np.stack([np.cos(rho) * np.cos(th), np.cos(rho) * np.sin(th), np.sin(rho)], 1)
        t, on_surface = _room_hit(scene, d)
        X = d * t[:, None]
        M, ok = ns.mirror_points_towards(tc, X)
        uv, ok2 = ns.project_to_pixels(tc, M)
        good = ok & ok2 & on_surface
        if np.any(good):
            vis = _visible(omni_valid, uv[good])
            uvs.append(uv[good][vis])
            dirs.append(d[good][vis])
            dist.append(t[good][vis])
    uv_all, d_all, t_all = (np.concatenate(x)[:n] for x in (uvs, dirs, dist))
    nadir, _ = ns.project_to_pixels(
        tc, ns.mirror_points_towards(tc, np.array([[0.0, 0.0, -1e7]]))[0]
    )
    planes = ns.dissertation_planes(240, 180)
    side = int(rng.integers(0, 4))
    views: dict[str, TruthView] = {}
    for name, plane in (("perspective", planes[f"side_{side}"]), ("top", planes["top"])):
        img, seen = ns.render_view_plane(tc, scene, plane, supersample=ss)
        mx, my, ok = ns.view_plane_map(tc, plane)
        w, h = tc.size
        views[name] = TruthView(plane, img, seen, Maps(mx, my, ok, (w, h)))
    views["panorama"] = _misaligned_panorama(tc, scene, Panorama(720, 200, (-55.0, 5.0)), ss)
    return PanoCase(
        "mirror-misaligned",
        seed,
        omni,
        omni_valid,
        uv_all,
        d_all,
        t_all,
        (float(nadir[0, 0]), float(nadir[0, 1])),
        tc.size,
        views,
        {
            "lens_offset_mm": off,
            "axis_tilt_deg": math.degrees(ang),
            "pose": dataclasses.asdict(pose),
        },
    )


def _room_hit(scene: Any, d: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Distance from O_m to the textured room's walls/floor along unit ``d`` (mm), and hit mask."""
    from omnidev.sim.pseudo_target import GROUND_Z, SIDE_DISTANCE

    ts = []
    for k in range(4):
        a = math.radians(45.0 + 90.0 * k)
        nrm = np.array([math.cos(a), math.sin(a), 0.0])
        den = d @ nrm
        with np.errstate(divide="ignore", invalid="ignore"):
            t = SIDE_DISTANCE / den
        ts.append(np.where(den > 1e-12, t, np.inf))
    with np.errstate(divide="ignore", invalid="ignore"):
        tf = GROUND_Z / d[:, 2]
    ts.append(np.where(d[:, 2] < -1e-12, tf, np.inf))
    tt = np.stack(ts, 1)
    face = np.argmin(tt, 1)
    t = tt[np.arange(len(d)), face]
    z = d[:, 2] * t
    hit = np.isfinite(t) & ((face == 4) | (z <= scene.wall_top))
    return np.where(hit, t, 1e7), hit


def _visible(valid: BoolArray, uv: FloatArray) -> BoolArray:
    h, w = valid.shape
    iu = np.clip(np.round(uv[:, 0]).astype(int), 0, w - 1)
    iv = np.clip(np.round(uv[:, 1]).astype(int), 0, h - 1)
    return np.asarray(valid[iv, iu], np.bool_)


def _misaligned_panorama(tc: Any, scene: Any, view: Panorama, ss: int) -> TruthView:
    """Panorama truth of the non-SVP camera: the room seen from O_m; exact maps by Fermat."""
    from omnidev.sim import nonsvp as ns

    def points(v: Panorama) -> tuple[FloatArray, FloatArray]:
        d = v.points(None).reshape(-1, 3)
        t, _ = _room_hit(scene, d)
        return d, d * t[:, None]

    big = dataclasses.replace(view, width=view.width * ss, height=view.height * ss)
    d, _ = points(big)
    col = scene.shade(np.zeros(3), d).reshape(big.height, big.width, 3)
    img = cv2.resize(col, (view.width, view.height), interpolation=cv2.INTER_AREA)
    truth = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    _, X = points(view)
    M, ok = ns.mirror_points_towards(tc, X)
    uv, ok2 = ns.project_to_pixels(tc, M)
    shape = (view.height, view.width)
    valid = (ok & ok2).reshape(shape)
    maps = Maps(
        uv[:, 0].reshape(shape).astype(np.float32),
        uv[:, 1].reshape(shape).astype(np.float32),
        valid,
        tc.size,
    )
    return TruthView(view, truth, valid, maps)


def make_case(
    kind: Kind,
    seed: int,
    *,
    size: int | None = None,
    n_landmarks: int = 300,
    supersample: int = 2,
) -> PanoCase:
    """Render one case of ``kind`` from ``seed`` (see the module docstring).

    ``size``: the omni-image's width in px (default 960 for the SVP and fisheye
    kinds, 640 for the misaligned mirror, whose image is 4:3).
    """
    rng = np.random.default_rng([seed, KINDS.index(kind)])
    if kind in ("svp-aligned", "svp-aspect"):
        return _svp_case(kind, seed, rng, size or 960, n_landmarks, supersample)
    if kind == "fisheye-tilt":
        return _fisheye_case(seed, rng, size or 960, n_landmarks, supersample)
    if kind == "mirror-misaligned":
        w = size or 640
        return _misaligned_case(seed, rng, (w, w * 3 // 4), n_landmarks, supersample)
    raise ValueError(f"unknown case kind {kind!r} (choose from {', '.join(KINDS)})")


__all__ = ["KINDS", "PanoCase", "TruthView", "make_case"]
_ = PlaneView  # the side views of the misaligned mirror are PlaneViews


# ---------------------------------------------------------------- image-center renders


@dataclass(frozen=True)
class CenterCase:
    """An omni-image with camera-like degradations and its true image center."""

    kind: str  # "mirror" or "fisheye"
    seed: int
    image: Image
    center: tuple[float, float]
    radius: float  # px of the outer boundary along u
    look: dict[str, Any]  # the degradations drawn


def degrade(
    image: Image, rng: np.random.Generator, center: tuple[float, float], radius: float
) -> tuple[Image, dict[str, Any]]:
    """What a real camera adds: exposure, gamma, vignetting, blur, noise, JPEG, housing.

    Vignetting is radial about ``center``; the housing is a dark arm crossing
    the rim from the frame's edge (a mount) and/or a faint bright ring just
    outside the disc (a lens barrel's reflection).
    """
    h, w = image.shape[:2]
    img = image.astype(np.float64)
    look: dict[str, Any] = {}
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
    r = np.hypot(uu - center[0], vv - center[1]) / radius
    vig = float(rng.uniform(0.0, 0.6))
    img *= (1.0 - vig * np.clip(r, 0, 1) ** 2)[..., None]
    look["vignetting"] = vig
    if rng.random() < 0.3:
        ring_r = radius * float(rng.uniform(1.01, 1.04)) + 3
        ring_w = float(rng.uniform(2, 5))
        grey = float(rng.uniform(35, 80))
        ring = np.exp(-(((r * radius - ring_r) / ring_w) ** 2))
        img = np.maximum(img, (grey * ring)[..., None])
        look["ring"] = {"radius": ring_r, "grey": grey}
    if rng.random() < 0.4:
        ang = float(rng.uniform(0, 2 * math.pi))
        width = radius * float(rng.uniform(0.04, 0.1))
        dx, dy = uu - center[0], vv - center[1]
        along = dx * math.cos(ang) + dy * math.sin(ang)
        across = -dx * math.sin(ang) + dy * math.cos(ang)
        arm = (np.abs(across) < width / 2) & (along > radius * float(rng.uniform(0.75, 0.95)))
        img[arm] = float(rng.uniform(8, 30))
        look["arm_deg"] = math.degrees(ang)
    gain = float(rng.uniform(0.6, 1.4))
    gamma = float(rng.uniform(0.8, 1.25))
    img = 255.0 * np.clip(img * gain / 255.0, 0, 1) ** gamma
    look["gain"], look["gamma"] = gain, gamma
    blur = float(rng.uniform(0.0, 1.2))
    if blur > 0.2:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), blur), np.float64)
    look["blur"] = blur
    noise = float(rng.uniform(0.5, 6.0))
    img += rng.normal(0, noise, img.shape)
    look["noise"] = noise
    out = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    if rng.random() < 0.5:
        q = int(rng.integers(60, 96))
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, q])
        assert ok
        out = np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR), np.uint8)
        look["jpeg"] = q
    return out, look


def make_center_case(
    kind: str, seed: int, size: tuple[int, int], *, supersample: int = 1
) -> CenterCase:
    """A mirror (SVP, cut-off circle) or fisheye render of ``size`` with :func:`degrade` applied."""
    rng = np.random.default_rng([seed, 11, size[0], size[1]])
    w, h = size
    scene = RoomScene(seed)
    center = (w / 2 - 0.5 + rng.uniform(-15, 15), h / 2 - 0.5 + rng.uniform(-15, 15))
    fill = float(rng.uniform(0.42, 0.48)) * min(w, h)
    cam: Any
    if kind == "mirror":
        base = SvpHyperbolicCamera.default(min(w, h))
        base = dataclasses.replace(
            base,
            a=base.a * rng.uniform(0.85, 1.15),
            b=base.b * rng.uniform(0.85, 1.15),
            image_size=(w, h),
            center=center,
            cutoff_radius=float(rng.uniform(0.08, 0.2)) * min(w, h),
        )
        cam = dataclasses.replace(base, f=_rim_focal(base, fill))
    elif kind == "fisheye":
        max_angle = math.radians(rng.uniform(90, 100))
        k1 = float(rng.uniform(-0.06, 0.03))
        unit = max_angle + k1 * max_angle**3
        cam = PolyFisheyeCamera(fill / unit, k1, 0.0, (w, h), center, max_angle)
    else:
        raise ValueError(f"kind {kind!r}: mirror or fisheye")
    img = render_omni(cam, scene, supersample=supersample)
    out, look = degrade(img, rng, center, fill)
    return CenterCase(kind, seed, out, center, fill, look)

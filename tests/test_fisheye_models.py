"""Lens models of omnidev.fisheye.models against closed forms, OpenCV and the papers' formulas."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

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
from tests.conftest import REALDATA

W, H = 640, 480

# ss of ocamcalib_urban_samples/Fisheye1 (OCamCalib subpixel), centred in a 640x480 image
SS = (-337.4373582216233, 0.0, 0.0012324461031028204, -1.35588258728807e-06, 2.9146541692232028e-09)

MODELS: dict[str, tuple[LensModel, float]] = {
    # name: (model, round-trip tolerance in px: exact formulas 1e-9, iterative inverses 1e-8)
    "kb4": (KannalaBrandt(250.0, 251.0, 321.3, 238.7, (0.02, -0.01, 0.003, -0.0004), 0.4), 1e-8),
    "mei": (Unified(420.0, 418.0, 322.0, 241.0, 1.3, 0.2, -0.12, 0.03, 0.0008, -0.0005), 1e-8),
    "mei-para": (Unified(300.0, 300.0, 319.5, 239.5, 1.0), 1e-9),
    "mei-xi<1": (Unified(380.0, 381.0, 319.5, 239.5, 0.7, 0.0, 0.05, -0.01), 1e-8),
    "equidistant": (IdealFisheye("equidistant", 140.0, 320.2, 240.9), 1e-9),
    "equisolid": (IdealFisheye("equisolid", 150.0, 320.2, 240.9, 1.02), 1e-9),
    "stereographic": (IdealFisheye("stereographic", 110.0, 320.2, 240.9), 1e-9),
    "orthographic": (IdealFisheye("orthographic", 230.0, 320.2, 240.9), 1e-9),
    "scaramuzza": (Scaramuzza(SS, 240.3, 319.1, 0.9989, -0.0001, -0.0003), 1e-8),
    "ds": (DoubleSphere(160.0, 161.0, 319.0, 240.0, -0.25, 0.58), 1e-9),
    "ds-a<.5": (DoubleSphere(200.0, 200.0, 319.0, 240.0, 0.3, 0.45), 1e-9),
    "eucm": (EUCM(230.0, 231.0, 319.0, 240.0, 0.62, 1.05), 1e-9),
    "eucm-a<.5": (EUCM(300.0, 300.0, 319.0, 240.0, 0.4, 0.9), 1e-9),
    "fov": (FieldOfView(250.0, 251.0, 319.0, 240.0, 0.93), 1e-9),
}


def pixel_grid(step: float = 3.0) -> np.ndarray:
    u, v = np.meshgrid(np.arange(-0.5, W, step), np.arange(-0.5, H, step))
    return np.stack([u, v], -1)


def directions(max_angle: float, n_angle: int = 400, n_az: int = 120) -> np.ndarray:
    t = np.linspace(0.0, max_angle, n_angle)[:, None]
    a = np.linspace(-math.pi, math.pi, n_az, endpoint=False)[None, :]
    return np.stack(
        [np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.broadcast_to(np.cos(t), (n_angle, n_az))],
        -1,
    )


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


@pytest.mark.parametrize("key", list(MODELS))
def test_pixel_round_trip_over_the_image(key: str) -> None:
    model, tol = MODELS[key]
    uv = pixel_grid()
    rays, ok = model.unproject(uv)
    assert ok.mean() > 0.5, ok.mean()  # the models image most of the frame
    assert np.all(np.isfinite(rays[ok])) and np.all(np.isnan(rays[~ok]))
    np.testing.assert_allclose(np.linalg.norm(rays[ok], axis=-1), 1.0, atol=1e-14)
    back, ok2 = model.project(rays)
    assert np.all(ok2[ok])
    err = np.abs(back[ok] - uv[ok]).max()
    assert err < tol, (key, err)


@pytest.mark.parametrize("key", list(MODELS))
def test_ray_round_trip_over_the_field_of_view(key: str) -> None:
    model, tol = MODELS[key]
    top = min(model.max_angle, math.pi) - 1e-6
    rays = directions(top)
    uv, ok = model.project(rays * 3.7)  # points at any distance project like their directions
    assert np.all(ok), (key, ok.mean())
    assert np.all(np.isfinite(uv))
    centre = model.project(np.array([0.0, 0.0, 1.0]))[0]
    # rays whose pixels lie within 10 image widths of the centre (where the model's radius
    # diverges at its limit, e.g. the parabolic mirror's back axis, pixels run to 1e11 px)
    near = np.linalg.norm(uv - centre, axis=-1) < 10 * W
    assert near.mean() > 0.8
    back, ok2 = model.unproject(uv)
    assert ok2[near].all(), (key, ok2.mean())
    # the ray error is the pixel error over d(radius)/d(angle): where a model's radius stops
    # growing at its limit (orthographic at 90 deg, equisolid at 180) that scale vanishes,
    # so the ray figure leaves out the last 3 % of the angles and pixels are checked everywhere
    inner = near & (np.linspace(0, 1, rays.shape[0])[:, None] < 0.97)
    err = angle_between(back[inner], rays[inner]).max()
    assert err < tol / 10, (key, err)
    again, ok3 = model.project(back[near])
    assert ok3.all()
    assert np.abs(again - uv[near]).max() < tol, key


@pytest.mark.parametrize("key", list(MODELS))
def test_radius_grows_with_the_angle_inside_the_mask(key: str) -> None:
    """The validity masks keep each model injective: along a meridian, valid pixels move
    strictly outwards, and the mask ends where the model's formula folds or diverges."""
    model, _ = MODELS[key]
    t = np.linspace(0, math.pi, 20001)
    rays = np.stack([np.sin(t) * 0.6, np.sin(t) * 0.8, np.cos(t)], -1)
    uv, ok = model.project(rays)
    assert ok[0] and np.all(np.diff(ok.astype(int)) <= 0)  # one valid interval from the axis
    assert abs(t[ok].max() - min(model.max_angle, math.pi)) < 2e-4
    centre = model.project(np.array([0.0, 0.0, 1.0]))[0]
    r = np.hypot(*(uv[ok] - centre).T)
    assert np.all(np.diff(r) > 0), key


def test_kb4_matches_cv2_fisheye() -> None:
    model = MODELS["kb4"][0]
    assert isinstance(model, KannalaBrandt)
    K = np.array([[model.fx, model.skew, model.cx], [0, model.fy, model.cy], [0, 0, 1.0]])
    D = np.array(model.k, np.float64)
    rays = directions(math.radians(89.0), 60, 60).reshape(-1, 3)
    ours, ok = model.project(rays)
    assert ok.all()
    cv, _ = cv2.fisheye.projectPoints(
        rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D, alpha=model.skew / model.fx
    )
    assert np.abs(cv.reshape(-1, 2) - ours).max() < 1e-6
    # undistortPoints returns x/z, y/z
    # cv2.fisheye.undistortPoints ignores K's skew: compare without it
    model = KannalaBrandt(model.fx, model.fy, model.cx, model.cy, model.k)
    K[0, 1] = 0.0
    ours, _ = model.project(rays)
    und = cv2.fisheye.undistortPoints(
        ours.reshape(-1, 1, 2),
        K,
        D,
        criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-14),
    ).reshape(-1, 2)
    back, ok2 = model.unproject(ours)
    assert ok2.all()
    front = rays[:, 2] > 0.05  # x/z blows up at 90 degrees
    got = back[front, :2] / back[front, 2:]
    ref = und[front]
    # compare in pixels (scaled by the focal length)
    assert np.abs((got - ref) * model.fx).max() < 1e-6


def test_mei_matches_cv2_omnidir() -> None:
    model = MODELS["mei"][0]
    assert isinstance(model, Unified)
    K = np.array([[model.fx, model.skew, model.cx], [0, model.fy, model.cy], [0, 0, 1.0]])
    D = np.array([[model.k1, model.k2, model.p1, model.p2]])
    rays = directions(math.radians(85.0), 60, 60).reshape(-1, 3)
    ours, ok = model.project(rays)
    assert ok.all()
    cv, _ = cv2.omnidir.projectPoints(
        rays.reshape(1, -1, 3), np.zeros((1, 3)), np.zeros((1, 3)), K, model.xi, D
    )
    assert np.abs(cv.reshape(-1, 2) - ours).max() < 1e-6
    und = cv2.omnidir.undistortPoints(
        ours.reshape(1, -1, 2), K, D, np.array([[model.xi]]), np.eye(3)
    ).reshape(-1, 2)
    back, ok2 = model.unproject(ours)
    assert ok2.all()
    got = back[:, :2] / back[:, 2:]
    assert np.abs((got - und) * model.fx).max() < 1e-6


def test_ideal_lenses_follow_their_closed_forms() -> None:
    f, cx, cy = 150.0, 320.0, 240.0
    forms = {
        "equidistant": (lambda t: f * t, 180.0),
        "equisolid": (lambda t: 2 * f * math.sin(t / 2), 180.0),
        "stereographic": (lambda t: 2 * f * math.tan(t / 2), 180.0),
        "orthographic": (lambda t: f * math.sin(t), 90.0),
    }
    for name, (radius, limit_deg) in forms.items():
        lens = IdealFisheye(name, f, cx, cy, aspect=1.1)  # type: ignore[arg-type]
        for deg in (0.0, 10.0, 45.0, 80.0, 89.0, 91.0, 120.0, 179.0, 180.0):
            t = math.radians(deg)
            az = math.radians(30.0)
            ray = np.array([math.sin(t) * math.cos(az), math.sin(t) * math.sin(az), math.cos(t)])
            uv, ok = lens.project(ray)
            if deg >= limit_deg:
                assert not ok, (name, deg)
                continue
            assert ok, (name, deg)
            r = radius(t)
            expect = (cx + r * math.cos(az), cy + 1.1 * r * math.sin(az))
            assert np.abs(uv - expect).max() < 1e-9, (name, deg)


def test_kb4_200_degree_field_of_view() -> None:
    """A 200-degree KB4 lens: rays up to 100 degrees from the axis image finitely, rays
    beyond are masked; cv2.fisheye (through x/z) puts rays behind the lens in front."""
    # theta_d = theta (1 + k1 theta^2 ...) stays monotonic up to about 106 degrees
    lens = KannalaBrandt(180.0, 180.0, 319.5, 239.5, (-0.06, -0.004, 0.0, 0.0))
    assert math.radians(100) < lens.max_angle < math.radians(120)
    rays = directions(math.radians(100.0), 200, 90)
    uv, ok = lens.project(rays)
    assert ok.all() and np.all(np.isfinite(uv))
    beyond = directions(math.pi, 400, 90)
    t = np.linspace(0, math.pi, 400)
    uvb, okb = lens.project(beyond)
    assert np.all(okb[t <= lens.max_angle]) and not np.any(okb[t > lens.max_angle])
    assert np.all(np.isfinite(uvb[okb])) and np.all(np.isnan(uvb[~okb]))
    back, okr = lens.unproject(uv)
    assert okr.all() and angle_between(back, rays).max() < 1e-9
    # behind the lens plane (100 deg) the angle of (x/z, y/z) is that of a ray at 80 deg
    behind = rays[-1].reshape(-1, 1, 3)
    K = np.array([[180.0, 0, 319.5], [0, 180.0, 239.5], [0, 0, 1]])
    cv, _ = cv2.fisheye.projectPoints(behind, np.zeros(3), np.zeros(3), K, np.array(lens.k))
    r_cv = np.hypot(*(cv.reshape(-1, 2) - (319.5, 239.5)).T)
    r_ours = np.hypot(*(uv[-1] - (319.5, 239.5)).T)
    assert np.all(r_cv < r_ours - 10)  # OpenCV folds the rays behind the lens inwards
    # pixels beyond the image of the 106-degree rim are masked, the rest unproject
    far, okf = lens.unproject(np.array([[319.5 + 180.0 * 2.5, 239.5], [319.5, 239.5]]))
    assert okf.tolist() == [False, True] and np.isnan(far[0]).all()


def test_equidistant_200_degrees_and_masks() -> None:
    lens = IdealFisheye("equidistant", 1000 / math.radians(200), 511.5, 511.5)
    t = np.radians([0.0, 45.0, 90.0, 95.0, 100.0, 150.0, 179.9, 180.0])
    rays = np.stack([np.sin(t), 0 * t, np.cos(t)], -1)
    uv, ok = lens.project(rays)
    assert ok[:-1].all() and not ok[-1]  # the axis behind the lens has no azimuth
    assert abs(uv[4, 0] - (511.5 + 500.0)) < 1e-9  # 100 degrees at the 1000 px circle
    assert np.all(np.isfinite(uv[ok]))
    zero, okz = lens.project(np.zeros(3))
    assert not okz and np.isnan(zero).all()
    assert not lens.project(np.array([np.nan, 0.0, 1.0]))[1]


# Published formulas, written out independently of omnidev.fisheye.models (scalar math).
def ds_project(p, fx, fy, cx, cy, xi, alpha):  # Usenko et al. 2018, eqs. 40-45
    x, y, z = p
    d1 = math.sqrt(x * x + y * y + z * z)
    d2 = math.sqrt(x * x + y * y + (xi * d1 + z) ** 2)
    w1 = alpha / (1 - alpha) if alpha <= 0.5 else (1 - alpha) / alpha
    w2 = (w1 + xi) / math.sqrt(2 * w1 * xi + xi * xi + 1)
    den = alpha * d2 + (1 - alpha) * (xi * d1 + z)
    return (fx * x / den + cx, fy * y / den + cy), z > -w2 * d1


def ds_unproject(u, v, fx, fy, cx, cy, xi, alpha):  # eqs. 46-51
    mx, my = (u - cx) / fx, (v - cy) / fy
    r2 = mx * mx + my * my
    mz = (1 - alpha * alpha * r2) / (alpha * math.sqrt(1 - (2 * alpha - 1) * r2) + 1 - alpha)
    k = (mz * xi + math.sqrt(mz * mz + (1 - xi * xi) * r2)) / (mz * mz + r2)
    return np.array([k * mx, k * my, k * mz - xi])


def eucm_project(p, fx, fy, cx, cy, alpha, beta):  # Khomutenko et al. 2016; Usenko eqs. 26-29
    x, y, z = p
    d = math.sqrt(beta * (x * x + y * y) + z * z)
    den = alpha * d + (1 - alpha) * z
    w = alpha / (1 - alpha) if alpha <= 0.5 else (1 - alpha) / alpha
    return (fx * x / den + cx, fy * y / den + cy), z > -w * d


def eucm_unproject(u, v, fx, fy, cx, cy, alpha, beta):  # Usenko eqs. 30-35
    mx, my = (u - cx) / fx, (v - cy) / fy
    r2 = mx * mx + my * my
    mz = (1 - beta * alpha * alpha * r2) / (
        alpha * math.sqrt(1 - (2 * alpha - 1) * beta * r2) + 1 - alpha
    )
    return np.array([mx, my, mz]) / math.sqrt(mx * mx + my * my + mz * mz)


HAND_POINTS = [
    (0.0, 0.0, 1.0),
    (0.3, -0.2, 1.0),
    (1.0, 2.0, 0.5),
    (-3.0, 1.0, 0.0),  # on the lens plane: 90 degrees
    (2.0, 0.5, -0.6),  # behind it
    (-0.4, -0.1, -2.0),  # far behind: masked
]


@pytest.mark.parametrize("key", ["ds", "ds-a<.5"])
def test_double_sphere_published_formulas(key: str) -> None:
    model = MODELS[key][0]
    assert isinstance(model, DoubleSphere)
    params = (model.fx, model.fy, model.cx, model.cy, model.xi, model.alpha)
    for p in HAND_POINTS:
        (u, v), ok_ref = ds_project(p, *params)
        uv, ok = model.project(np.array(p))
        assert bool(ok) == ok_ref, p
        if ok_ref:
            assert np.abs(uv - (u, v)).max() < 1e-9
            ray = ds_unproject(u, v, *params)
            back, okb = model.unproject(uv)
            assert okb and np.abs(back - ray / np.linalg.norm(ray)).max() < 1e-12
            assert np.abs(back - np.array(p) / np.linalg.norm(p)).max() < 1e-10


@pytest.mark.parametrize("key", ["eucm", "eucm-a<.5"])
def test_eucm_published_formulas(key: str) -> None:
    model = MODELS[key][0]
    assert isinstance(model, EUCM)
    params = (model.fx, model.fy, model.cx, model.cy, model.alpha, model.beta)
    for p in HAND_POINTS:
        (u, v), ok_ref = eucm_project(p, *params)
        uv, ok = model.project(np.array(p))
        assert bool(ok) == ok_ref, p
        if ok_ref:
            assert np.abs(uv - (u, v)).max() < 1e-9
            back, okb = model.unproject(uv)
            assert okb and np.abs(back - eucm_unproject(u, v, *params)).max() < 1e-12
            assert np.abs(back - np.array(p) / np.linalg.norm(p)).max() < 1e-10


def test_fov_published_formula_on_hand_points() -> None:
    """Devernay & Faugeras 2001: r_d = atan(2 r_u tan(w / 2)) / w on pinhole coordinates.
    With w = pi / 2 (tan(w / 2) = 1): r_u = 1/2 -> atan(1) / (pi / 2) = 1/2, r_u = sqrt(3)/2
    -> atan(sqrt(3)) / (pi / 2) = 2/3; r_u -> infinity (90 degrees) -> 1 (not imaged)."""
    lens = FieldOfView(400.0, 410.0, 320.0, 240.0, math.pi / 2)
    r3 = math.sqrt(3) / 2
    points = np.array(
        [[0.5, 0.0, 1.0], [0.0, -2 * r3, 2.0], [0.6 * r3, 0.8 * r3, 1.0], [0, 0, 3.0]]
    )
    expected = [[520.0, 240.0], [320.0, 240.0 - 410 * 2 / 3], [480.0, 240.0 + 410 * 0.8 * 2 / 3],
                [320.0, 240.0]]  # fmt: skip
    uv, ok = lens.project(points)
    assert ok.all() and np.abs(uv - expected).max() < 1e-12
    rays, ok = lens.unproject(uv)
    assert ok.all()
    assert np.abs(rays - points / np.linalg.norm(points, axis=1)[:, None]).max() < 1e-15
    # Kalibr/basalt near the axis: r_d / r_u -> 2 tan(w / 2) / w; any w, the same formula
    other = MODELS["fov"][0]
    assert isinstance(other, FieldOfView)
    for p in HAND_POINTS:
        uv1, ok1 = other.project(np.array(p))
        assert bool(ok1) == (p[2] > 0), p  # a pinhole-based model: z > 0 only
        if p[2] > 0:
            xu, yu = p[0] / p[2], p[1] / p[2]
            ru = math.hypot(xu, yu)
            f = math.atan(2 * ru * math.tan(other.w / 2)) / (other.w * ru) if ru else 2 * math.tan(
                other.w / 2) / other.w  # fmt: skip
            assert (
                np.abs(uv1 - (other.fx * f * xu + other.cx, other.fy * f * yu + other.cy)).max()
                < 1e-9
            )
    # the image ends at r_d = pi / (2 w): 90 degrees
    edge = other.cx + other.fx * math.pi / (2 * other.w)
    assert other.unproject(np.array([[edge - 1e-6, other.cy], [edge + 1e-6, other.cy]]))[
        1
    ].tolist() == [True, False]
    with pytest.raises(ValueError, match="w must be"):
        FieldOfView(400.0, 400.0, 1.0, 1.0, 0.0)


def test_masks_beyond_the_unified_family_limits() -> None:
    # UCM with xi > 1 folds at z = -|p| / xi; DS and EUCM with alpha > 0.5 bound the image radius
    mei = MODELS["mei-para"][0]
    assert abs(mei.max_angle - math.pi) < 1e-12  # parabolic: everything but the back axis
    steep = Unified(300.0, 300.0, 319.5, 239.5, 2.0)
    t = math.acos(-1 / 2.0)
    ok = steep.project(np.array([[math.sin(t - 1e-6), 0, math.cos(t - 1e-6)],
                                 [math.sin(t + 1e-6), 0, math.cos(t + 1e-6)]]))[1]  # fmt: skip
    assert ok.tolist() == [True, False]
    ds = MODELS["ds"][0]
    assert isinstance(ds, DoubleSphere)
    r_lim = math.sqrt(1 / (2 * ds.alpha - 1))
    px = np.array([[ds.cx + ds.fx * r_lim * 0.999, ds.cy], [ds.cx + ds.fx * r_lim * 1.001, ds.cy]])
    assert ds.unproject(px)[1].tolist() == [True, False]
    eu = MODELS["eucm"][0]
    assert isinstance(eu, EUCM)
    r_lim = math.sqrt(1 / (eu.beta * (2 * eu.alpha - 1)))
    px = np.array([[eu.cx + eu.fx * r_lim * 0.999, eu.cy], [eu.cx + eu.fx * r_lim * 1.001, eu.cy]])
    assert eu.unproject(px)[1].tolist() == [True, False]


def test_scaramuzza_invpol_and_conventions() -> None:
    """The direct solve of ss and OCamCalib's world2cam polynomial agree; the optical axis
    is the centre; x_opt grows with the column and y_opt with the row."""
    lens = MODELS["scaramuzza"][0]
    assert isinstance(lens, Scaramuzza)
    uv, ok = lens.project(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]))
    assert ok.all()
    assert np.abs(uv[0] - (lens.yc, lens.xc)).max() < 1e-12
    assert uv[1, 0] > lens.yc + 100 and abs(uv[1, 1] - lens.xc) < 1
    assert uv[2, 1] > lens.xc + 100 and abs(uv[2, 0] - lens.yc) < 1
    # fit an invpol (as OCamCalib does) on the solved projection and use it
    t = np.linspace(0, math.radians(100), 400)
    rho = np.hypot(*(lens.project(np.stack([np.sin(t), 0 * t, np.cos(t)], -1))[0] - uv[0]).T)
    invpol = np.polynomial.polynomial.polyfit(t - math.pi / 2, rho, 10)
    fitted = Scaramuzza(lens.ss, lens.xc, lens.yc, lens.c, lens.d, lens.e, tuple(invpol))
    rays = directions(math.radians(100), 50, 36)
    a, _ = lens.project(rays)
    b, okb = fitted.project(rays)
    assert okb.all() and np.abs(a - b).max() < 0.05
    # beyond the fitted 100 degrees the polynomial is extrapolated: masked where it strays
    t = np.radians(np.arange(100.0, 180.0, 0.5))
    far = np.stack([np.sin(t), 0 * t, np.cos(t)], -1)
    exact, ok_exact = lens.project(far)
    fit, ok_fit = fitted.project(far)
    assert ok_exact.all() and not ok_fit.all()
    assert np.abs(fit[ok_fit] - exact[ok_fit]).max() <= 1.0 + 1e-6


def test_scaramuzza_reproduces_ocamcalib_on_real_corners() -> None:
    """Fisheye1's stored OCamCalib calibration reprojects its stored corners with the stored RMS."""
    path = REALDATA / "ocamcalib_urban_samples" / "Fisheye1" / "calibration_and_corners.json"
    if not path.is_file():
        pytest.skip(f"{path} absent (shared/realdata not mounted)")
    from tests.ocam import load_corners, ocam_project

    data = load_corners(path)
    m = data.model
    lens = Scaramuzza(
        tuple(m["ss"]), m["xc_row_1based"] - 1, m["yc_col_1based"] - 1, m["c"], m["d"], m["e"]
    )
    # OCamCalib's camera frame (x rows, y columns, scene at -z) -> optical (x cols, y rows, +z)
    xyz = data.xyz
    opt = np.stack([xyz[:, 1], xyz[:, 0], -xyz[:, 2]], -1)
    uv, ok = lens.project(opt)
    assert ok.all()
    assert np.abs(uv - ocam_project(m, xyz)).max() < 1e-6
    rms = math.sqrt(np.mean(np.sum((uv - data.uv) ** 2, axis=-1)))
    assert abs(rms - data.published_rms_px) < 1e-3, rms
    with_inv = Scaramuzza(lens.ss, lens.xc, lens.yc, lens.c, lens.d, lens.e,
                          tuple(m["invpol_lowest_first"]))  # fmt: skip
    uv2, ok2 = with_inv.project(opt)
    assert ok2.all() and np.abs(uv2 - uv).max() < 0.05


def test_bad_shapes_are_rejected() -> None:
    lens = MODELS["kb4"][0]
    with pytest.raises(ValueError, match="shape"):
        lens.project(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="shape"):
        lens.unproject(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="ss"):
        Scaramuzza((10.0, 0.0, 0.001), 1.0, 1.0)
    with pytest.raises(ValueError, match="alpha"):
        DoubleSphere(100.0, 100.0, 1.0, 1.0, 0.1, 1.5)
    with pytest.raises(ValueError, match="beta"):
        EUCM(100.0, 100.0, 1.0, 1.0, 0.5, -1.0)
    with pytest.raises(ValueError, match="k2"):
        KannalaBrandt(100.0, 100.0, 1.0, 1.0, (0.0, math.nan, 0.0, 0.0))

"""The non-SVP camera model: mirror, lens, pose, frames (dissertation sec. 2.3, eqs. 2.8-2.17)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from omnidev.errors import CalibrationError
from omnidev.nonsvp.model import (
    DISSERTATION_CAMERA,
    Lens,
    Mirror,
    NonSvpCamera,
    Pose,
    angles_from_rotation,
    camera_to_base,
    camera_to_mirror,
    distorted_to_ideal,
    ideal_to_distorted,
    ideal_to_pixel,
    image_point_in_mirror,
    mirror_for_aligned_lens,
    mirror_to_camera,
    mirror_to_world,
    pixel_to_ideal,
    rotation_pitch_yaw_tilt,
    world_to_mirror,
)

CAM = DISSERTATION_CAMERA
MIR = CAM.mirror


def test_dissertation_camera_numbers() -> None:
    assert CAM.pose == Pose(0.013, 0.035, 0.007, (-2.99, 0.96, 88.67))
    assert CAM.lens == Lens(2.9, (3.2, 2.4), (640, 480), 0.0)
    # aligned, the lens centre would be at the second focus: b + h + c = T_z
    assert MIR.b + MIR.h + MIR.c == pytest.approx(88.67, abs=1e-9)
    assert MIR.c == pytest.approx(math.sqrt(MIR.a**2 + MIR.b**2), rel=1e-15)
    # the rim lies on the surface (eq. 2.19 at r = m gives z = d = b + h - c)
    assert float(MIR.surface_z(MIR.m, 0.0)) == pytest.approx(MIR.d, abs=1e-9)
    # the mirror chosen for it: rim radius 29 mm seen from O_m 6 degrees above the horizon
    assert MIR.m == 29.0
    assert math.degrees(math.atan2(MIR.d, MIR.m)) == pytest.approx(6.0, abs=1e-12)
    assert (MIR.a, MIR.b) == pytest.approx((28.36457171909808, 32.06605393760611), abs=1e-9)
    # the rim circle images inside the 640 x 480 frame, with margin
    th = np.linspace(0.0, 2.0 * np.pi, 720, endpoint=False)
    rim = np.column_stack([MIR.m * np.cos(th), MIR.m * np.sin(th), np.full_like(th, MIR.d)])
    pc = mirror_to_camera(CAM, rim)
    px, ok = ideal_to_pixel(CAM.lens, CAM.lens.f * pc[:, :2] / pc[:, 2:])
    assert ok.all()
    assert px[:, 0].min() > 100 and px[:, 0].max() < 540
    assert px[:, 1].min() > 30 and px[:, 1].max() < 450


def test_rotation_order_and_tsai_conversion() -> None:
    p, y, t = 0.013, 0.035, 0.007
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rz = np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])
    r = CAM.pose.R()
    np.testing.assert_allclose(r, rz @ ry @ rx, atol=1e-15)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    # eq. 2.14: R' (angles negated, order reversed) is the inverse
    np.testing.assert_allclose(
        rotation_pitch_yaw_tilt(-p, 0, 0) @ rotation_pitch_yaw_tilt(0, -y, 0) @ rz.T,
        r.T,
        atol=1e-15,
    )
    assert angles_from_rotation(r) == pytest.approx((p, y, t), abs=1e-14)
    r_t, t_t = CAM.pose.tsai()
    back = Pose.from_tsai(r_t, t_t)
    assert (back.pitch, back.yaw, back.tilt) == pytest.approx((p, y, t), abs=1e-14)
    np.testing.assert_allclose(back.T, CAM.pose.T, atol=1e-12)
    # Tsai's x_c = R_t x_b + T_t is the exact inverse of eq. 2.13
    xb = np.array([[10.0, -20.0, 0.0], [29.0, 0.0, 0.0]])
    xc = xb @ r_t.T + t_t
    np.testing.assert_allclose(camera_to_base(CAM.pose, xc), xb, atol=1e-12)


def test_frame_conversions_follow_eqs_2_15_to_2_17() -> None:
    r1 = CAM.pose.R().T  # R' of eq. 2.14
    tx, ty, tz = CAM.pose.T
    d = MIR.b + MIR.h - MIR.c
    # eq. 2.16: the lens centre in O_m
    np.testing.assert_allclose(CAM.center_in_mirror(), [-tx, -ty, -tz + d], atol=1e-15)
    np.testing.assert_allclose(camera_to_mirror(CAM, [0.0, 0.0, 0.0])[0], [-tx, -ty, -tz + d])
    # eq. 2.17 written out for one image point
    u, v, f = 0.4, -0.7, CAM.lens.f
    want = [
        u * r1[0, 0] + v * r1[0, 1] + f * r1[0, 2] - tx,
        u * r1[1, 0] + v * r1[1, 1] + f * r1[1, 2] - ty,
        u * r1[2, 0] + v * r1[2, 1] + f * r1[2, 2] - tz + MIR.b + MIR.h - MIR.c,
    ]
    np.testing.assert_allclose(image_point_in_mirror(CAM, [u, v])[0], want, atol=1e-13)
    pts = np.random.default_rng(1).normal(scale=500.0, size=(50, 3))
    np.testing.assert_allclose(mirror_to_camera(CAM, camera_to_mirror(CAM, pts)), pts, atol=1e-10)
    np.testing.assert_allclose(world_to_mirror(MIR, mirror_to_world(MIR, pts)), pts, atol=1e-12)
    # the mirror tip T_m is at z = b in W (eq. 2.3)
    tip = mirror_to_world(MIR, [0.0, 0.0, float(MIR.surface_z(0.0, 0.0))])
    assert tip[0, 2] == pytest.approx(MIR.b, abs=1e-12)


def test_svp_pose_puts_the_lens_at_the_second_focus() -> None:
    svp = NonSvpCamera.svp(MIR, CAM.lens)
    np.testing.assert_allclose(svp.center_in_mirror(), MIR.second_focus, atol=1e-12)
    np.testing.assert_allclose(svp.rotation_camera_to_mirror(), np.eye(3))


def test_lens_pixels_and_distortion() -> None:
    lens = Lens(2.9, (3.2, 2.4), (640, 480), kappa=0.03)
    assert lens.scale == (200.0, 200.0)
    assert lens.principal_point == (319.5, 239.5)
    assert Lens(2.9, (3.2, 2.4), (640, 480), center=(320.0, 240.0)).principal_point == (
        320.0,
        240.0,
    )
    ud = np.array([[0.5, -0.3], [1.5, 1.1], [0.0, 0.0]])
    # eq. 2.8: u = (1 - kappa r_d^2) u_d
    r2 = np.sum(ud**2, axis=1, keepdims=True)
    np.testing.assert_allclose(distorted_to_ideal(lens, ud), (1 - 0.03 * r2) * ud)
    back, ok = ideal_to_distorted(lens, distorted_to_ideal(lens, ud))
    assert ok.all()
    np.testing.assert_allclose(back, ud, atol=1e-13)
    px = np.array([[10.0, 20.0], [600.5, 470.25]])
    again, ok = ideal_to_pixel(lens, pixel_to_ideal(lens, px))
    assert ok.all()
    np.testing.assert_allclose(again, px, atol=1e-9)
    # beyond the fold of eq. 2.8 (kappa > 0) there is no inverse: masked
    _, ok = ideal_to_distorted(lens, [[5.0, 0.0]])
    assert not ok[0]


def test_to_dict_round_trip_through_json() -> None:
    d = json.loads(json.dumps(CAM.to_dict()))
    assert NonSvpCamera.from_dict(d) == CAM
    centred = NonSvpCamera(MIR, Lens(2.9, (3.2, 2.4), (640, 480), 0.01, (321.0, 241.5)), CAM.pose)
    assert NonSvpCamera.from_dict(json.loads(json.dumps(centred.to_dict()))) == centred
    del d["pose"]["yaw"]
    with pytest.raises(CalibrationError, match="missing key 'yaw'"):
        NonSvpCamera.from_dict(d)


def _one_line(exc: pytest.ExceptionInfo[CalibrationError]) -> str:
    msg = str(exc.value)
    assert "\n" not in msg and msg
    return msg


def test_bad_mirror_parameters() -> None:
    with pytest.raises(CalibrationError) as exc:
        Mirror.from_abc(20.0, 30.0, 40.0, 10.0, 20.0)
    assert "c = sqrt(a^2 + b^2)" in _one_line(exc)
    ok = Mirror.from_abc(MIR.a, MIR.b, MIR.c * (1 + 1e-8), MIR.h, MIR.m)
    assert ok == MIR
    with pytest.raises(CalibrationError) as exc:
        Mirror(MIR.a, MIR.b, MIR.h + 1.0, MIR.m)
    assert "Mirror.from_rim" in _one_line(exc)
    with pytest.raises(CalibrationError) as exc:
        Mirror(-1.0, 30.0, 10.0, 20.0)
    assert "mirror a" in _one_line(exc)
    with pytest.raises(CalibrationError):
        Mirror(float("nan"), 30.0, 10.0, 20.0)
    with pytest.raises(CalibrationError) as exc:  # m / a overflows a float (fuzz seed 17)
        Mirror(1e-200, 30.0, 10.0, 1e200)
    assert "h=inf mm" in _one_line(exc)
    with pytest.raises(CalibrationError):
        Lens(2.9, (3.2, 2.4), (640, 0))


def test_mirror_for_aligned_lens() -> None:
    """The closed form against the two defining equations, over a range of choices."""
    for tz, m, e in [
        (88.67, 29.0, 6.0),
        (88.67, 28.0, 5.0),
        (60.0, 20.0, -10.0),
        (120.0, 40.0, 30.0),
    ]:
        mir = mirror_for_aligned_lens(tz, m, e)
        assert mir.b + mir.h + mir.c == pytest.approx(tz, abs=1e-9)
        assert math.degrees(math.atan2(mir.d, mir.m)) == pytest.approx(e, abs=1e-9)
        assert 0.0 < mir.b < mir.c and mir.h > 0.0
    # an earlier helper's proposal (a, b rounded to 1e-3 mm)
    p = mirror_for_aligned_lens(88.67, 28.0, 5.0)
    assert (p.a, p.b) == pytest.approx((28.393, 32.439), abs=6e-4)
    for bad in [(88.67, 29.0, 90.0), (88.67, -1.0, 6.0), (10.0, 29.0, 45.0)]:
        with pytest.raises(CalibrationError) as exc:
            mirror_for_aligned_lens(*bad)
        _one_line(exc)


def test_pose_inside_the_mirror_is_refused() -> None:
    with pytest.raises(CalibrationError) as exc:
        CAM.with_pose(Pose(0.0, 0.0, 0.0, (0.0, 0.0, 10.0)))
    assert "inside the mirror" in _one_line(exc)
    with pytest.raises(CalibrationError) as exc:  # off-axis, behind the surface
        CAM.with_pose(Pose(0.01, 0.0, 0.0, (-20.0, 0.0, 5.0)))
    assert "inside the mirror" in _one_line(exc)
    with pytest.raises(CalibrationError) as exc:
        CAM.with_pose(Pose(math.pi, 0.0, 0.0, (0.0, 0.0, 88.67)))
    assert "away from the mirror" in _one_line(exc)

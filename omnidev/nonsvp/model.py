"""The non-SVP hypercatadioptric camera of dissertation sec. 2.3: mirror, lens, pose, frames.

Frames (all lengths in mm, all right-handed):

- **world W** (sec. 2.3.1): origin at the midpoint between the two foci of the
  hyperboloid, z along the mirror axis. The mirror is the sheet
  ``z = b sqrt(1 + r^2 / a^2)`` (eq. 2.3), its tip T_m at z = b, its rim (base
  circle of radius m) at z = b + h. The foci are at z = +c and z = -c.
- **mirror O_m** (sec. 2.3.3, eq. 2.19): W shifted by -c along z, origin at the
  focus z_W = +c behind the mirror surface (the single viewpoint of an aligned
  camera). The mirror surface is ``z = -c + b sqrt(1 + r^2 / a^2)``, i.e.
  ``(z + c)^2 / b^2 - (x^2 + y^2) / a^2 = 1`` on the sheet z + c > 0, with ``b``
  the semi-axis along z and ``c = sqrt(a^2 + b^2)``. Its tip is at z = b - c < 0,
  its rim at z = d = b + h - c; the second focus is (0, 0, -2c). The camera
  looks along +z at the convex side; the scene it sees lies mostly at z < 0
  ("below" the mirror: the dissertation's ground plane is at z = -2000).
  This is the frame the back-projection and forward projection work in.
- **base** (sec. 2.3.1): origin C at the centre of the mirror's base circle,
  axes parallel to O_m: ``x_m = x_b, y_m = y_b, z_m = z_b + d`` (eq. 2.15).
  The ring calibration pattern lies in its plane z_b = 0.
- **camera**: origin at the lens centre O_c, x along image columns, y along
  image rows (down), z along the optical axis towards the mirror. An ideal image
  point (u, v) in mm lies at (u, v, f) (eq. 2.5).

Pose (eqs. 2.4, 2.13-2.16). ``R = Rz(tilt) @ Ry(yaw) @ Rx(pitch)``: the rotation of
eq. 2.4 by pitch, yaw, tilt about the x-, y- and z-axes of the base frame, in
that order (fixed axes). Eq. 2.14's R', "obtained by reversing the signs of the
angles", is its inverse ``R.T = Rx(-pitch) @ Ry(-yaw) @ Rz(-tilt)`` (reversing
the order with the signs is what makes R' undo R). The camera-to-base
conversion is eq. 2.13 taken as the definition of the pose::

    x_b = R.T @ x_c - T        (so x_c = R @ (x_b + T))

so the lens centre sits at -T in the base frame and at (-T_x, -T_y, -T_z + d) in
O_m (eq. 2.16), and the optical axis points along ``R.T @ (0, 0, 1)``. The SVP
pose is pitch = yaw = tilt = 0, T = (0, 0, b + h + c).

Note: eq. 2.4 (Tsai's output, ``x_c = R_t x_b + T_t``) and eq. 2.13 are not
exact inverses of each other unless R = I; the dissertation feeds Tsai's T into
eq. 2.13 as it is. Here the pose is eq. 2.13 exactly, and :meth:`Pose.from_tsai`
/ :meth:`Pose.tsai` convert exactly: ``R = R_t``, ``T = R_t.T @ T_t``.

Lens (eqs. 2.5-2.11): pixels (u_f, v_f) -> distorted (u_d, v_d) = ((u_f - C_x) / S_x,
(v_f - C_y) / S_y) mm -> ideal (u, v) = (1 - kappa r_d^2)(u_d, v_d) (eq. 2.8, r_d^2 =
u_d^2 + v_d^2, kappa in 1/mm^2). Eq. 2.12 writes the opposite sign (Tsai's
(1 + kappa r^2)); this module uses eq. 2.8's. S_x = w_i / w_s, S_y = h_i / h_s
(eq. 2.10); the default image centre is the geometric centre ((w - 1) / 2,
(h - 1) / 2) in omnidev's pixel convention (centre of the top-left pixel is
(0, 0)), which is eq. 2.10's (w / 2, h / 2) when pixel corners are counted.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from omnidev.errors import CalibrationError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "DISSERTATION_CAMERA",
    "Lens",
    "Mirror",
    "NonSvpCamera",
    "Pose",
    "angles_from_rotation",
    "base_to_camera",
    "base_to_mirror",
    "camera_center_in_mirror",
    "camera_to_base",
    "camera_to_mirror",
    "distorted_to_ideal",
    "ideal_to_distorted",
    "ideal_to_pixel",
    "image_point_in_mirror",
    "mirror_for_aligned_lens",
    "mirror_to_base",
    "mirror_to_camera",
    "mirror_to_world",
    "pixel_to_ideal",
    "rotation_pitch_yaw_tilt",
    "world_to_mirror",
]


def _points(x: ArrayLike, n: int, name: str) -> FloatArray:
    """``x`` as a float64 (N, n) array; a single point (n,) becomes (1, n)."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 1 and arr.shape[0] == n:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != n:
        raise ValueError(f"{name}: expected shape (N, {n}), got {arr.shape}")
    return arr


def _finite_positive(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise CalibrationError(f"{name} must be a positive finite number, got {value!r}")
    return v


# ---------------------------------------------------------------------------
# rotations


def rotation_pitch_yaw_tilt(pitch: float, yaw: float, tilt: float) -> FloatArray:
    """R = Rz(tilt) @ Ry(yaw) @ Rx(pitch) (eq. 2.4), angles in rad; (3, 3).

    >>> np.allclose(rotation_pitch_yaw_tilt(0.0, 0.0, 0.0), np.eye(3))
    True
    """
    cx, sx = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    cz, sz = math.cos(tilt), math.sin(tilt)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(rz @ ry @ rx, dtype=np.float64)


def angles_from_rotation(R: ArrayLike) -> tuple[float, float, float]:
    """(pitch, yaw, tilt) in rad with ``rotation_pitch_yaw_tilt(*angles) == R``; |yaw| < pi/2.

    >>> [round(v, 12) for v in angles_from_rotation(rotation_pitch_yaw_tilt(0.013, 0.035, 0.007))]
    [0.013, 0.035, 0.007]
    """
    m = np.asarray(R, dtype=np.float64)
    yaw = math.asin(max(-1.0, min(1.0, -float(m[2, 0]))))
    pitch = math.atan2(float(m[2, 1]), float(m[2, 2]))
    tilt = math.atan2(float(m[1, 0]), float(m[0, 0]))
    return pitch, yaw, tilt


# ---------------------------------------------------------------------------
# the three parts


@dataclass(frozen=True)
class Mirror:
    """A hyperbolic mirror (eq. 2.19): ``z = -c + b sqrt(1 + r^2 / a^2)`` in O_m, mm.

    ``a``: transverse semi-axis (radial), ``b``: semi-axis along the mirror axis
    (distance from W to the tip T_m), ``h``: mirror height from the tip to the
    base plane, ``m``: radius of the base circle (the rim). The rim must lie on
    the surface: ``b sqrt(1 + m^2 / a^2) = b + h`` (relative tolerance 1e-6);
    :meth:`from_rim` computes h from the rest.
    """

    a: float
    b: float
    h: float
    m: float

    def __post_init__(self) -> None:
        for name in ("a", "b", "h", "m"):
            object.__setattr__(self, name, _finite_positive(f"mirror {name}", getattr(self, name)))
        z_rim = self.b * math.hypot(1.0, self.m / self.a)  # no overflow: inf at worst
        if abs(z_rim - (self.b + self.h)) > 1e-6 * (self.b + self.h):
            raise CalibrationError(
                f"mirror rim (m={self.m} mm) is not on the surface: with a={self.a}, b={self.b} "
                f"the height must be h={z_rim - self.b!r} mm, got {self.h} (use Mirror.from_rim)"
            )

    @property
    def c(self) -> float:
        """Focal half-distance sqrt(a^2 + b^2), mm."""
        return math.hypot(self.a, self.b)

    @property
    def d(self) -> float:
        """z of the base plane (the rim) in O_m: d = b + h - c (sec. 2.3.3), mm."""
        return self.b + self.h - self.c

    @property
    def second_focus(self) -> FloatArray:
        """The focus (0, 0, -2c) in O_m where an aligned lens centre sits, mm."""
        return np.array([0.0, 0.0, -2.0 * self.c])

    @classmethod
    def from_abc(cls, a: float, b: float, c: float, h: float, m: float) -> Mirror:
        """A mirror given a, b and c too: CalibrationError unless c^2 = a^2 + b^2 (rel. 1e-6)."""
        a_, b_, c_ = (
            _finite_positive(n, v) for n, v in (("mirror a", a), ("mirror b", b), ("mirror c", c))
        )
        if abs(c_ * c_ - a_ * a_ - b_ * b_) > 1e-6 * c_ * c_:
            raise CalibrationError(
                f"mirror parameters inconsistent: c^2 = {c_ * c_:.6g} but "
                f"a^2 + b^2 = {a_ * a_ + b_ * b_:.6g} (a hyperbola needs c = sqrt(a^2 + b^2))"
            )
        return cls(a=a_, b=b_, h=h, m=m)

    @classmethod
    def from_rim(cls, a: float, b: float, m: float) -> Mirror:
        """A mirror cut at rim radius m: h = b (sqrt(1 + m^2 / a^2) - 1)."""
        a_, b_, m_ = (
            _finite_positive(n, v) for n, v in (("mirror a", a), ("mirror b", b), ("mirror m", m))
        )
        return cls(a=a_, b=b_, h=b_ * (math.sqrt(1.0 + (m_ / a_) ** 2) - 1.0), m=m_)

    def surface_z(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """z in O_m of the surface point above (x, y) (eq. 2.19), mm."""
        r2 = np.square(np.asarray(x, dtype=np.float64)) + np.square(np.asarray(y, dtype=np.float64))
        return np.asarray(
            -self.c + self.b * np.sqrt(1.0 + r2 / (self.a * self.a)), dtype=np.float64
        )

    def normal(self, points: ArrayLike) -> FloatArray:
        """(N, 3) unit normals at surface points (N, 3) in O_m, pointing out of the convex side.

        Eq. 2.21: n = (sin d cos phi, sin d sin phi, -cos d), i.e. along
        (x / a^2, y / a^2, -(z + c) / b^2) normalised; it faces the camera.
        """
        p = _points(points, 3, "points")
        g = np.stack(
            [p[:, 0] / self.a**2, p[:, 1] / self.a**2, -(p[:, 2] + self.c) / self.b**2], axis=1
        )
        return np.asarray(g / np.linalg.norm(g, axis=1, keepdims=True), dtype=np.float64)

    def inside(self, points: ArrayLike) -> BoolArray:
        """(N,) True where points (N, 3) in O_m lie in the mirror body (behind the surface)."""
        p = _points(points, 3, "points")
        r2 = p[:, 0] ** 2 + p[:, 1] ** 2
        return np.asarray(
            p[:, 2] + self.c >= self.b * np.sqrt(1.0 + r2 / self.a**2), dtype=np.bool_
        )


@dataclass(frozen=True)
class Lens:
    """A perspective camera (eqs. 2.5-2.10): focal length f and sensor (width, height) in mm,
    image size (width, height) in px, radial distortion kappa (eq. 2.8, 1/mm^2), image
    centre (C_x, C_y) in px (None: the geometric centre ((w - 1) / 2, (h - 1) / 2))."""

    f: float
    sensor: tuple[float, float]
    size: tuple[int, int]
    kappa: float = 0.0
    center: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "f", _finite_positive("lens f", self.f))
        sensor = (
            _finite_positive("sensor width", self.sensor[0]),
            _finite_positive("sensor height", self.sensor[1]),
        )
        object.__setattr__(self, "sensor", sensor)
        w, h = int(self.size[0]), int(self.size[1])
        if w != self.size[0] or h != self.size[1] or w <= 0 or h <= 0:
            raise CalibrationError(f"image size must be two positive integers, got {self.size!r}")
        object.__setattr__(self, "size", (w, h))
        if not math.isfinite(float(self.kappa)):
            raise CalibrationError(f"lens kappa must be finite, got {self.kappa!r}")
        object.__setattr__(self, "kappa", float(self.kappa))
        if self.center is not None:
            cx, cy = float(self.center[0]), float(self.center[1])
            if not (math.isfinite(cx) and math.isfinite(cy)):
                raise CalibrationError(f"image centre must be finite, got {self.center!r}")
            object.__setattr__(self, "center", (cx, cy))

    @property
    def scale(self) -> tuple[float, float]:
        """(S_x, S_y) of eq. 2.10, px per mm."""
        return self.size[0] / self.sensor[0], self.size[1] / self.sensor[1]

    @property
    def principal_point(self) -> tuple[float, float]:
        """(C_x, C_y) of eq. 2.9 in px."""
        if self.center is not None:
            return self.center
        return (self.size[0] - 1) / 2.0, (self.size[1] - 1) / 2.0


@dataclass(frozen=True)
class Pose:
    """The camera relative to the mirror base (eqs. 2.4, 2.13-2.16): angles in rad, T in mm.

    ``x_b = R().T @ x_c - T`` maps camera-frame points to the base frame (eq.
    2.13); the lens centre is at -T in the base frame. See the module docstring.
    """

    pitch: float
    yaw: float
    tilt: float
    T: tuple[float, float, float]

    def __post_init__(self) -> None:
        for name in ("pitch", "yaw", "tilt"):
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise CalibrationError(f"pose {name} must be finite, got {v!r}")
            object.__setattr__(self, name, v)
        t = tuple(float(v) for v in self.T)
        if len(t) != 3 or not all(math.isfinite(v) for v in t):
            raise CalibrationError(f"pose T must be three finite numbers (mm), got {self.T!r}")
        object.__setattr__(self, "T", t)

    def R(self) -> FloatArray:  # noqa: N802 - the dissertation's name
        """(3, 3) R of eq. 2.4: base-frame directions -> camera-frame directions.

        ``R().T`` (eq. 2.14's R') maps camera-frame directions to base (and O_m) directions.
        """
        return rotation_pitch_yaw_tilt(self.pitch, self.yaw, self.tilt)

    @classmethod
    def from_tsai(cls, R_t: ArrayLike, T_t: ArrayLike) -> Pose:
        """The pose from Tsai's extrinsics ``x_c = R_t @ x_b + T_t`` (eq. 2.4), exactly."""
        r = np.asarray(R_t, dtype=np.float64)
        t = r.T @ np.asarray(T_t, dtype=np.float64)
        pitch, yaw, tilt = angles_from_rotation(r)
        return cls(pitch, yaw, tilt, (float(t[0]), float(t[1]), float(t[2])))

    def tsai(self) -> tuple[FloatArray, FloatArray]:
        """(R_t, T_t) with ``x_c = R_t @ x_b + T_t`` (eq. 2.4): R_t = R, T_t = R @ T."""
        r = self.R()
        return r, r @ np.asarray(self.T, dtype=np.float64)


@dataclass(frozen=True)
class NonSvpCamera:
    """A hypercatadioptric camera: mirror, lens and the lens's pose relative to the mirror base.

    Raises CalibrationError when the lens centre is inside the mirror body or the
    optical axis does not point towards the mirror.
    """

    mirror: Mirror
    lens: Lens
    pose: Pose

    def __post_init__(self) -> None:
        o = self.center_in_mirror()
        if bool(self.mirror.inside(o)[0]):
            tz = self.mirror.b + self.mirror.h + self.mirror.c
            raise CalibrationError(
                f"pose puts the lens centre inside the mirror (at {np.round(o, 3).tolist()} mm "
                f"in O_m); the aligned pose has T = (0, 0, b + h + c = {tz:.3f})"
            )
        axis = self.pose.R().T[:, 2]
        if axis[2] <= 0.0:
            raise CalibrationError(
                f"pose points the optical axis away from the mirror (axis {axis.round(3).tolist()})"
            )

    @classmethod
    def svp(cls, mirror: Mirror, lens: Lens) -> NonSvpCamera:
        """The aligned pose: lens centre at the second focus, optical axis on the mirror axis."""
        return cls(mirror, lens, Pose(0.0, 0.0, 0.0, (0.0, 0.0, mirror.b + mirror.h + mirror.c)))

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) px."""
        return self.lens.size

    def center_in_mirror(self) -> FloatArray:
        """(3,) lens centre O_c in O_m (eq. 2.16): (-T_x, -T_y, -T_z + b + h - c), mm."""
        t = self.pose.T
        return np.array([-t[0], -t[1], -t[2] + self.mirror.d])

    def rotation_camera_to_mirror(self) -> FloatArray:
        """(3, 3) R' = R.T (eq. 2.14): camera-frame directions -> O_m directions."""
        return self.pose.R().T

    def with_pose(self, pose: Pose) -> NonSvpCamera:
        """The same mirror and lens with another pose."""
        return NonSvpCamera(self.mirror, self.lens, pose)

    def to_dict(self) -> dict[str, Any]:
        """Plain floats, lists and dicts (JSON, cv2.FileStorage); ``center`` only if set."""
        lens: dict[str, Any] = {
            "f": self.lens.f,
            "sensor": list(self.lens.sensor),
            "size": list(self.lens.size),
            "kappa": self.lens.kappa,
        }
        if self.lens.center is not None:
            lens["center"] = list(self.lens.center)
        return {
            "mirror": {
                "a": self.mirror.a,
                "b": self.mirror.b,
                "h": self.mirror.h,
                "m": self.mirror.m,
            },
            "lens": lens,
            "pose": {
                "pitch": self.pose.pitch,
                "yaw": self.pose.yaw,
                "tilt": self.pose.tilt,
                "T": list(self.pose.T),
            },
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> NonSvpCamera:
        """Inverse of :meth:`to_dict`; CalibrationError naming the missing or bad key."""
        try:
            mi, le, po = data["mirror"], data["lens"], data["pose"]
            mirror = Mirror(a=float(mi["a"]), b=float(mi["b"]), h=float(mi["h"]), m=float(mi["m"]))
            center = le.get("center")
            lens = Lens(
                f=float(le["f"]),
                sensor=(float(le["sensor"][0]), float(le["sensor"][1])),
                size=(int(le["size"][0]), int(le["size"][1])),
                kappa=float(le.get("kappa", 0.0)),
                center=None if center is None else (float(center[0]), float(center[1])),
            )
            pose = Pose(
                float(po["pitch"]),
                float(po["yaw"]),
                float(po["tilt"]),
                (float(po["T"][0]), float(po["T"][1]), float(po["T"][2])),
            )
        except KeyError as exc:
            raise CalibrationError(f"non-SVP camera: missing key {exc.args[0]!r}") from None
        except (TypeError, ValueError, IndexError) as exc:
            raise CalibrationError(f"non-SVP camera: bad value ({exc})") from None
        return cls(mirror, lens, pose)


# ---------------------------------------------------------------------------
# frame conversions (eqs. 2.13-2.17); points are (N, 3) mm


def camera_to_base(pose: Pose, points: ArrayLike) -> FloatArray:
    """Camera-frame points -> base frame: x_b = R' x_c - T (eq. 2.13)."""
    p = _points(points, 3, "points")
    return np.asarray(p @ pose.R() - np.asarray(pose.T), dtype=np.float64)


def base_to_camera(pose: Pose, points: ArrayLike) -> FloatArray:
    """Base-frame points -> camera frame: x_c = R (x_b + T) (inverse of eq. 2.13)."""
    p = _points(points, 3, "points")
    return np.asarray((p + np.asarray(pose.T)) @ pose.R().T, dtype=np.float64)


def base_to_mirror(mirror: Mirror, points: ArrayLike) -> FloatArray:
    """Base frame -> O_m: z + d (eq. 2.15)."""
    p = _points(points, 3, "points").copy()
    p[:, 2] += mirror.d
    return p


def mirror_to_base(mirror: Mirror, points: ArrayLike) -> FloatArray:
    """O_m -> base frame: z - d."""
    p = _points(points, 3, "points").copy()
    p[:, 2] -= mirror.d
    return p


def mirror_to_world(mirror: Mirror, points: ArrayLike) -> FloatArray:
    """O_m -> world W (midpoint of the foci, eq. 2.3): z + c."""
    p = _points(points, 3, "points").copy()
    p[:, 2] += mirror.c
    return p


def world_to_mirror(mirror: Mirror, points: ArrayLike) -> FloatArray:
    """World W -> O_m (eq. 2.19): z - c."""
    p = _points(points, 3, "points").copy()
    p[:, 2] -= mirror.c
    return p


def camera_to_mirror(cam: NonSvpCamera, points: ArrayLike) -> FloatArray:
    """Camera-frame points -> O_m (eq. 2.15)."""
    return base_to_mirror(cam.mirror, camera_to_base(cam.pose, points))


def mirror_to_camera(cam: NonSvpCamera, points: ArrayLike) -> FloatArray:
    """O_m points -> camera frame (inverse of eq. 2.15)."""
    return base_to_camera(cam.pose, mirror_to_base(cam.mirror, points))


def camera_center_in_mirror(cam: NonSvpCamera) -> FloatArray:
    """(3,) (x_cw, y_cw, z_cw) of eq. 2.16, mm in O_m."""
    return cam.center_in_mirror()


def image_point_in_mirror(cam: NonSvpCamera, uv_ideal: ArrayLike) -> FloatArray:
    """(N, 3) (x_i, y_i, z_i) of eq. 2.17: ideal image points (u, v) mm at (u, v, f) -> O_m."""
    uv = _points(uv_ideal, 2, "uv_ideal")
    pts = np.column_stack([uv, np.full(len(uv), cam.lens.f)])
    return camera_to_mirror(cam, pts)


# ---------------------------------------------------------------------------
# lens: pixels <-> ideal image coordinates (eqs. 2.8-2.11)


def pixel_to_ideal(lens: Lens, uv: ArrayLike) -> FloatArray:
    """(N, 2) pixels (u_f, v_f) -> ideal image coordinates (u, v) in mm (eqs. 2.11, 2.8)."""
    ud = pixel_to_distorted(lens, uv)
    return distorted_to_ideal(lens, ud)


def pixel_to_distorted(lens: Lens, uv: ArrayLike) -> FloatArray:
    """(N, 2) pixels -> distorted image coordinates (u_d, v_d) in mm (eq. 2.11)."""
    p = _points(uv, 2, "uv")
    (sx, sy), (cx, cy) = lens.scale, lens.principal_point
    return np.column_stack([(p[:, 0] - cx) / sx, (p[:, 1] - cy) / sy])


def distorted_to_ideal(lens: Lens, ud: ArrayLike) -> FloatArray:
    """(N, 2) distorted -> ideal coordinates, mm: (u, v) = (1 - kappa r_d^2)(u_d, v_d) (eq. 2.8)."""
    p = _points(ud, 2, "ud")
    if lens.kappa == 0.0:
        return p.copy()
    return np.asarray(
        p * (1.0 - lens.kappa * np.sum(p * p, axis=1, keepdims=True)), dtype=np.float64
    )


def ideal_to_distorted(lens: Lens, uv_ideal: ArrayLike) -> tuple[FloatArray, BoolArray]:
    """(N, 2) ideal -> distorted coordinates in mm, inverting eq. 2.8 by Newton on the radius.

    Returns the coordinates and an (N,) mask, False where eq. 2.8 has no
    monotonic inverse (kappa > 0 and radius beyond the fold at 1 / sqrt(3 kappa)).
    """
    p = _points(uv_ideal, 2, "uv_ideal")
    k = lens.kappa
    if k == 0.0:
        return p.copy(), np.ones(len(p), dtype=np.bool_)
    ru = np.hypot(p[:, 0], p[:, 1])
    rd = ru.copy()
    for _ in range(50):
        fval = rd * (1.0 - k * rd * rd) - ru
        deriv = 1.0 - 3.0 * k * rd * rd
        step = fval / np.where(np.abs(deriv) > 1e-12, deriv, 1e-12)
        rd = rd - step
        if float(np.max(np.abs(step), initial=0.0)) < 1e-15:
            break
    ok = (1.0 - 3.0 * k * rd * rd > 0.0) & (
        np.abs(rd * (1.0 - k * rd * rd) - ru) <= 1e-12 * (1.0 + ru)
    )
    ratio = np.where(ru > 0.0, rd / np.where(ru > 0.0, ru, 1.0), 1.0)
    return np.asarray(p * ratio[:, None], dtype=np.float64), np.asarray(ok, dtype=np.bool_)


def distorted_to_pixel(lens: Lens, ud: ArrayLike) -> FloatArray:
    """(N, 2) distorted coordinates mm -> pixels (eq. 2.9)."""
    p = _points(ud, 2, "ud")
    (sx, sy), (cx, cy) = lens.scale, lens.principal_point
    return np.column_stack([p[:, 0] * sx + cx, p[:, 1] * sy + cy])


def ideal_to_pixel(lens: Lens, uv_ideal: ArrayLike) -> tuple[FloatArray, BoolArray]:
    """(N, 2) ideal coordinates mm -> pixels and an (N,) mask (see :func:`ideal_to_distorted`)."""
    ud, ok = ideal_to_distorted(lens, uv_ideal)
    return distorted_to_pixel(lens, ud), ok


# ---------------------------------------------------------------------------
# the dissertation's camera

_DISS_TZ = 88.67  # mm, the dissertation's T_z
_DISS_M = 29.0  # mm, rim radius
_DISS_RIM_ELEVATION_DEG = 6.0  # rim seen from O_m this far above the horizon


def mirror_for_aligned_lens(t_z: float, m: float, rim_elevation_deg: float) -> Mirror:
    """The hyperbolic mirror with b + h + c = ``t_z`` (mm) whose rim of radius ``m`` (mm) is
    seen from O_m ``rim_elevation_deg`` above the horizon (closed form).

    With the lens at the second focus (0, 0, -2c) and the base plane at d = b + h - c,
    the lens-to-rim distance is b + h + c. The rim elevation fixes d = m tan(e), so
    c = (t_z - d) / 2 and b + h = Z = (t_z + d) / 2. The rim on the surface,
    Z^2 / b^2 - m^2 / a^2 = 1 with a^2 = c^2 - b^2, is a quadratic in b^2:
    b^4 - (Z^2 + c^2 + m^2) b^2 + Z^2 c^2 = 0. It is negative at b^2 = c^2 (value
    -m^2 c^2), so one root lies below c^2 and one above; a > 0 needs the smaller.

    >>> mir = mirror_for_aligned_lens(88.67, 29.0, 6.0)
    >>> round(mir.a, 4), round(mir.b, 4), round(mir.b + mir.h + mir.c, 9)
    (28.3646, 32.0661, 88.67)
    >>> round(math.degrees(math.atan2(mir.d, mir.m)), 9)
    6.0
    """
    tz, m_ = _finite_positive("T_z", t_z), _finite_positive("mirror m", m)
    e = math.radians(float(rim_elevation_deg))
    if not -math.pi / 2 < e < math.pi / 2:
        raise CalibrationError(
            f"rim elevation must lie in (-90, 90) degrees, got {rim_elevation_deg}"
        )
    d = m_ * math.tan(e)
    c, z = (tz - d) / 2.0, (tz + d) / 2.0
    if c <= 0.0 or z <= 0.0:
        raise CalibrationError(f"no mirror: T_z = {tz} mm is too short for the rim elevation")
    s = z * z + c * c + m_ * m_
    b2 = 2.0 * z * z * c * c / (s + math.sqrt(s * s - 4.0 * z * z * c * c))  # the smaller root
    return Mirror.from_rim(math.sqrt(c * c - b2), math.sqrt(b2), m_)


DISSERTATION_CAMERA = NonSvpCamera(
    mirror=mirror_for_aligned_lens(_DISS_TZ, _DISS_M, _DISS_RIM_ELEVATION_DEG),
    lens=Lens(f=2.9, sensor=(3.2, 2.4), size=(640, 480), kappa=0.0),
    pose=Pose(pitch=0.013, yaw=0.035, tilt=0.007, T=(-2.99, 0.96, _DISS_TZ)),
)
"""The camera of dissertation secs. 2.3.2 / 2.5.1, with a mirror chosen to fit it.

Given (sec. 2.5.1): T = (-2.99, 0.96, 88.67) mm; pitch, yaw, tilt = (0.013, 0.035,
0.007) rad; kappa = 0; f = 2.9 mm; 3.2 x 2.4 mm sensor; 640 x 480 px. The
dissertation does not give the mirror. Chosen here (docs/nonsvp.md, "The mirror
of the fixtures"):

- aligned, the lens centre would sit at the second focus: eq. 2.16 with
  T_x = T_y = 0 gives z_cw = -T_z + b + h - c = -2c, so **b + h + c = T_z = 88.67**;
- **m = 29 mm** (rim radius): the rim lies T_z = 88.67 mm in front of the lens,
  so its image radius is f m / T_z * S = 2.9 * 29 / 88.67 * 200 = 189.7 px
  (79 % of the half-height); the calibration ring's marks (sec. 2.3.2, out to
  m + 5 mm) image out to 222.4 px, which still leaves ~15 px in the 480-px
  height (with eq. 2.13's pose the tilt of 0.035 rad towards the axis nearly
  cancels the 2.99 mm offset: the mirror centre images within 2 px of the image
  centre). m = 30 would leave the marks 9 px, m = 32 would cut them;
- **the rim 6 degrees above the horizon** seen from O_m (d = m tan 6 deg =
  3.04802 mm): the views of sec. 2.5.1 lie below the horizon (the side planes
  from z = 0 down), so the omni-image is spent there; 6 degrees keeps every
  azimuth of the rim above the horizon at the larger misalignment too
  (:data:`omnidev.sim.nonsvp.LARGE_POSE`: the incident rays at the rim are 1.4 to
  9.7 degrees up; at this pose 4.1 to 7.8);
- these three fix the mirror (:func:`mirror_for_aligned_lens`):
  **a = 28.36457 mm, b = 32.06605 mm**, c = 42.81099 mm, h = 13.79296 mm,
  d = b + h - c = 3.04802 mm; the tip is c - b = 10.745 mm from O_m, the
  asymptotes rise atan(b / a) = 48.5 degrees from the base plane.

An earlier choice (b = 30, m = 29, a = 20.187 mm) put the rim 29.4 degrees above
the horizon: back-projection then filled only ~10 % of a 320x240 view, ~25 % now.
"""

"""Back-projection of image points (dissertation sec. 2.4): pixel -> mirror point -> incident ray.

Two implementations of one mapping, both in the mirror frame O_m (mm; see
:mod:`omnidev.nonsvp.model`):

- :func:`backproject`: the dissertation's equations, the mirror point by eqs.
  2.38-2.40 and 2.19, the incident direction by eqs. 2.18-2.37;
- :func:`backproject_vector`: the plain vector form (intersect the ray from the
  lens centre with the hyperboloid, reflect ``r = d - 2 (d.n) n``).

Both return ``(M, w, valid)``: M (N, 3) the mirror points, w (N, 3) unit
directions of the incident rays pointing from M out into the world (the scene
point seen at the pixel is M + t w for some t > 0), valid (N,) True where the
pixel sees the mirror inside its rim. Rows that are not valid hold NaN.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from omnidev.nonsvp.model import (
    Mirror,
    NonSvpCamera,
    image_point_in_mirror,
    pixel_to_ideal,
)

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = ["backproject", "backproject_vector", "incident_direction_eqs", "mirror_point_eqs"]


def _pixels(uv: ArrayLike) -> FloatArray:
    arr = np.asarray(uv, dtype=np.float64)
    if arr.ndim == 1 and arr.shape[0] == 2:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"uv: expected shape (N, 2) pixels, got {arr.shape}")
    return arr


def _roots(k4: FloatArray, k5: FloatArray, k6: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Both roots of K4 x^2 + 2 K5 x + K6 = 0, i.e. eq. 2.40 (-K5 +- sqrt(K5^2 - K4 K6)) / K4.

    Written in the cancellation-free form q = -(K5 + sign(K5) sqrt(D)), roots
    q / K4 and K6 / q (the same two numbers); NaN where D < 0.
    """
    disc = k5 * k5 - k4 * k6
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
        q = -(k5 + np.where(k5 >= 0.0, sq, -sq))
        return q / k4, k6 / q


def mirror_point_eqs(
    mirror: Mirror, center: FloatArray, image_points: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """Mirror points M on the line from the lens centre through image points (eqs. 2.38-2.40).

    ``center``: (3,) (x_cw, y_cw, z_cw) of eq. 2.16; ``image_points``: (N, 3)
    (x_i, y_i, z_i) of eq. 2.17; both in O_m, mm. Returns (N, 3) M and an (N,)
    mask of rows where the line meets the mirror's sheet in front of the lens
    (the rim is not checked here).

    Root choice. Eq. 2.40 has two roots and the dissertation keeps the one with
    (x_m - x_cw)(x_i - x_cw) >= 0 (in front of the lens). That alone does not
    decide: the quadric of eq. 2.19 squared, (z + c)^2 / b^2 - r^2 / a^2 = 1, has
    a second sheet z + c < 0 around the lens, and a ray leaving a lens near the
    second focus (0, 0, -2c) crosses that sheet (between z = -2c and the tip
    z = -b - c of that sheet) *before* it reaches the mirror, so both roots are
    in front of the lens (on the axis: z = -b - c and z = b - c). The root kept
    here is in front of the lens (the dissertation's test), on the mirror's
    sheet (z_m + c = K_2 x_m + K_3 > 0), and, if both are, the one nearer the
    lens (the mirror body z + c >= b sqrt(1 + r^2 / a^2) is convex, so a ray
    enters it once; the far root is its exit).

    Parametrisation. Eqs. 2.38-2.39 divide by x_i - x_cw (tan phi, K_2), which
    vanishes on the image column whose line of sight lies in the plane
    x = x_cw. Rows with |y_i - y_cw| > |x_i - x_cw| are solved with x and y
    exchanged (the mirror is symmetric under x <-> y, so eqs. 2.38-2.40 hold
    verbatim in that relabelled frame), and a line of sight parallel to the
    axis (both differences < 1e-12 of the z difference) meets the mirror at
    (x_cw, y_cw, z(x_cw, y_cw)).
    """
    a2, b2, c = mirror.a**2, mirror.b**2, mirror.c
    n = len(image_points)
    ddx = image_points[:, 0] - center[0]
    ddy = image_points[:, 1] - center[1]
    ddz = image_points[:, 2] - center[2]
    swap = np.abs(ddy) > np.abs(ddx)
    # relabel x <-> y where the line runs more along y than along x
    xi = np.where(swap, image_points[:, 1], image_points[:, 0])
    yi = np.where(swap, image_points[:, 0], image_points[:, 1])
    zi = image_points[:, 2]
    xcw = np.where(swap, center[1], center[0])
    ycw = np.where(swap, center[0], center[1])
    zcw = np.full(n, center[2])
    axial = np.maximum(np.abs(ddx), np.abs(ddy)) <= 1e-12 * np.abs(ddz)
    dxi = np.where(axial, 1.0, xi - xcw)
    with np.errstate(invalid="ignore", divide="ignore"):
        tan_phi = (yi - ycw) / dxi  # eq. 2.38
        k1 = ycw - xcw * tan_phi  # eq. 2.39-1
        k2 = (zi - zcw) / dxi  # eq. 2.39-2
        k3 = zcw + c - xcw * k2  # eq. 2.39-3
        k4 = b2 * (1.0 + tan_phi**2) - a2 * k2**2  # eq. 2.39-4
        k5 = b2 * k1 * tan_phi - a2 * k2 * k3  # eq. 2.39-5
        k6 = a2 * b2 + b2 * k1**2 - a2 * k3**2  # eq. 2.39-6
        x1, x2 = _roots(k4, k5, k6)  # eq. 2.40
        ahead1 = (x1 - xcw) * dxi >= 0.0
        ahead2 = (x2 - xcw) * dxi >= 0.0
        sheet1 = k2 * x1 + k3 > 0.0
        sheet2 = k2 * x2 + k3 > 0.0
    ok1 = ahead1 & sheet1 & np.isfinite(x1)
    ok2 = ahead2 & sheet2 & np.isfinite(x2)
    nearer1 = np.abs(x1 - xcw) <= np.abs(x2 - xcw)
    take1 = ok1 & (~ok2 | nearer1)
    xm = np.where(take1, x1, x2)
    hit = ok1 | ok2
    ym = k1 + xm * tan_phi  # eq. 2.38
    xm = np.where(axial, xcw, xm)
    ym = np.where(axial, ycw, ym)
    hit = np.where(axial, ddz > 0.0, hit)
    out = np.empty((n, 3))
    out[:, 0] = np.where(swap, ym, xm)
    out[:, 1] = np.where(swap, xm, ym)
    out[:, 2] = mirror.surface_z(out[:, 0], out[:, 1])  # eq. 2.19
    out[~hit] = np.nan
    return out, np.asarray(hit, dtype=np.bool_)


def _incident_eqs_xparam(
    mirror: Mirror, m: FloatArray, center: FloatArray, o_u: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Eqs. 2.18-2.37 solved for w_x first; returns ((N, 3) w, (N,) |Q_x| / |Q_y|)."""
    a, b, c = mirror.a, mirror.b, mirror.c
    xm, ym, zm = m[:, 0], m[:, 1], m[:, 2]
    xcw, ycw, zcw = center[:, 0], center[:, 1], center[:, 2]
    phi = np.arctan2(ym, xm)  # eq. 2.18 (atan2 keeps the quadrant)
    cphi, sphi = np.cos(phi), np.sin(phi)
    rm = np.hypot(xm, ym)
    root = np.sqrt(a**4 + c**2 * rm**2)
    sd = b * rm / root  # eq. 2.21
    cd = a * np.sqrt(a**2 + rm**2) / root
    km1 = (ym - ycw) * cd + (zm - zcw) * sd * sphi  # eq. 2.24-1
    km2 = (xm - xcw) * cd + (zm - zcw) * sd * cphi  # eq. 2.24-2
    km3 = (xcw - xm) * sd * sphi - (ycw - ym) * sd * cphi  # eq. 2.24-3
    ox, oy, oz = xcw - xm, ycw - ym, zcw - zm
    cos_rho = (ox * sd * cphi + oy * sd * sphi - oz * cd) / np.sqrt(ox**2 + oy**2 + oz**2)  # 2.27
    qx = km2 * cd - km3 * sd * sphi  # the denominator of eqs. 2.34, 2.36
    qy = km1 * cd + km3 * sd * cphi  # the numerator of A_m (the denominator after x <-> y)
    with np.errstate(invalid="ignore", divide="ignore"):
        am = qy / qx  # eq. 2.34
        bm = -km3 * cos_rho / qx
        cm = (km1 * sphi + km2 * cphi) * sd / qx  # eq. 2.36
        dm = -km2 * cos_rho / qx
        p = am * bm + cm * dm
        q = 1.0 + am**2 + cm**2
        disc = np.maximum(p * p - q * (bm**2 + dm**2 - 1.0), 0.0)
        wx_plus = (-p + np.sqrt(disc)) / q  # eq. 2.37
        wx_minus = (-p - np.sqrt(disc)) / q
    # root choice: one root of eq. 2.37 is the reflected ray R_r itself, o_u, the
    # unit vector from M towards the lens (it satisfies 2.31 and 2.29 trivially);
    # o_u is parallel to O_c - I, so keep the root farther from (x_cw - x_i) / |O_c - I|.
    wx = np.where(np.abs(wx_plus - o_u[:, 0]) >= np.abs(wx_minus - o_u[:, 0]), wx_plus, wx_minus)
    w = np.column_stack([wx, am * wx + bm, cm * wx + dm])  # eqs. 2.33, 2.35
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.abs(qx) / np.abs(qy)
    return w, ratio


def incident_direction_eqs(
    mirror: Mirror, mirror_points: FloatArray, center: FloatArray, image_points: FloatArray
) -> FloatArray:
    """(N, 3) unit incident directions w_u at mirror points (eqs. 2.18-2.37), O_m.

    ``mirror_points`` (N, 3) M, ``center`` (3,) lens centre, ``image_points``
    (N, 3) I (eq. 2.17), all in O_m, mm. w_u points from M out into the world.

    Root choice of eq. 2.37 (the text omits it): the two unit vectors that lie
    in the plane of o = O_c - M and n (eq. 2.31) and make the angle rho with n
    (eq. 2.29) are the reflected ray o / |o| itself and the incident ray; since
    I lies on the segment O_c M, o / |o| = (O_c - I) / |O_c - I|, so the root
    kept is the one whose w_x is farther from (x_cw - x_i) / |O_c - I|. The two
    roots have equal w_x where the incidence plane's in-plane tangent
    n x (o x n) has no x component (e.g. phi = 90 deg for an aligned lens), where
    eqs. 2.34/2.36 also divide by zero; rows whose denominator Q_x =
    K_m2 cos d - K_m3 sin d sin phi is smaller than its x <-> y counterpart are
    solved with x and y exchanged (the mirror is symmetric under that exchange).
    At normal incidence (o parallel to n, all K_m = 0) w_u = o / |o|.
    """
    n = len(mirror_points)
    cen = np.broadcast_to(np.asarray(center, dtype=np.float64), (n, 3))
    oi = cen - image_points
    o_u = oi / np.linalg.norm(oi, axis=1, keepdims=True)
    w_x, ratio = _incident_eqs_xparam(mirror, mirror_points, cen, o_u)
    sw = [1, 0, 2]
    w_y, _ = _incident_eqs_xparam(mirror, mirror_points[:, sw], cen[:, sw], o_u[:, sw])
    w_y = w_y[:, sw]
    use_x = ratio >= 1.0
    w = np.where(use_x[:, None], w_x, w_y)
    # normal incidence: o x n = 0, every K_m vanishes
    om = cen - mirror_points
    nrm = mirror.normal(mirror_points)
    cross = np.linalg.norm(np.cross(om, nrm), axis=1)
    normal_inc = cross <= 1e-14 * np.linalg.norm(om, axis=1)
    w = np.where(normal_inc[:, None], o_u, w)
    return np.asarray(w, dtype=np.float64)


def backproject(cam: NonSvpCamera, uv: ArrayLike) -> tuple[FloatArray, FloatArray, BoolArray]:
    """(N, 2) pixels -> (M (N, 3), w (N, 3), valid (N,)) by the dissertation's equations.

    Pixel -> ideal (u, v) mm (eqs. 2.11, 2.8) -> I in O_m (eq. 2.17) -> mirror
    point M (eqs. 2.38-2.40, 2.19; root choice in :func:`mirror_point_eqs`) ->
    incident direction w_u (eqs. 2.18-2.37; root choice in
    :func:`incident_direction_eqs`). valid: the line of sight meets the mirror
    inside its rim (z_m <= d = b + h - c). M and w in O_m (mm, unit); NaN where
    not valid.
    """
    px = _pixels(uv)
    ideal = pixel_to_ideal(cam.lens, px)
    img = image_point_in_mirror(cam, ideal)
    center = cam.center_in_mirror()
    m, hit = mirror_point_eqs(cam.mirror, center, img)
    valid = hit & (m[:, 2] <= cam.mirror.d)
    w = np.full((len(px), 3), np.nan)
    if np.any(valid):
        w[valid] = incident_direction_eqs(cam.mirror, m[valid], center, img[valid])
    m[~valid] = np.nan
    return m, w, np.asarray(valid, dtype=np.bool_)


def backproject_vector(
    cam: NonSvpCamera, uv: ArrayLike
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Same as :func:`backproject` by plain vectors: ray-quadric intersection and reflection.

    The ray leaves the lens centre O (eq. 2.16) along d = R' (u, v, f) (unit);
    it meets the mirror at the smallest t > 0 with (z + c)^2 / b^2 - r^2 / a^2 = 1
    and z + c > 0; the incident ray is w = d - 2 (d.n) n with n the unit surface
    normal.
    """
    px = _pixels(uv)
    ideal = pixel_to_ideal(cam.lens, px)
    mir = cam.mirror
    a2, b2, c = mir.a**2, mir.b**2, mir.c
    rays = np.column_stack([ideal, np.full(len(px), cam.lens.f)]) @ cam.pose.R()  # R' applied
    d = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    o = cam.center_in_mirror()
    oz = o[2] + c
    qa = d[:, 2] ** 2 / b2 - (d[:, 0] ** 2 + d[:, 1] ** 2) / a2
    qb = oz * d[:, 2] / b2 - (o[0] * d[:, 0] + o[1] * d[:, 1]) / a2
    qc = oz * oz / b2 - (o[0] ** 2 + o[1] ** 2) / a2 - 1.0
    t1, t2 = _roots(qa, qb, qc)
    with np.errstate(invalid="ignore"):
        ok1 = (t1 > 0.0) & (oz + t1 * d[:, 2] > 0.0)
        ok2 = (t2 > 0.0) & (oz + t2 * d[:, 2] > 0.0)
        t = np.where(ok1 & (~ok2 | (t1 <= t2)), t1, t2)
    hit = ok1 | ok2
    m = o + t[:, None] * d
    valid = hit & (m[:, 2] <= mir.d)
    w = np.full((len(px), 3), np.nan)
    if np.any(valid):
        nv = mir.normal(m[valid])
        dv = d[valid]
        r = dv - 2.0 * np.sum(dv * nv, axis=1, keepdims=True) * nv
        w[valid] = r / np.linalg.norm(r, axis=1, keepdims=True)
    m[~valid] = np.nan
    return m, w, np.asarray(valid, dtype=np.bool_)

"""The printable calibration ring of dissertation sec. 2.3.2, and its view through a lens.

The ring is a paper annulus glued on the mirror mount around the mirror's base
circle: its inner circle has the mirror's diameter (radius ``m``) and 16 short black
radial marks are spread evenly around it, each with one end on the inner circle.
Those 16 inner end points are the *calibration points* (Fig. 2.3).

Pattern-plane frame = the mirror's *base coordinate system* of sec. 2.3.1 (mm): origin
C at the centre of the mirror's base circle, z_b = 0 on the base plane, z_b pointing
away from the camera (towards the mirror's base, so the camera looks along +z_b).
Seen from its printed side (the side that faces the camera), the page has x_b to the
right and y_b down. Mark k sits at angle ``2 pi k / 16`` from +x_b towards +y_b, so
calibration point k is ``m (cos a_k, sin a_k, 0)``; mark 0 is at the page's right.

:func:`ring_pattern` returns the printable A4 page (true size at its ``dpi``) and the
calibration points; :func:`save_ring_pattern` writes it as PNG and PDF;
:func:`render_ring_view` is the renderer the tests use: the pattern plane seen by a
pinhole camera with the radial distortion of eqs. 2.6-2.10 (``cv2.remap`` of a
high-resolution drawing of the pattern, supersampled so each pixel integrates its area).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import ConfigError
from omnidev.nonsvp.model import Lens, Pose, pixel_to_ideal

FloatArray = NDArray[np.float64]
MM_PER_INCH = 25.4
N_MARKS = 16
_PREFIX = "ring pattern"


@dataclass(frozen=True)
class RingLayout:
    """Geometry of the calibration ring on the base plane (all mm).

    ``mirror_radius_mm`` is the inner circle's radius (= the mirror base radius m);
    each mark is a black bar ``mark_width_mm`` wide running radially from the inner
    circle out to ``mirror_radius_mm + mark_length_mm``; the paper ends at
    ``mirror_radius_mm + ring_width_mm``.
    """

    mirror_radius_mm: float
    mark_length_mm: float = 5.0
    mark_width_mm: float = 1.5
    ring_width_mm: float = 9.0
    n_marks: int = N_MARKS

    def __post_init__(self) -> None:
        for key in ("mirror_radius_mm", "mark_length_mm", "mark_width_mm", "ring_width_mm"):
            value = getattr(self, key)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"{_PREFIX}: {key} must be a positive number (mm), got {value!r}")
        if self.mark_length_mm >= self.ring_width_mm:
            raise ConfigError(f"{_PREFIX}: mark_length_mm must be smaller than ring_width_mm")
        if self.n_marks < 4:
            raise ConfigError(f"{_PREFIX}: n_marks must be at least 4, got {self.n_marks}")
        gap = 2 * math.pi * self.mirror_radius_mm / self.n_marks
        if self.mark_width_mm >= 0.5 * gap:
            raise ConfigError(f"{_PREFIX}: marks {self.mark_width_mm} mm wide overlap on the ring")

    @property
    def outer_radius_mm(self) -> float:
        """Radius of the paper ring's outer edge (mm)."""
        return self.mirror_radius_mm + self.ring_width_mm

    def mark_angles(self) -> FloatArray:
        """(n,) angle of each mark from +x_b towards +y_b (rad): ``2 pi k / n``."""
        return 2.0 * np.pi * np.arange(self.n_marks) / self.n_marks

    def calibration_points_mm(self) -> FloatArray:
        """(n, 3) calibration points (x_b, y_b, z_b = 0) in the base frame (mm), mark order.

        Example:
            >>> RingLayout(30.0).calibration_points_mm()[4].round(6).tolist()
            [0.0, 30.0, 0.0]
        """
        a = self.mark_angles()
        m = self.mirror_radius_mm
        return np.stack([m * np.cos(a), m * np.sin(a), np.zeros_like(a)], axis=1)


@dataclass(frozen=True)
class RingSheet:
    """A drawn ring: ``image`` (uint8, 255 white) at ``dpi``; the ring's centre C is at
    page pixel ``center_px`` (col, row; centre of the top-left pixel = (0, 0)), x_b
    along +col and y_b along +row; ``points_mm`` are the calibration points (n, 3)."""

    image: NDArray[np.uint8]
    dpi: float
    center_px: tuple[float, float]
    layout: RingLayout

    @property
    def points_mm(self) -> FloatArray:
        """(n, 3) calibration points in the base frame (mm)."""
        return self.layout.calibration_points_mm()

    @property
    def px_per_mm(self) -> float:
        """Page pixels per millimetre."""
        return self.dpi / MM_PER_INCH

    def mm_to_px(self, xy_mm: FloatArray) -> FloatArray:
        """(..., 2) base-plane (x_b, y_b) in mm -> (..., 2) page (col, row)."""
        xy = np.asarray(xy_mm, np.float64)[..., :2]
        return np.asarray(xy * self.px_per_mm + np.asarray(self.center_px), np.float64)


def _coverage(signed_distance_px: FloatArray) -> FloatArray:
    """Area coverage of a pixel by a shape whose boundary is locally straight, from the
    signed distance (px, negative inside) of the pixel centre to that boundary."""
    return np.clip(0.5 - signed_distance_px, 0.0, 1.0)


def _draw_ring(
    layout: RingLayout,
    *,
    dpi: float,
    size_px: tuple[int, int],
    center_px: tuple[float, float],
    interior: float,
    surround: float,
    band_rows: int = 256,
) -> NDArray[np.uint8]:
    """Draw paper (255), marks (0), the inside of the inner circle (``interior``) and
    everything beyond the paper (``surround``) with anti-aliased edges."""
    w, h = size_px
    ppm = dpi / MM_PER_INCH
    m, r_out = layout.mirror_radius_mm * ppm, layout.outer_radius_mm * ppm
    length, half_w = layout.mark_length_mm * ppm, 0.5 * layout.mark_width_mm * ppm
    step = 2.0 * np.pi / layout.n_marks
    out = np.empty((h, w), np.uint8)
    x = np.arange(w, dtype=np.float64) - center_px[0]
    for r0 in range(0, h, band_rows):
        y = (np.arange(r0, min(h, r0 + band_rows), dtype=np.float64) - center_px[1])[:, None]
        rho = np.hypot(x[None, :], y)
        c_in = _coverage(rho - m)  # inside the inner circle
        c_paper = _coverage(np.maximum(m - rho, rho - r_out))
        c_sur = np.clip(1.0 - c_in - c_paper, 0.0, 1.0)
        k = np.round(np.arctan2(y, x[None, :]) / step)
        a = k * step
        s = x[None, :] * np.cos(a) + y * np.sin(a)  # along the nearest mark
        t = -x[None, :] * np.sin(a) + y * np.cos(a)  # across it
        c_mark = _coverage(np.maximum(np.maximum(m - s, s - (m + length)), np.abs(t) - half_w))
        c_white = np.clip(c_paper - c_mark, 0.0, 1.0)
        val = 255.0 * c_white + interior * c_in + surround * c_sur
        out[r0 : r0 + band_rows] = np.clip(np.round(val), 0, 255).astype(np.uint8)
    return out


def ring_pattern(
    mirror_radius_mm: float,
    *,
    mark_length_mm: float = 5.0,
    mark_width_mm: float = 1.5,
    ring_width_mm: float = 9.0,
    dpi: float = 300.0,
    paper_mm: tuple[float, float] = (210.0, 297.0),
) -> RingSheet:
    """The printable ring page of sec. 2.3.2 and its 16 calibration points.

    Args:
        mirror_radius_mm: the mirror's base radius m = the inner circle's radius (mm).
        mark_length_mm, mark_width_mm, ring_width_mm: see :class:`RingLayout`.
        dpi: printer dots per inch of the returned image.
        paper_mm: (width, height) of the portrait page (mm).

    Returns:
        A :class:`RingSheet`: white page, black marks, thin grey cut lines just inside
        the inner circle and just outside the outer edge (cut along them), a 100 mm
        scale bar to check the print's true size and a legend. ``points_mm`` are the
        calibration points in the base frame, mark order (mark 0 at the page's right,
        indices increasing clockwise as printed).

    Raises ConfigError when the ring does not fit on the page.

    Example:
        >>> sheet = ring_pattern(30.0, dpi=100)
        >>> sheet.image.shape, sheet.points_mm.shape
        ((1169, 827), (16, 3))
    """
    layout = RingLayout(mirror_radius_mm, mark_length_mm, mark_width_mm, ring_width_mm)
    ppm = dpi / MM_PER_INCH
    pw, ph = (round(v * ppm) for v in paper_mm)
    diameter = 2.0 * layout.outer_radius_mm
    if diameter + 20.0 > paper_mm[0] or diameter + 60.0 > paper_mm[1]:
        raise ConfigError(
            f"{_PREFIX}: a ring {diameter:.1f} mm across does not fit on a "
            f"{paper_mm[0]:g}x{paper_mm[1]:g} mm page with its scale bar"
        )
    center = ((pw - 1) / 2.0, (15.0 + layout.outer_radius_mm) * ppm)
    page = _draw_ring(
        layout, dpi=dpi, size_px=(pw, ph), center_px=center, interior=255.0, surround=255.0
    )
    thick = max(1, round(0.2 * ppm))
    centre_i = (round(center[0] * 16), round(center[1] * 16))
    for radius in (layout.mirror_radius_mm - 0.3, layout.outer_radius_mm + 0.3):
        cv2.circle(page, centre_i, round(radius * ppm * 16), 170, thick, cv2.LINE_AA, 4)
    cv2.drawMarker(page, (round(center[0]), round(center[1])), 170, cv2.MARKER_CROSS, 20, 1)
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, max(0.4, dpi / 300.0)
    y = center[1] + (layout.outer_radius_mm + 12.0) * ppm
    lines = (
        f"omnidev ring pattern (sec. 2.3.2): inner circle {2 * mirror_radius_mm:g} mm = "
        "mirror diameter",
        f"{layout.n_marks} marks {mark_width_mm:g} x {mark_length_mm:g} mm; mark 0 at right, "
        "indices clockwise",
        "print at 100 % (no fit-to-page); cut along the grey circles; printed side faces",
        "the camera; page right = +x_b, page down = +y_b",
    )
    for i, text in enumerate(lines):
        org = (round(10.0 * ppm), round(y + i * 6.0 * ppm))
        cv2.putText(page, text, org, font, scale, 0, max(1, round(dpi / 300)), cv2.LINE_AA)
    yb = round(ph - 15.0 * ppm)
    xb = round(10.0 * ppm)
    cv2.line(page, (xb, yb), (xb + round(100.0 * ppm), yb), 0, thick)
    for xt in (xb, xb + round(100.0 * ppm)):
        cv2.line(page, (xt, yb - round(2 * ppm)), (xt, yb + round(2 * ppm)), 0, thick)
    cv2.putText(page, "100 mm", (xb, yb - round(3 * ppm)), font, scale, 0, 1, cv2.LINE_AA)
    return RingSheet(page, float(dpi), center, layout)


def save_ring_pattern(
    sheet: RingSheet,
    outdir: Path,
    *,
    stem: str = "ring",
    force: bool = False,
    paper_mm: tuple[float, float] = (210.0, 297.0),
) -> list[Path]:
    """Write ``<stem>.png`` (at the sheet's dpi) and ``<stem>.pdf`` (the page at true size)
    into ``outdir``, atomically; returns the paths. Raises OutputError if one exists
    and not ``force``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from omnidev.atomic import atomic_path, check_output
    from omnidev.errors import OutputError

    outdir = Path(outdir)
    outs = [outdir / f"{stem}.png", outdir / f"{stem}.pdf"]
    for path in outs:
        check_output(path, force=force)
    with atomic_path(outs[0], force=force) as tmp:
        if not cv2.imwrite(str(tmp), sheet.image, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
            raise OutputError(f"{outs[0]}: cannot write the PNG")
    fig = plt.figure(figsize=(paper_mm[0] / MM_PER_INCH, paper_mm[1] / MM_PER_INCH))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))  # the page image fills the page exactly
    ax.imshow(sheet.image, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
    ax.set_axis_off()
    try:
        with atomic_path(outs[1], force=force) as tmp:
            fig.savefig(tmp, format="pdf", dpi=sheet.dpi)
    finally:
        plt.close(fig)
    return outs


def render_ring_view(
    layout: RingLayout,
    lens: Lens,
    pose: Pose,
    *,
    interior: float = 150.0,
    surround: float = 70.0,
    supersample: int = 4,
    dpi: float = 1200.0,
) -> NDArray[np.uint8]:
    """The ring as the camera sees it: (H, W) uint8 image of ``lens.size``.

    This is a test renderer, not the mirror model: every pixel's area is sampled
    ``supersample``^2 times; each sample (u_f, v_f) goes to distorted sensor
    coordinates (eq. 2.11), to ideal ones through ``lens`` (eq. 2.8), along the ray
    (u, v, f) of the camera frame to the base plane z_b = 0 through the inverse of
    eq. 2.4 (x_cam = R x_b + T with ``pose``), and samples a ``dpi`` drawing of the
    ring with ``cv2.remap`` (bilinear); the samples are averaged. Inside the inner
    circle (where the mirror would be) the value is ``interior``, beyond the paper
    ``surround``; rays that miss the plane get ``surround``.
    """
    w, h = lens.size
    s = int(supersample)
    ppm = dpi / MM_PER_INCH
    half = layout.outer_radius_mm * ppm + 8.0
    n = math.ceil(2 * half) + 1
    center = ((n - 1) / 2.0, (n - 1) / 2.0)
    src = _draw_ring(
        layout, dpi=dpi, size_px=(n, n), center_px=center, interior=interior, surround=surround
    )
    sub = (np.arange(s, dtype=np.float64) + 0.5) / s - 0.5
    uf = (np.arange(w, dtype=np.float64)[:, None] + sub[None, :]).ravel()
    vf = (np.arange(h, dtype=np.float64)[:, None] + sub[None, :]).ravel()
    ug, vg = np.meshgrid(uf, vf)
    xb, yb, ok = plane_points_from_pixels(np.stack([ug, vg], axis=-1), lens, pose)
    mapx = np.where(ok, xb * ppm + center[0], -10.0).astype(np.float32)
    mapy = np.where(ok, yb * ppm + center[1], -10.0).astype(np.float32)
    big = cv2.remap(
        src.astype(np.float32),
        mapx,
        mapy,
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float(surround),
    )
    img = big.reshape(h, s, w, s).mean(axis=(1, 3))
    return np.asarray(np.clip(np.round(img), 0, 255), np.uint8)


def plane_points_from_pixels(
    pixels: FloatArray, lens: Lens, pose: Pose
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Back-project pixels (..., 2) (u_f, v_f) onto the base plane z_b = 0.

    Pixel -> ideal (u, v) mm (eqs. 2.11, 2.8) -> ray lam (u, v, f) in the camera frame ->
    base frame by eq. 2.13 (``x_b = R^T x_c - T``) -> the point with z_b = 0.
    Returns (x_b, y_b) in mm, each of shape (...), and a mask of the pixels whose ray
    meets the plane in front of the camera.
    """
    px = np.asarray(pixels, np.float64)
    ideal = pixel_to_ideal(lens, px.reshape(-1, 2))
    d = np.c_[ideal, np.full(len(ideal), lens.f)]
    d_b = d @ pose.R()  # R^T d, row vectors
    t = np.asarray(pose.T, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = t[2] / d_b[:, 2]
    ok = np.isfinite(lam) & (lam > 0)
    lam = np.where(ok, lam, 0.0)
    shape = px.shape[:-1]
    xb = (lam * d_b[:, 0] - t[0]).reshape(shape)
    yb = (lam * d_b[:, 1] - t[1]).reshape(shape)
    return xb, yb, ok.reshape(shape)

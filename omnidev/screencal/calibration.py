"""Screen calibration from three captured patterns: image pixels -> screen pixels (ch. 5).

Pipeline (sec. 5.2): the screen's border polygon -> TDM (eq. 5.1) -> dot centres
(eqs. 5.2-5.3, DTM) -> the chosen image -> screen transform. The border comes
from the white-minus-black difference by default (``border="region"``: only the
screen changes by a large positive amount, so it cannot land on the wall), or
by the dissertation's scan windows on the TDM (``border="tdm"``, Figs. 5.5-5.7).
Any dot layout (rows x columns, margins: :func:`omnidev.screencal.patterns.dot_grid`)
is accepted and written into the calibration. Transforms (see
:mod:`omnidev.screencal.transform`): ``radial`` (default: the most accurate on the
rendered fixtures), ``bilinear``, ``idw`` (the dissertation's, eqs. 5.4-5.5),
``homography``, ``tsai``. Image pixels (u right, v down) and screen pixels (x
right, y down) both put the centre of the top-left pixel at (0, 0).

Example:
    >>> import numpy as np
    >>> from omnidev.screencal.calibration import METHODS
    >>> METHODS[0]
    'radial'
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.budget import check_pixels
from omnidev.calibfile import (
    check_header,
    open_storage,
    read_mat,
    read_real,
    read_string,
    write_storage,
)
from omnidev.errors import CalibrationError
from omnidev.screencal.coded import CodedLayout
from omnidev.screencal.dots import DotDetection, find_dots
from omnidev.screencal.features import (
    MIN_CONTRAST,
    BorderPolygon,
    border_from_edges,
    border_from_region,
    edge_points,
    exposure_gain,
    find_border,
    screen_region,
    threshold_map,
    to_gray,
)
from omnidev.screencal.grid import LandmarkGrid, landmark_grid
from omnidev.screencal.patterns import DotGrid, dot_grid
from omnidev.screencal.transform import (
    LENS_FORMS,
    CellMap,
    HomographyMap,
    ImageToScreen,
    RadialMap,
    invert,
)
from omnidev.screencal.tsai import TsaiMap

FloatArray = NDArray[np.float64]
KIND = "screen-calibration"
FORMAT_VERSION = 2  # 2: dot layout (rows, cols, margins, radius); version 1 still read
BORDERS = ("region", "tdm")
EXPOSURES = ("room", "as-is")  # the dots at their own capture's exposure, or as captured
METHODS = ("radial", "bilinear", "idw", "homography", "tsai")
DEFAULT_METHOD = "radial"
# the radial model's lens form: the lens's forward (Brown) distortion and the polynomial
# undistortion both fitted, the smaller residual kept; the polynomial alone cannot follow
# a strong barrel lens to the screen's corners (issue 12, 59020, 59135: 2-4 px off there)
DEFAULT_LENS_FORM = "auto"
# radial terms of the final fit with the forward form in play ("poly" alone keeps the
# fit's own rule: three for a whole grid, two for a partial one). k1, k2 of the forward
# form follow a strong barrel lens; a third term only took up the dots' noise: on the
# looked-at 59000-59199 the largest error's 95th percentile over the 112 large scenes
# within the bounds went 1.06 -> 0.94 screen px, and 59155 (h264) 1.55 -> 0.92
LENS_TERMS = 2
EDGE_TOLERANCE_PX = 1.0  # screen px beyond the screen's edge still mapped (not NaN)
CORNER_TOLERANCE = 0.02  # of the screen's width: the border's corners against the dots
# the dots' median miss of the layout (fraction of a spacing) above which the dots are
# measured too roughly: on 61000-61199 the in-spec scenes reach 0.028 (61097, calibrated
# within 0.52 px RMS), an out-of-spec one (61011: dots of 1.4 image px radius,
# calibrated 7.2 px RMS) 0.091
DOT_SCATTER = 0.05
EDGE_ENDS = 0.03  # fraction of each side's length, at both ends, with no edge profile


def min_dots(n: int, cols: int | None = None) -> int:
    """Fewest dots of an n x n (or n x cols) grid that still calibrate: half, at least 12
    (all of them if there are fewer than 12)."""
    count = n * (n if cols is None else cols)
    return min(count, max(12, math.ceil(count / 2)))


@dataclass(frozen=True)
class ScreenFeatures:
    """Everything measured in the three images: TDM, border polygon, dots, and the layout."""

    image_size: tuple[int, int]
    screen_size: tuple[int, int]
    n: int  # rows (kept for square grids; see layout)
    tdm: NDArray[np.uint8]
    border: BorderPolygon
    dots: DotDetection
    screen_dots: FloatArray  # (rows*cols, 2) screen px of the pattern's dots
    lattice: FloatArray  # x0, y0, sx, sy of the dot lattice on the screen
    layout: DotGrid | None = None
    edges: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None  # top, right, ..

    def edge_constraints(self) -> list[tuple[FloatArray, int, float]]:
        """The screen-edge points as (points, screen axis, value) for RadialMap.fit."""
        if self.edges is None:
            return []
        sw, sh = self.screen_size
        top, right, bottom, left = self.edges
        return [(top, 1, -0.5), (right, 0, sw - 0.5), (bottom, 1, sh - 0.5), (left, 0, -0.5)]

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the dot grid."""
        return self.dots.shape


MAX_UNEXPLAINED = 0.5  # of the dot image's spread outside the screen (see _unexplained)


def _unexplained(black: NDArray[np.int16], dots: NDArray[np.int16]) -> float:
    """How much of the dot image outside the screen the black image does not explain,
    0 (a function of it) .. about 1 (unrelated): the median distance of each dot-image
    pixel from the median of the pixels whose black-image level lies in the same bin of
    16 grey levels, over the dot image's median absolute deviation. An auto-exposure
    change between the captures (any increasing level map) leaves only the noise; a
    different scene or a moved camera over a textured room does not."""
    bins = black // 16
    dev = np.empty(dots.shape, np.float64)
    for k in np.unique(bins):
        sel = bins == k
        dev[sel] = np.abs(dots[sel] - np.median(dots[sel]))
    spread = float(np.median(np.abs(dots - np.median(dots))))
    return float(np.median(dev)) / max(spread, 1.0)


def _check_scene(
    w: NDArray[np.uint8], b: NDArray[np.uint8], d: NDArray[np.uint8], screen: NDArray[np.bool_]
) -> None:
    """Swapped or mismatched images, judged on the screen region (auto-exposure may
    brighten the room in the black image; only the screen must be darker there); the
    dot image outside the screen must differ from the black image by little, or by a
    change of exposure alone."""
    wi, bi, di = (x.astype(np.int16) for x in (w, b, d))
    diff = wi - bi
    on = screen
    if np.count_nonzero(on) and float(np.median(diff[on])) < 0:
        raise CalibrationError(
            "the black image is brighter than the white image on the screen: "
            "are --white and --black swapped?"
        )
    off = ~cv2.dilate(screen.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    if np.count_nonzero(off) > 0.02 * off.size:
        mismatch = float(np.median(np.abs(di - bi)[off]))
        unexplained = _unexplained(bi[off], di[off])
        if mismatch > 2 * MIN_CONTRAST and unexplained > MAX_UNEXPLAINED:
            raise CalibrationError(
                "the dot image does not match the black image outside the screen "
                f"(median difference {mismatch:.0f} grey levels, {100 * unexplained:.0f} % of "
                "its spread not explained by a change of exposure): different scene or "
                "camera moved?"
            )
    if np.count_nonzero(on) and np.count_nonzero(
        di[on] > (wi[on] + bi[on]) // 2
    ) > 0.5 * np.count_nonzero(on):
        raise CalibrationError(
            "the dot image is mostly bright inside the screen: is it the white image, "
            "not the dot matrix?"
        )


def _region_tdm(
    w: NDArray[np.uint8], b: NDArray[np.uint8], mask: NDArray[np.bool_]
) -> NDArray[np.uint8]:
    """The TDM (eq. 5.1) on the screen region: b + (w - b) / 2 inside, 255 outside."""
    wi, bi = w.astype(np.int16), b.astype(np.int16)
    t = np.full(w.shape, 255, np.uint8)
    t[mask] = np.clip(bi[mask] + np.maximum(wi[mask] - bi[mask], 0) // 2, 0, 255).astype(np.uint8)
    return t


def _grid_summary(uv: FloatArray, border: BorderPolygon, screen_size: tuple[int, int]) -> str:
    """'in about 7 rows x 7 columns': dot-like blobs counted along the screen's axes."""
    sw, sh = screen_size
    if len(uv) < 2:
        return ""
    corners_img = border.vertices[[0, 2, 4, 6]].astype(np.float32)
    corners_scr = np.array(
        [[-0.5, -0.5], [sw - 0.5, -0.5], [sw - 0.5, sh - 0.5], [-0.5, sh - 0.5]], np.float32
    )
    hmat = cv2.getPerspectiveTransform(corners_img, corners_scr)
    xy = np.asarray(
        cv2.perspectiveTransform(uv.reshape(-1, 1, 2).astype(np.float64), hmat), np.float64
    ).reshape(-1, 2)

    def clusters(v: FloatArray) -> int:
        v = np.sort(v)
        gaps = np.diff(v)
        if len(gaps) == 0:
            return 1
        big = gaps > max(0.4 * float(np.max(gaps)), 1e-9)
        return int(np.count_nonzero(big)) + 1

    return f" in about {clusters(xy[:, 1])} rows x {clusters(xy[:, 0])} columns"


def _grey_images(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    third: NDArray[np.uint8],
    name: str,
    border: str,
) -> tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray[np.uint8]]:
    """The white, black and ``name`` (dots or coded) images in grey, of one size, for the
    ``border`` method; CalibrationError otherwise."""
    if border not in BORDERS:
        raise CalibrationError(
            f"unknown border method {border!r}; choose from {', '.join(BORDERS)}"
        )
    w, b, t = to_gray(white), to_gray(black), to_gray(third)
    if not (w.shape == b.shape == t.shape):
        raise CalibrationError(
            f"image sizes differ: white {w.shape[::-1]}, black {b.shape[::-1]}, "
            f"{name} {t.shape[::-1]}"
        )
    return w, b, t


def detect_screen(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    dots: NDArray[np.uint8],
    *,
    n: int = 9,
    screen_size: tuple[int, int] = (1920, 1080),
    subpixel: bool = True,
    layout: DotGrid | None = None,
    border: str = "region",
    index: str = "model",
    use_edges: bool = True,
    exposure: str = "room",
) -> ScreenFeatures:
    """Measure the border polygon, the TDM and the dot centres in the three images.

    Images are H x W grey or BGR uint8 (one grey conversion, :func:`to_gray`, for
    every caller). ``layout`` is the displayed dot layout (default: ``n`` x ``n``
    dots of :func:`~omnidev.screencal.patterns.dot_grid` on ``screen_size``);
    ``border``: ``region`` (white minus black, default) or ``tdm`` (the
    dissertation's scan windows); ``index``: ``model`` (default) or ``walk`` (the
    dissertation's CMP walk), see :func:`omnidev.screencal.dots.find_dots`;
    ``use_edges``: also measure sub-pixel points on the screen's edges
    (:func:`~omnidev.screencal.features.edge_points`), which the ``radial`` method
    fits beside the dots; ``exposure``: ``room`` (default) reads the dot capture's
    exposure from the room (:func:`~omnidev.screencal.features.exposure_gain`) and
    thresholds and weighs the dots against the white and black images at it
    (:func:`~omnidev.screencal.dots.dot_threshold`: an auto-exposure camera sets it
    between theirs); ``as-is`` takes the images as captured (the dissertation).
    Raises CalibrationError saying what was found.
    """
    if exposure not in EXPOSURES:
        raise CalibrationError(
            f"unknown dot exposure {exposure!r}; choose from {', '.join(EXPOSURES)}"
        )
    w, b, d = _grey_images(white, black, dots, "dots", border)
    grid = dot_grid(screen_size[0], screen_size[1], n) if layout is None else layout
    screen_size = grid.screen_px
    rows, cols = grid.shape
    poly, tdm, gain = _border_tdm(w, b, d, border)
    dot_gain = exposure_gain(d, b, tdm < 255) if exposure == "room" else None
    det = find_dots(
        d,
        w,
        b,
        tdm,
        poly,
        (rows, cols),
        grid.centers,
        screen_size,
        subpixel=subpixel,
        index=index,
        black_gain=gain,
        dot_gain=dot_gain,
    )
    need = min_dots(rows, cols)
    expected = rows * cols
    blobs = det.blob_uv if det.blob_uv is not None else det.centers[det.found]
    if det.count < need:
        raise CalibrationError(
            f"found {det.count} of the {rows} x {cols} = {expected} dots (need {need}; "
            f"{det.blobs} dot-like blobs inside the screen"
            f"{_grid_summary(blobs, poly, screen_size)}): dots occluded, or the dot image "
            "does not show this layout (check --layout / --n)"
        )
    sx, sy = grid.spacing_px
    lattice = np.array([grid.centers[0, 0], grid.centers[0, 1], sx, sy])
    image_size = (w.shape[1], w.shape[0])
    if det.blobs > 1.3 * expected:
        raise CalibrationError(
            f"found {det.blobs} dot-like blobs inside the screen"
            f"{_grid_summary(blobs, poly, screen_size)}, expected {rows} x {cols} = "
            f"{expected}: is the layout right (check --layout / --n)?"
        )
    found = det.found
    model = RadialMap.fit(
        det.centers[found],
        grid.centers[found],
        image_size,
        lattice,
        (rows, cols),
        found,
        correct=False,
    )
    res = np.hypot(*(model(det.centers[found]) - grid.centers[found]).T)
    spacing = float(min(sx, sy))
    if float(np.median(res)) > 0.1 * spacing:
        raise CalibrationError(
            f"the {det.count} dots matched do not fit a {rows} x {cols} layout (median "
            f"residual {float(np.median(res)) / spacing:.2f} dot spacings; {det.blobs} dot-like "
            f"blobs inside the screen{_grid_summary(blobs, poly, screen_size)}): check "
            "--layout / --n"
        )
    miss = float(np.median(res)) / spacing
    if miss > DOT_SCATTER:
        radius = float(np.nanmedian(det.radius[found]))
        raise CalibrationError(
            f"the {det.count} dots are measured too roughly to calibrate: they miss a "
            f"{rows} x {cols} layout by a median {miss:.3f} dot "
            f"spacings (at most {DOT_SCATTER}); dots of {radius:.1f} image px radius: move "
            "the camera closer, or show fewer, larger dots (--layout)"
        )
    if subpixel:
        det = _unbias(det, grid.centers, grid.radius_px, image_size, lattice)
    edges = edge_points(w, b, poly, ends=EDGE_ENDS, black_gain=gain) if use_edges else None
    features = ScreenFeatures(
        image_size, screen_size, rows, tdm, poly, det, grid.centers, lattice, grid, edges
    )
    _check_features(features)
    return features


def detect_screen_coded(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    coded: NDArray[np.uint8],
    layout: CodedLayout,
    *,
    border: str = "region",
    use_edges: bool = True,
) -> ScreenFeatures:
    """Like :func:`detect_screen` with the ChArUco board of ``layout``
    (:mod:`omnidev.screencal.coded`) in place of the dot matrix: every corner found
    is identified, so there is no grid to index."""
    from omnidev.screencal.coded import find_charuco

    w, b, c = _grey_images(white, black, coded, "coded", border)
    poly, tdm, gain = _border_tdm(w, b, None, border)
    det = find_charuco(c, layout)
    grid = layout.lattice
    sx, sy = grid.spacing_px
    lattice = np.array([grid.centers[0, 0], grid.centers[0, 1], sx, sy])
    image_size = (w.shape[1], w.shape[0])
    edges = edge_points(w, b, poly, ends=EDGE_ENDS, black_gain=gain) if use_edges else None
    features = ScreenFeatures(
        image_size, grid.screen_px, grid.rows, tdm, poly, det, grid.centers, lattice, grid, edges
    )
    _check_features(features)
    return features


def _border_tdm(
    w: NDArray[np.uint8], b: NDArray[np.uint8], d: NDArray[np.uint8] | None, border: str
) -> tuple[BorderPolygon, NDArray[np.uint8], float]:
    """The border polygon, the TDM and the black image's exposure gain
    (:func:`~omnidev.screencal.features.exposure_gain`; 1 for ``tdm``) by ``border``
    (checking the scene on the way)."""
    if border == "region":
        region = screen_region(w, b)
        if d is not None:
            _check_scene(w, b, d, region.mask)
        poly = border_from_edges(w, b, border_from_region(region), region.black_gain)
        tdm = _region_tdm(w, b, poly.mask((w.shape[1], w.shape[0])) & region.mask)
        return poly, tdm, region.black_gain
    else:
        wi, bi = w.astype(np.int16), b.astype(np.int16)
        if np.count_nonzero(bi - wi > MIN_CONTRAST) > np.count_nonzero(wi - bi > MIN_CONTRAST):
            raise CalibrationError(
                "the black image is brighter than the white image: are --white and --black swapped?"
            )
        tdm = threshold_map(w, b)
        if d is not None:
            _check_scene(w, b, d, tdm < 255)
        poly = find_border(tdm)
    return poly, tdm, 1.0


JOINT_EDGE_MISS = 0.02  # dot spacings: edge points off their edge (median per side)
JOINT_DOT_MISS = 0.003  # dot spacings: dots off the layout (median), both in the joint fit


def _check_features(features: ScreenFeatures) -> None:
    """:func:`_check_alignment` of the dots against the border polygon, with a second
    opinion where it refuses: the calibration's own fit of the dots and the edge points
    together (:func:`fit_calibration`, ``radial``) must then leave every side's edge
    points within ``JOINT_EDGE_MISS`` of their edge and the dots within
    ``JOINT_DOT_MISS`` of the layout (medians, dot spacings), else its refusal stands.

    The polygon's corners are intersections of quadratic side fits and the dots'
    model is extrapolated to them beyond the outer dots: under strong barrel or
    pincushion distortion both miss by 12-65 image px, while the edge points are
    measured on the edges. Held-out range 65000-65199 had five large in-spec scenes
    refused by the check; four calibrated within 0.09-0.20 px RMS (0.25-0.59 max) and
    left their edge points 0.000-0.004 spacings and their dots 0.0007-0.0014 off in the
    joint fit. The fifth (65130: 1.07 px RMS, 5.83 max) left edge points unmappable, and
    a grid indexed one row or column off 1.0 spacing or unmappable (dots 0.004-0.008)."""
    det = features.dots
    try:
        _check_alignment(
            det,
            features.border,
            features.screen_dots,
            features.image_size,
            features.screen_size,
            features.lattice,
        )
    except CalibrationError:
        if features.edges is None or not _agrees_jointly(features):
            raise


def _agrees_jointly(features: ScreenFeatures) -> bool:
    """Whether the dots and the edge points fit one radial calibration (see
    :func:`_check_features`)."""
    try:
        fit = fit_calibration(features, "radial")
    except (CalibrationError, ValueError, np.linalg.LinAlgError):
        return False
    spacing = float(min(features.lattice[2], features.lattice[3]))
    for pts, axis, value in features.edge_constraints():
        pts = np.asarray(pts, np.float64).reshape(-1, 4)
        if len(pts) == 0:
            continue
        miss = np.abs(fit.image_to_screen(pts[:, :2])[:, axis] - value)
        if not np.isfinite(miss).all() or float(np.median(miss)) > JOINT_EDGE_MISS * spacing:
            return False
    found = features.dots.found
    dot_miss = np.hypot(
        *(fit.image_to_screen(features.dots.centers[found]) - features.screen_dots[found]).T
    )
    return (
        bool(np.isfinite(dot_miss).all()) and float(np.median(dot_miss)) <= JOINT_DOT_MISS * spacing
    )


def _check_alignment(
    det: DotDetection,
    border: BorderPolygon,
    screen_dots: FloatArray,
    image_size: tuple[int, int],
    screen_size: tuple[int, int],
    lattice: FloatArray,
) -> None:
    """The dots must agree with the border of the white/black images: a radial model
    fitted to the dots maps the border's mid-side vertices P1, P3, P5, P7 to the
    screen's edges within a quarter of the dot spacing, and its corners to the screen's
    corners within half a spacing.

    The border lies beyond the outer dots (a whole spacing on some layouts), where the
    model extrapolates: with three radial terms fitted to a whole grid the corners of
    tuning scenes 50110 and 50140 landed 0.55-1.09 spacings off, with one term
    0.01-0.03 (their calibrations, with the edges, were within 0.5 px RMS). So the
    models of one, two and three terms are each tried and the one that agrees best
    is judged: the dots must agree with the border under some lens model. Being the
    best of three, it is held to the corners within ``CORNER_TOLERANCE`` of the screen's
    width too (half a spacing of a 4 x 4 grid is 8 % of it: held-out scene 55094's
    corner, 4 % off, then passed, and its calibration was 89 px off)."""
    found = det.found
    sw, sh = screen_size
    screen_corners = np.array(
        [[-0.5, -0.5], [sw - 0.5, -0.5], [sw - 0.5, sh - 0.5], [-0.5, sh - 0.5]]
    )
    spacing = float(min(lattice[2], lattice[3]))
    corner_tol = min(0.5 * spacing, CORNER_TOLERANCE * sw)
    best: tuple[float, FloatArray, FloatArray] | None = None
    for terms in (1, 2, 3):
        model = RadialMap.fit(
            det.centers[found],
            screen_dots[found],
            image_size,
            lattice,
            det.shape,
            found,
            correct=True,
            terms=terms,
        )
        xy = model(border.vertices[[1, 3, 5, 7]])
        off = np.abs([xy[0, 1] + 0.5, xy[1, 0] - (sw - 0.5), xy[2, 1] - (sh - 0.5), xy[3, 0] + 0.5])
        # the corners too (a glare or an occluder can cut a corner off the lit region)
        coff = np.hypot(*(model(border.vertices[[0, 2, 4, 6]]) - screen_corners).T)
        score = float(np.max(np.r_[off / (0.25 * spacing), coff / corner_tol]))  # tolerances
        if best is None or score < best[0] or not np.isfinite(best[0]):
            best = (score, off, coff)
    assert best is not None
    _, off, coff = best
    worst = float(np.max(off))
    if np.isfinite(coff).all() and float(np.max(coff)) > corner_tol:
        k = int(np.argmax(coff))
        corner = ("top-left", "top-right", "bottom-right", "bottom-left")[k]
        raise CalibrationError(
            f"the dots do not line up with the screen border of the white/black images: "
            f"its {corner} corner is {float(coff[k]):.0f} screen px ({float(coff[k]) / spacing:.2f}"
            f" dot spacings; at most {corner_tol:.0f} px) from where the dots put it; is that "
            "corner hidden, or is a reflection or glare on the screen there?"
        )
    if not worst <= 0.25 * spacing:
        side = ("top", "right", "bottom", "left")[int(np.argmax(off))]
        hint = (
            "the dot grid is indexed off by a whole row or column (is the layout right?)"
            if worst > 0.6 * spacing
            else "different scenes, or the camera moved between the captures?"
        )
        raise CalibrationError(
            f"the dots do not line up with the screen border of the white/black images: "
            f"{side} edge off by {worst:.1f} screen px ({worst / spacing:.2f} dot spacings); "
            + hint
        )


def _unbias(
    det: DotDetection,
    screen_dots: FloatArray,
    radius: float,
    image_size: tuple[int, int],
    lattice: FloatArray,
    samples: int = 48,
) -> DotDetection:
    """Drop dots cut by an occluder, and remove the perspective/distortion bias of the
    dots' brightness centroids.

    A dot whose centre strays from the radial model fitted to all dots by more than
    6 x the median residual (and 1 % of the dot spacing) is dropped (partly hidden).

    A disc's image is not centred on the image of the disc's centre. With the radial
    model fitted to the raw centroids, each dot's outline (``samples`` points of the
    screen circle) is mapped into the image; the area centroid of that polygon minus
    the image of the centre is the bias, subtracted from the measured centre.
    """
    found = det.found.copy()
    uv, xy = det.centers[found], screen_dots[found]
    model = RadialMap.fit(uv, xy, image_size, lattice, det.shape, found, correct=False)
    # dots cut by an occluder: their centroids stray from the model fitted to all
    res = np.hypot(*(model(uv) - xy).T)
    bad = res > max(6.0 * float(np.median(res)), 0.01 * float(min(lattice[2], lattice[3])))
    if bad.any() and (~bad).sum() >= min_dots(det.rows, det.cols):
        idx = np.flatnonzero(found)[bad]
        found[idx] = False
        centers = det.centers.copy()
        centers[idx] = np.nan
        det = replace(det, centers=centers, found=found)
        uv, xy = det.centers[found], screen_dots[found]
        model = RadialMap.fit(uv, xy, image_size, lattice, det.shape, found, correct=False)
    a = np.arange(samples) * 2 * np.pi / samples
    ring = xy[:, None, :] + radius * np.stack([np.cos(a), np.sin(a)], axis=1)[None]
    start = np.repeat(uv, samples, axis=0)
    poly = invert(model, ring.reshape(-1, 2), start)
    poly = poly.reshape(len(uv), samples, 2)
    centre = invert(model, xy, uv)
    x, y = poly[..., 0], poly[..., 1]
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * y1 - x1 * y
    area = cross.sum(axis=1) / 2
    cx = ((x + x1) * cross).sum(axis=1) / (6 * area)
    cy = ((y + y1) * cross).sum(axis=1) / (6 * area)
    bias = np.stack([cx, cy], axis=1) - centre
    centers = det.centers.copy()
    centers[found] = uv - bias
    return replace(det, centers=centers)


@dataclass
class ScreenCalibration:
    """A fitted image -> screen calibration.

    image_size and screen_size are (W, H) in pixels; ``method`` names the transform;
    ``dots_used`` is how many of the rows x cols dots were found and used; ``layout``
    the displayed dot layout (rows, cols, margins, radius), written into the file.
    """

    image_size: tuple[int, int]
    screen_size: tuple[int, int]
    method: str
    dots_used: int
    n: int  # rows of the dot grid
    border: BorderPolygon
    transform: ImageToScreen
    dots_image: FloatArray = field(repr=False)  # (rows*cols, 2) image px, NaN if not found
    layout: DotGrid | None = None

    def image_to_screen(self, uv: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, 2) image px -> (N, 2) screen px; NaN outside the calibrated screen (more
        than EDGE_TOLERANCE_PX beyond its edges, or where the method is undefined)."""
        pts = np.asarray(uv, np.float64).reshape(-1, 2)
        xy = np.asarray(self.transform(pts), np.float64)
        sw, sh = self.screen_size
        lo, t = -0.5 - EDGE_TOLERANCE_PX, EDGE_TOLERANCE_PX
        with np.errstate(invalid="ignore"):
            out = (
                (xy[:, 0] < lo)
                | (xy[:, 1] < lo)
                | (xy[:, 0] > sw - 0.5 + t)
                | (xy[:, 1] > sh - 0.5 + t)
            )
        xy[out | ~np.isfinite(xy).all(axis=1)] = np.nan
        return xy

    def screen_mask(self) -> NDArray[np.bool_]:
        """H x W bool: image pixels inside the screen border polygon."""
        return self.border.mask(self.image_size)

    def save(self, path: Path, *, force: bool = True) -> None:
        """Write as cv2.FileStorage (.yml / .yml.gz), atomically, with the dot layout."""
        found: NDArray[np.bool_] = np.asarray(np.isfinite(self.dots_image).all(axis=1))
        lay = self.layout or dot_grid(self.screen_size[0], self.screen_size[1], self.n)
        nodes: dict[str, object] = {
            "method": self.method,
            "image_width": self.image_size[0],
            "image_height": self.image_size[1],
            "screen_width": self.screen_size[0],
            "screen_height": self.screen_size[1],
            "n": lay.rows,
            "rows": lay.rows,
            "cols": lay.cols,
            "margin_x": float(lay.margin_px[0]),
            "margin_y": float(lay.margin_px[1]),
            "radius_px": float(lay.radius_px),
            "polarity": lay.polarity,
            "dots_used": self.dots_used,
            "border": self.border.vertices,
            "dots_image": np.where(found[:, None], self.dots_image, -1.0),
            "dots_found": found.astype(np.int32).reshape(-1, 1),
        }
        nodes.update({k: np.asarray(v, np.float64) for k, v in self.transform.params().items()})
        write_storage(Path(path), KIND, FORMAT_VERSION, nodes, force=force)


def fit_calibration(
    features: ScreenFeatures, method: str = DEFAULT_METHOD, *, lens_form: str = DEFAULT_LENS_FORM
) -> ScreenCalibration:
    """Fit the image -> screen ``method`` to measured features; ``lens_form``: how the
    radial model (``radial``, and the dots it fills in for the cell methods) undoes the
    lens (:data:`omnidev.screencal.transform.LENS_FORMS`, or ``auto``: both fitted with
    ``LENS_TERMS`` radial terms, the one with the smaller residual kept; ``poly``: the
    polynomial alone with three terms for a whole grid, as before 2026-12-06)."""
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    if lens_form not in (*LENS_FORMS, "auto"):
        raise CalibrationError(
            f"unknown lens form {lens_form!r}; choose from {', '.join(LENS_FORMS)}, auto"
        )
    det = features.dots
    rows, cols = det.shape
    found = det.found
    uv, xy = det.centers[found], features.screen_dots[found]

    def radial() -> RadialMap:
        return RadialMap.fit(
            uv,
            xy,
            features.image_size,
            features.lattice,
            (rows, cols),
            found,
            edges=features.edge_constraints(),
            form=lens_form,
            terms=None if lens_form == "poly" else LENS_TERMS,
        )

    transform: ImageToScreen
    if method == "radial":
        transform = radial()
    elif method == "homography":
        transform = HomographyMap.fit(uv, xy)
    elif method == "tsai":
        transform = TsaiMap.fit(uv, xy, features.image_size)
    else:
        dots_img = det.centers.copy()
        if not found.all():  # a partial grid: missing dots from the radial model
            miss = ~found
            guess = HomographyMap(np.asarray(np.linalg.inv(HomographyMap.fit(uv, xy).hmat)))
            dots_img[miss] = invert(
                radial(), features.screen_dots[miss], guess(features.screen_dots[miss])
            )
        grid = landmark_grid(
            dots_img.reshape(rows, cols, 2),
            features.screen_dots.reshape(rows, cols, 2),
            features.border,
            features.screen_size,
        )
        transform = CellMap(grid, features.image_size, kind=method)
    return ScreenCalibration(
        features.image_size,
        features.screen_size,
        method,
        det.count,
        rows,
        features.border,
        transform,
        det.centers.copy(),
        features.layout,
    )


def calibrate_screen(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    dots: NDArray[np.uint8],
    *,
    n: int = 9,
    screen_size: tuple[int, int] = (1920, 1080),
    method: str = DEFAULT_METHOD,
    layout: DotGrid | None = None,
    border: str = "region",
) -> ScreenCalibration:
    """Calibrate image -> screen from the captured white, black and dot-matrix images
    (H x W grey or BGR uint8, one fixed camera; the dots ``n`` x ``n`` on
    ``screen_size`` or any ``layout``). Raises CalibrationError saying what was found
    (screen, dots, rows and columns) or which images look swapped or mismatched."""
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    features = detect_screen(
        white, black, dots, n=n, screen_size=screen_size, layout=layout, border=border
    )
    return fit_calibration(features, method)


MAX_SIDE = 32768
"""Largest image or screen side a calibration file may name, pixels."""


def _int(fs: object, path: Path, key: str) -> int:
    return int(read_real(fs, path, key))  # type: ignore[arg-type]


def load_screen_calibration(path: Path) -> ScreenCalibration:
    """Read a calibration written by :meth:`ScreenCalibration.save` (format 2, or 1 with
    square default layouts); errors name the file and the key."""
    path = Path(path)
    with open_storage(path) as fs:
        version = (
            int(read_real(fs, path, "format_version"))
            if not fs.getNode("format_version").empty()
            else FORMAT_VERSION
        )
        check_header(fs, path, KIND, 1 if version == 1 else FORMAT_VERSION)
        method = read_string(fs, path, "method")
        if method not in METHODS:
            raise CalibrationError(f"{path}: key 'method': unknown method {method!r}")
        image_size = (_int(fs, path, "image_width"), _int(fs, path, "image_height"))
        screen_size = (_int(fs, path, "screen_width"), _int(fs, path, "screen_height"))
        for what, (w, h) in (("image", image_size), ("screen", screen_size)):
            if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
                raise CalibrationError(
                    f"{path}: keys '{what}_width'/'{what}_height' = {w} x {h}; each must be "
                    f"1..{MAX_SIDE} pixels"
                )
        check_pixels(
            *image_size, 2.0, f"{path}: the masks of a {image_size[0]}x{image_size[1]} image"
        )
        if version == 1:
            rows = cols = _int(fs, path, "n")
            try:
                lay = dot_grid(screen_size[0], screen_size[1], rows)
            except ValueError as exc:
                raise CalibrationError(f"{path}: key 'n': {exc}") from None
        else:
            rows, cols = _int(fs, path, "rows"), _int(fs, path, "cols")
            margin = (read_real(fs, path, "margin_x"), read_real(fs, path, "margin_y"))
            try:
                lay = dot_grid(
                    screen_size[0],
                    screen_size[1],
                    rows=rows,
                    cols=cols,
                    margin_px=margin,
                    radius_px=read_real(fs, path, "radius_px"),
                )
            except ValueError as exc:
                raise CalibrationError(f"{path}: dot layout keys: {exc}") from None
        used = _int(fs, path, "dots_used")
        border = read_mat(fs, path, "border").astype(np.float64)
        if border.shape != (8, 2):
            raise CalibrationError(f"{path}: key 'border' must be 8 x 2, got {border.shape}")
        dots = read_mat(fs, path, "dots_image").astype(np.float64).reshape(-1, 2)
        found = np.asarray(read_mat(fs, path, "dots_found"), np.float64).ravel() > 0.5
        count = rows * cols
        if len(dots) != count or len(found) != count:
            raise CalibrationError(
                f"{path}: keys 'dots_image'/'dots_found' must have rows*cols = {count} rows"
            )
        dots[~found] = np.nan
        transform: ImageToScreen
        if method == "radial":
            keys = ("radial_params", "radial_scale", "residual", "lattice")
            params = {k: read_mat(fs, path, k) for k in keys}
            params["residual_shape"] = np.array([rows, cols], np.float64)
            node = fs.getNode("radial_form")  # absent before 2026-12-06: poly
            if not node.empty():  # written as a 1-vector; a plain number is read too
                params["radial_form"] = (
                    np.array([read_real(fs, path, "radial_form")])
                    if node.isReal() or node.isInt()
                    else read_mat(fs, path, "radial_form")
                )
            try:
                transform = RadialMap.from_params(params)
            except ValueError as exc:
                raise CalibrationError(f"{path}: key {exc}") from None
        elif method == "homography":
            transform = HomographyMap(read_mat(fs, path, "H").astype(np.float64))
        elif method == "tsai":
            transform = TsaiMap(read_mat(fs, path, "tsai_params"), image_size)
        else:
            gi = read_mat(fs, path, "grid_image").astype(np.float64)
            gs = read_mat(fs, path, "grid_screen").astype(np.float64)
            m = (rows + 2) * (cols + 2)
            if gi.shape != (m, 2) or gs.shape != (m, 2):
                raise CalibrationError(f"{path}: keys 'grid_image'/'grid_screen' must be {m} x 2")
            grid = LandmarkGrid(
                gi.reshape(rows + 2, cols + 2, 2), gs.reshape(rows + 2, cols + 2, 2)
            )
            transform = CellMap(grid, image_size, kind=method)
    return ScreenCalibration(
        image_size, screen_size, method, used, rows, BorderPolygon(border), transform, dots, lay
    )

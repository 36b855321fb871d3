"""Screen calibration from three captured patterns: image pixels -> screen pixels (ch. 5).

Pipeline (sec. 5.2): TDM (eq. 5.1) -> border polygon (Figs. 5.5-5.7) -> dot centres
(eqs. 5.2-5.3, DTM) -> the chosen image -> screen transform (see
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

import numpy as np
from numpy.typing import NDArray

from omnidev.calibfile import (
    check_header,
    open_storage,
    read_mat,
    read_real,
    read_string,
    write_storage,
)
from omnidev.errors import CalibrationError
from omnidev.screencal.dots import DotDetection, find_dots
from omnidev.screencal.features import (
    MIN_CONTRAST,
    BorderPolygon,
    find_border,
    threshold_map,
    to_gray,
)
from omnidev.screencal.grid import LandmarkGrid, landmark_grid
from omnidev.screencal.patterns import dot_grid
from omnidev.screencal.transform import CellMap, HomographyMap, ImageToScreen, RadialMap, invert
from omnidev.screencal.tsai import TsaiMap

FloatArray = NDArray[np.float64]
KIND = "screen-calibration"
FORMAT_VERSION = 1
METHODS = ("radial", "bilinear", "idw", "homography", "tsai")
DEFAULT_METHOD = "radial"
EDGE_TOLERANCE_PX = 1.0  # screen px beyond the screen's edge still mapped (not NaN)


def min_dots(n: int) -> int:
    """Fewest dots of an n x n grid that still calibrate: half of them, at least 12."""
    return max(12, math.ceil(n * n / 2))


@dataclass(frozen=True)
class ScreenFeatures:
    """Everything measured in the three images: TDM, border polygon, dots."""

    image_size: tuple[int, int]
    screen_size: tuple[int, int]
    n: int
    tdm: NDArray[np.uint8]
    border: BorderPolygon
    dots: DotDetection
    screen_dots: FloatArray  # (n*n, 2) screen px of the pattern's dots
    lattice: FloatArray  # x0, y0, sx, sy of the dot lattice on the screen


def _check_scene(w: NDArray[np.uint8], b: NDArray[np.uint8], d: NDArray[np.uint8]) -> None:
    wi, bi, di = (x.astype(np.int16) for x in (w, b, d))
    brighter = int(np.count_nonzero(wi - bi > MIN_CONTRAST))
    darker = int(np.count_nonzero(bi - wi > MIN_CONTRAST))
    if darker > brighter:
        raise CalibrationError(
            "the black image is brighter than the white image: are --white and --black swapped?"
        )
    off = (wi - bi) <= MIN_CONTRAST // 2
    if np.count_nonzero(off) > 0.02 * off.size:
        mismatch = float(np.median(np.abs(di - bi)[off]))
        if mismatch > MIN_CONTRAST:
            raise CalibrationError(
                "the dot image does not match the white/black images outside the screen "
                f"(median difference {mismatch:.0f} grey levels): different scene or camera moved?"
            )
    on = ~off
    if np.count_nonzero(on) and np.count_nonzero(
        di[on] > (wi[on] + bi[on]) // 2
    ) > 0.5 * np.count_nonzero(on):
        raise CalibrationError(
            "the dot image is mostly bright inside the screen: is it the white image, "
            "not the dot matrix?"
        )


def detect_screen(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    dots: NDArray[np.uint8],
    *,
    n: int = 9,
    screen_size: tuple[int, int] = (1920, 1080),
    subpixel: bool = True,
) -> ScreenFeatures:
    """Measure the TDM, the border polygon and the dot centres in the three images."""
    w, b, d = to_gray(white), to_gray(black), to_gray(dots)
    if not (w.shape == b.shape == d.shape):
        raise CalibrationError(
            f"image sizes differ: white {w.shape[::-1]}, black {b.shape[::-1]}, "
            f"dots {d.shape[::-1]}"
        )
    _check_scene(w, b, d)
    tdm = threshold_map(w, b)
    border = find_border(tdm)
    grid = dot_grid(screen_size[0], screen_size[1], n)
    det = find_dots(d, w, b, tdm, border, n, grid.centers, screen_size, subpixel=subpixel)
    need = min_dots(n)
    if det.count < need:
        raise CalibrationError(
            f"only {det.count} of {n * n} calibration dots found (need {need}): dots occluded, "
            "or the dot image does not show the dot matrix"
        )
    sx, sy = grid.spacing_px
    lattice = np.array([grid.centers[0, 0], grid.centers[0, 1], sx, sy])
    image_size = (w.shape[1], w.shape[0])
    if subpixel:
        det = _unbias(det, grid.centers, grid.radius_px, image_size, lattice)
    _check_alignment(det, border, grid.centers, image_size, screen_size, lattice)
    return ScreenFeatures(image_size, screen_size, n, tdm, border, det, grid.centers, lattice)


def _check_alignment(
    det: DotDetection,
    border: BorderPolygon,
    screen_dots: FloatArray,
    image_size: tuple[int, int],
    screen_size: tuple[int, int],
    lattice: FloatArray,
) -> None:
    """The dots must agree with the border of the white/black images: the radial model
    fitted to the dots maps the border's mid-side vertices P1, P3, P5, P7 to the
    screen's edges, within a tenth of the dot spacing."""
    found = det.found
    model = RadialMap.fit(det.centers[found], screen_dots[found], image_size, lattice, det.n, found)
    xy = model(border.vertices[[1, 3, 5, 7]])
    sw, sh = screen_size
    off = np.abs([xy[0, 1] + 0.5, xy[1, 0] - (sw - 0.5), xy[2, 1] - (sh - 0.5), xy[3, 0] + 0.5])
    worst = float(np.max(off))
    if not worst <= 0.1 * float(min(lattice[2], lattice[3])):
        side = ("top", "right", "bottom", "left")[int(np.argmax(off))]
        raise CalibrationError(
            f"the dots do not line up with the screen border of the white/black images "
            f"({side} edge off by {worst:.0f} screen px): different scenes, or the camera moved?"
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
    model = RadialMap.fit(uv, xy, image_size, lattice, det.n, found, correct=False)
    # dots cut by an occluder: their centroids stray from the model fitted to all
    res = np.hypot(*(model(uv) - xy).T)
    bad = res > max(6.0 * float(np.median(res)), 0.01 * float(min(lattice[2], lattice[3])))
    if bad.any() and (~bad).sum() >= min_dots(det.n):
        idx = np.flatnonzero(found)[bad]
        found[idx] = False
        centers = det.centers.copy()
        centers[idx] = np.nan
        det = replace(det, centers=centers, found=found)
        uv, xy = det.centers[found], screen_dots[found]
        model = RadialMap.fit(uv, xy, image_size, lattice, det.n, found, correct=False)
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
    ``dots_used`` is how many of the n x n dots were found and used.
    """

    image_size: tuple[int, int]
    screen_size: tuple[int, int]
    method: str
    dots_used: int
    n: int
    border: BorderPolygon
    transform: ImageToScreen
    dots_image: FloatArray = field(repr=False)  # (n*n, 2) image px, NaN if not found

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
        """Write as cv2.FileStorage (.yml / .yml.gz), atomically."""
        found: NDArray[np.bool_] = np.asarray(np.isfinite(self.dots_image).all(axis=1))
        nodes: dict[str, object] = {
            "method": self.method,
            "image_width": self.image_size[0],
            "image_height": self.image_size[1],
            "screen_width": self.screen_size[0],
            "screen_height": self.screen_size[1],
            "n": self.n,
            "dots_used": self.dots_used,
            "border": self.border.vertices,
            "dots_image": np.where(found[:, None], self.dots_image, -1.0),
            "dots_found": found.astype(np.int32).reshape(-1, 1),
        }
        nodes.update({k: np.asarray(v, np.float64) for k, v in self.transform.params().items()})
        write_storage(Path(path), KIND, FORMAT_VERSION, nodes, force=force)


def fit_calibration(features: ScreenFeatures, method: str = DEFAULT_METHOD) -> ScreenCalibration:
    """Fit the image -> screen ``method`` to measured features."""
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    det = features.dots
    n = features.n
    found = det.found
    uv, xy = det.centers[found], features.screen_dots[found]
    radial = RadialMap.fit(uv, xy, features.image_size, features.lattice, n, found)
    transform: ImageToScreen
    if method == "radial":
        transform = radial
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
                radial, features.screen_dots[miss], guess(features.screen_dots[miss])
            )
        grid = landmark_grid(
            dots_img.reshape(n, n, 2),
            features.screen_dots.reshape(n, n, 2),
            features.border,
            features.screen_size,
        )
        transform = CellMap(grid, features.image_size, kind=method)
    return ScreenCalibration(
        features.image_size,
        features.screen_size,
        method,
        det.count,
        n,
        features.border,
        transform,
        det.centers.copy(),
    )


def calibrate_screen(
    white: NDArray[np.uint8],
    black: NDArray[np.uint8],
    dots: NDArray[np.uint8],
    *,
    n: int = 9,
    screen_size: tuple[int, int] = (1920, 1080),
    method: str = DEFAULT_METHOD,
) -> ScreenCalibration:
    """Calibrate image -> screen from the captured white, black and n x n dot images
    (H x W grey or BGR uint8, one fixed camera). Raises CalibrationError saying what
    was not found (screen, dots) or which images look swapped or mismatched."""
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    features = detect_screen(white, black, dots, n=n, screen_size=screen_size)
    return fit_calibration(features, method)


def _int(fs: object, path: Path, key: str) -> int:
    return int(read_real(fs, path, key))  # type: ignore[arg-type]


def load_screen_calibration(path: Path) -> ScreenCalibration:
    """Read a calibration written by :meth:`ScreenCalibration.save`; errors name the
    file and the key."""
    path = Path(path)
    with open_storage(path) as fs:
        check_header(fs, path, KIND, FORMAT_VERSION)
        method = read_string(fs, path, "method")
        if method not in METHODS:
            raise CalibrationError(f"{path}: key 'method': unknown method {method!r}")
        image_size = (_int(fs, path, "image_width"), _int(fs, path, "image_height"))
        screen_size = (_int(fs, path, "screen_width"), _int(fs, path, "screen_height"))
        n = _int(fs, path, "n")
        used = _int(fs, path, "dots_used")
        border = read_mat(fs, path, "border").astype(np.float64)
        if border.shape != (8, 2):
            raise CalibrationError(f"{path}: key 'border' must be 8 x 2, got {border.shape}")
        dots = read_mat(fs, path, "dots_image").astype(np.float64).reshape(-1, 2)
        found = np.asarray(read_mat(fs, path, "dots_found"), np.float64).ravel() > 0.5
        if len(dots) != n * n or len(found) != n * n:
            raise CalibrationError(
                f"{path}: keys 'dots_image'/'dots_found' must have n*n = {n * n} rows"
            )
        dots[~found] = np.nan
        transform: ImageToScreen
        if method == "radial":
            keys = ("radial_params", "radial_scale", "residual", "lattice")
            transform = RadialMap.from_params({k: read_mat(fs, path, k) for k in keys})
        elif method == "homography":
            transform = HomographyMap(read_mat(fs, path, "H").astype(np.float64))
        elif method == "tsai":
            transform = TsaiMap(read_mat(fs, path, "tsai_params"), image_size)
        else:
            gi = read_mat(fs, path, "grid_image").astype(np.float64)
            gs = read_mat(fs, path, "grid_screen").astype(np.float64)
            m = n + 2
            if gi.shape != (m * m, 2) or gs.shape != (m * m, 2):
                raise CalibrationError(
                    f"{path}: keys 'grid_image'/'grid_screen' must be {m * m} x 2"
                )
            grid = LandmarkGrid(gi.reshape(m, m, 2), gs.reshape(m, m, 2))
            transform = CellMap(grid, image_size, kind=method)
    return ScreenCalibration(
        image_size, screen_size, method, used, n, BorderPolygon(border), transform, dots
    )

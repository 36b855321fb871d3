"""Screen calibration, pure pieces on small synthetic arrays with known answers."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from omnidev.errors import CalibrationError, OutputError
from omnidev.screencal.features import BorderPolygon, binarize, find_border, threshold_map
from omnidev.screencal.framebuffer import FbFormat, pack_pixels, parse_screeninfo
from omnidev.screencal.grid import LandmarkGrid, ray_polygon
from omnidev.screencal.transform import CellMap, RadialMap, inverse_bilinear
from omnidev.screencal.tsai import TsaiMap, _apply


def test_threshold_map_eq_5_1_and_binarization_eq_5_2() -> None:
    w = np.array([[200, 40, 100]], np.uint8)
    b = np.array([[20, 30, 79]], np.uint8)
    t = threshold_map(w, b)
    # 20 + 180/2 = 110; 40 - 30 = 10 <= 20 -> 255; 100 - 79 = 21 > 20 -> 79 + 10 = 89
    assert t.tolist() == [[110, 255, 89]]
    d = np.array([[111, 255, 89]], np.uint8)
    assert binarize(d, t).tolist() == [[255, 0, 0]]


def test_threshold_map_rejects_different_sizes() -> None:
    with pytest.raises(CalibrationError, match="white image is"):
        threshold_map(np.zeros((4, 5), np.uint8), np.zeros((5, 4), np.uint8))


def _rect_tdm(x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    t = np.full((120, 160), 255, np.uint8)
    t[y0:y1, x0:x1] = 100
    return t


def test_border_of_a_rectangle_is_exact() -> None:
    # screen pixels 30..129 x 20..99: edges at 29.5, 129.5, 19.5, 99.5
    b = find_border(_rect_tdm(30, 20, 130, 100), step=1)
    v = b.vertices
    assert v[1][1] == 19.5 and v[5][1] == 99.5 and v[7][0] == 29.5 and v[3][0] == 129.5
    np.testing.assert_allclose(
        v[[0, 2, 4, 6]], [[29.5, 19.5], [129.5, 19.5], [129.5, 99.5], [29.5, 99.5]]
    )
    m = b.mask((160, 120))
    # every pixel inside; the polygon's rasterisation may add the pixels its sides touch
    assert m[20:100, 30:130].all() and m.sum() <= 102 * 82


def test_no_screen_is_one_clear_error() -> None:
    with pytest.raises(CalibrationError, match="screen not found"):
        find_border(np.full((60, 80), 255, np.uint8))


def test_ray_meets_polygon_side() -> None:
    sq = BorderPolygon(
        np.array([[0, 0], [5, 0], [10, 0], [10, 5], [10, 10], [5, 10], [0, 10], [0, 5]], float)
    )
    p = ray_polygon(np.array([3.0, 4.0]), np.array([-1.0, 0.0]), sq)
    np.testing.assert_allclose(p, [0.0, 4.0])


def _affine_grid() -> tuple[LandmarkGrid, np.ndarray]:
    a = np.array([[2.0, 0.3, 10.0], [-0.2, 1.5, 20.0]])  # screen = A [u, v, 1]
    gu, gv = np.meshgrid(np.linspace(20, 120, 5), np.linspace(20, 100, 5))
    img = np.stack([gu, gv], -1)
    scr = img @ a[:, :2].T + a[:, 2]
    return LandmarkGrid(img, scr), a


def test_bilinear_cells_exact_for_affine_and_idw_exact_at_nodes() -> None:
    grid, a = _affine_grid()
    rng = np.random.default_rng(1)
    uv = rng.uniform(21, 119, (200, 2))
    uv[:, 1] = rng.uniform(21, 99, 200)
    bil = CellMap(grid, (140, 120), kind="bilinear")
    np.testing.assert_allclose(bil(uv), uv @ a[:, :2].T + a[:, 2], atol=1e-6)
    idw = CellMap(grid, (140, 120), kind="idw")
    nodes = grid.image.reshape(-1, 2)
    np.testing.assert_allclose(idw(nodes), grid.screen.reshape(-1, 2), atol=1e-6)
    # eq. 5.4 by hand at one point of cell (0, 0): weights 1/d to its four corners
    p = np.array([[25.0, 22.0]])
    c = np.array([[20, 20], [45, 20], [45, 40], [20, 40]], float)
    wk = 1 / np.hypot(*(c - p).T)
    s = c @ a[:, :2].T + a[:, 2]
    np.testing.assert_allclose(idw(p)[0], (wk[:, None] * s).sum(0) / wk.sum(), atol=1e-9)


def test_border_cells_reach_the_image_border() -> None:
    grid, a = _affine_grid()
    bil = CellMap(grid, (140, 120), kind="bilinear")
    uv = np.array([[60.0, 5.0], [5.0, 60.0], [130.0, 60.0], [60.0, 115.0], [5.0, 5.0]])
    out = bil(uv)
    np.testing.assert_allclose(out[:4], uv[:4] @ a[:, :2].T + a[:, 2], atol=1e-6)
    assert np.isnan(out[4]).all()  # the corner of the border area is not in any cell


def test_inverse_bilinear_of_a_skewed_quad() -> None:
    q = np.array([[[0, 0], [10, 1], [12, 9], [-1, 8]]], float)
    s, t = 0.3, 0.7
    p = (
        (1 - s) * (1 - t) * q[0, 0]
        + s * (1 - t) * q[0, 1]
        + s * t * q[0, 2]
        + (1 - s) * t * q[0, 3]
    )
    np.testing.assert_allclose(inverse_bilinear(q, p[None])[0, 0], [s, t], atol=1e-10)


def test_tsai_recovers_a_one_term_camera() -> None:
    size = (640, 480)
    rvec = np.array([0.1, -0.25, 0.02])
    truth = np.array([1.6, -0.2, *rvec, -0.8, -0.45, 2.0]) * np.array(
        [1, 1, 1, 1, 1, 1e-3, 1e-3, 1e-3]
    )
    model = TsaiMap(truth, size)
    uv = np.stack(np.meshgrid(np.linspace(80, 560, 9), np.linspace(60, 420, 9)), -1).reshape(-1, 2)
    xy = _apply(truth, uv, model.centre, model.scale)
    fit = TsaiMap.fit(uv, xy, size)
    probe = np.array([[20.0, 20.0], [620.0, 460.0], [320.0, 240.0]])
    np.testing.assert_allclose(fit(probe), model(probe), atol=1e-4 * np.ptp(xy[:, 0]))
    assert math.isclose(fit.kappa1, -0.2, abs_tol=1e-4)


def test_radial_model_fits_opencv_distortion() -> None:
    # camera: OpenCV radial (k1, k2), principal point off-centre; plane seen at a slant
    k = np.array([[600.0, 0, 330], [0, 600, 236], [0, 0, 1]])
    dist = np.array([-0.25, 0.03, 0, 0, 0])
    rvec, tvec = np.array([0.05, 0.3, 0.01]), np.array([-0.9, -0.5, 2.2])
    xs, ys = np.meshgrid(np.arange(9) * 0.2 + 0.1, np.arange(9) * 0.1 + 0.05)
    xy = np.stack([xs, ys], -1).reshape(-1, 2)
    uv = cv2.projectPoints(np.c_[xy, np.zeros(81)], rvec, tvec, k, dist)[0].reshape(-1, 2)
    lattice = np.array([0.1, 0.05, 0.2, 0.1])
    m = RadialMap.fit(uv, xy, (640, 480), lattice, 9, np.ones(81, bool), correct=False)
    assert np.abs(m(uv) - xy).max() < 1e-3 * 1.6  # < 0.1 % of the plane's width


def test_pack_pixels_rgb565_xrgb8888_and_grey() -> None:
    img = np.array([[[0x10, 0x80, 0xF0], [0, 0, 0]]], np.uint8)  # BGR
    f565 = FbFormat(2, 1, 0, 0, 16, 6, (11, 5), (5, 6), (0, 5), (0, 0))
    raw = pack_pixels(img, f565)
    word = int.from_bytes(raw[:2], "little")
    assert word == (0xF0 >> 3) << 11 | (0x80 >> 2) << 5 | (0x10 >> 3)
    assert len(raw) == 6 and raw[4:] == b"\0\0"  # row padded to line_length
    f32 = FbFormat(2, 1, 0, 0, 32, 8, (16, 8), (8, 8), (0, 8), (24, 8))
    assert pack_pixels(img, f32)[:4] == bytes([0x10, 0x80, 0xF0, 0xFF])
    with pytest.raises(OutputError, match="framebuffer is 3x1"):
        pack_pixels(img, FbFormat(3, 1, 0, 0, 32, 12, (16, 8), (8, 8), (0, 8), (0, 0)))


def test_parse_screeninfo_reads_the_kernel_structs() -> None:
    import struct

    var = struct.pack(
        "=8I12I", 1024, 768, 1024, 1536, 0, 768, 16, 0, 11, 5, 0, 5, 6, 0, 0, 5, 0, 0, 0, 0
    )
    var += bytes(160 - len(var))
    fix = struct.pack("@16sLIIIIHHHI", b"Virtual FB", 0, 1 << 20, 0, 0, 2, 1, 1, 0, 2048)
    fix += bytes(80 - len(fix))
    f = parse_screeninfo(var, fix)
    assert (f.xres, f.yres, f.yoffset, f.bits_per_pixel, f.line_length) == (
        1024,
        768,
        768,
        16,
        2048,
    )
    assert f.red == (11, 5) and f.green == (5, 6) and f.blue == (0, 5)

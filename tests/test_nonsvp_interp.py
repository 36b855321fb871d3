"""Chapter 3 interpolation of unfilled pixels, against intact images (known truth).

Intact images (the committed omni_room fixtures; the real Mei paracatadioptric
frame from shared/realdata when present) get holes punched with a deterministic
back-projection-like pattern (omnidev.nonsvp.interp.synthetic_unfilled_mask: few
holes on the left, dense on the right). The edge-value image is the Sobel edge
value of the intact grey image read at the filled pixels only, as the unwarped
edge-value image of sec. 3.2.2 (1) would be. PSNR is taken over the unfilled
pixels (the filled ones are exact by construction) and over the unfilled pixels
on strong edges (true edge value >= e_t = 0.35). ``pytest -s`` prints the table.
"""

from __future__ import annotations

import math
from functools import cache

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from omnidev.nonsvp.interp import (
    find_on_edge_pairs,
    interpolate_4nn,
    interpolate_edge_preserving,
    interpolate_two_layered,
    interpolate_two_layered_reference,
    sobel_edge_value,
    synthetic_unfilled_mask,
    wedge_index,
    window_offsets,
)
from tests.conftest import REALDATA, REPO, psnr

MEI = REALDATA / "mei_paracatadioptric" / "images" / "img_para_001.pgm"
IMAGES = ["omni_room", "panorama", "mei"]
METHODS = ["4nn", "two_layered", "edge_preserving", "telea"]
DENSER = [(1.3, 2.6), (1.8, 2.5), (2.5, 3.5), (3.0, 4.5)]


def _image(name: str) -> NDArray[np.uint8]:
    if name == "omni_room":
        img = cv2.imread(str(REPO / "fixtures" / "omni_room" / "omni_0000.png"))
    elif name == "panorama":
        img = cv2.imread(str(REPO / "fixtures" / "omni_room" / "truth_panorama.png"))
    else:
        if not MEI.is_file():
            pytest.skip(f"real image {MEI} absent (shared/realdata not mounted)")
        img = cv2.imread(str(MEI), cv2.IMREAD_GRAYSCALE)
        assert img is not None
        img = img[300:700, 350:950]
    assert img is not None
    return np.ascontiguousarray(img, dtype=np.uint8)


@cache
def _case(name: str, magnification: tuple[float, float] = (1.0, 1.8)) -> dict[str, float]:
    """PSNR (all holes, edge holes) of each method on one image; the table's row."""
    img = _image(name)
    filled = synthetic_unfilled_mask(img.shape[:2], magnification=magnification)
    raw = img * (filled[:, :, None] if img.ndim == 3 else filled)
    gray = img if img.ndim == 2 else np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), np.uint8)
    edge_value = sobel_edge_value(gray)
    holes = ~filled
    on_edge = holes & (edge_value >= 0.35)
    outs = {
        "4nn": interpolate_4nn(raw, filled),
        "two_layered": interpolate_two_layered(raw, filled),
        "edge_preserving": interpolate_edge_preserving(raw, filled, edge_value * filled),
        "telea": cv2.inpaint(raw, holes.astype(np.uint8), 3, cv2.INPAINT_TELEA),
    }
    row: dict[str, float] = {"holes": float(holes.mean()), "edge_px": float(on_edge.sum())}
    for k, out in outs.items():
        assert out.shape == img.shape and out.dtype == img.dtype
        assert np.array_equal(out[filled], img[filled]), f"{k} changed filled pixels"
        row[k] = psnr(out, img, holes)
        row[k + "@edge"] = psnr(out, img, on_edge)
    return row


@pytest.fixture(scope="module", autouse=True)
def _table() -> object:
    yield
    rows = []
    for name in IMAGES:
        try:
            rows.append((name, _case(name)))
        except pytest.skip.Exception:
            continue
    # denser holes (a view magnifying the omni-image more): printed, not asserted
    for mag in DENSER:
        rows.append((f"omni {mag[0]:.1f}-{mag[1]:.1f}x", _case("omni_room", mag)))
    print("\nPSNR dB over unfilled pixels / over unfilled pixels on edges (e >= 0.35)")
    print(f"{'image':<14} {'holes':>5} {'edge px':>7} " + " ".join(f"{m:>15}" for m in METHODS))
    for name, r in rows:
        cells = " ".join(f"{r[m]:7.2f}/{r[m + '@edge']:7.2f}" for m in METHODS)
        print(f"{name:<14} {r['holes']:5.2f} {r['edge_px']:7.0f} {cells}")


# ---------------------------------------------------------------- quality


@pytest.mark.parametrize("name", IMAGES)
def test_edge_preserving_beats_two_layered_on_edges(name: str) -> None:
    r = _case(name)
    assert r["holes"] > 0.2
    assert r["edge_preserving@edge"] >= r["two_layered@edge"] + 0.5


@pytest.mark.parametrize("name", IMAGES)
def test_edge_preserving_beats_4nn_on_edges_or_not(name: str) -> None:
    """The measured edge-pixel ranking against 4NN, image by image (see the table)."""
    r = _case(name)
    # 4NN is a strong baseline on edges too: the real Mei frame is the one image
    # where it keeps a small lead (measured 19.84 vs 19.48 dB).
    if name == "mei":
        assert r["edge_preserving@edge"] > r["4nn@edge"] - 1.0
    else:
        assert r["edge_preserving@edge"] > r["4nn@edge"]


@pytest.mark.xfail(
    strict=True,
    reason="measured: the 4 nearest filled pixels beat the 7x7 two-layered weighting "
    "over all holes on every image tried (3.6-4.7 dB here at 35 % holes, 0.8 dB at 87 %); "
    "see docs/nonsvp-interpolation.md",
)
@pytest.mark.parametrize("name", IMAGES)
def test_two_layered_beats_4nn(name: str) -> None:
    r = _case(name)
    assert r["two_layered"] > r["4nn"]


@pytest.mark.xfail(
    strict=True,
    reason="measured: over all holes 4NN leads edge-preserving (2.6-5.4 dB here; the "
    "two-layered value fills every non-edge hole); see docs/nonsvp-interpolation.md",
)
@pytest.mark.parametrize("name", IMAGES)
def test_edge_preserving_beats_4nn(name: str) -> None:
    r = _case(name)
    assert r["edge_preserving"] > r["4nn"]


# ------------------------------------------------------- exactness of the eqs.


def _two_layered_by_hand(
    val: NDArray[np.float32], filled: NDArray[np.bool_], y: int, x: int
) -> float:
    """Eqs. 3.3-3.8 for one pixel, loop by loop, 7x7 window."""
    h, w = filled.shape
    dx, dy = window_offsets(7)
    k = wedge_index(dx, dy)
    pix: list[list[tuple[float, float]]] = [[] for _ in range(8)]
    for ddx, ddy, kk in zip(dx, dy, k, strict=True):
        yy, xx = y + int(ddy), x + int(ddx)
        if 0 <= yy < h and 0 <= xx < w and filled[yy, xx]:
            pix[int(kk)].append((math.hypot(float(ddx), float(ddy)), float(val[yy, xx])))
    big_m = sum(len(p) for p in pix)  # (3.3)
    i_u = 0.0
    for p in pix:
        if not p:
            continue
        s_i = len(p) / big_m  # (3.4)
        d_i = sum(1.0 / d for d, _ in p)  # (3.5)
        i_u += sum((1.0 / d) / d_i * s_i * v for d, v in p)  # (3.6), (3.7), (3.8)
    return i_u


def test_two_layered_equals_the_equations() -> None:
    rng = np.random.default_rng(3)
    val = rng.uniform(0.0, 255.0, (40, 50)).astype(np.float32)
    filled = rng.random((40, 50)) < 0.4
    out = interpolate_two_layered(val, filled)
    ref = interpolate_two_layered_reference(val, filled)
    np.testing.assert_allclose(out, ref, rtol=0, atol=2e-3)
    ys, xs = np.nonzero(~filled)
    for y, x in list(zip(ys, xs, strict=True))[::7]:
        want = _two_layered_by_hand(val, filled, int(y), int(x))
        assert out[y, x] == pytest.approx(want, abs=2e-3)


def test_wedges_partition_the_window() -> None:
    dx, dy = window_offsets(7)
    k = wedge_index(dx, dy)
    assert np.bincount(k, minlength=8).tolist() == [6] * 8
    # S_1 starts on +x, S_3 on +y (image down)
    assert k[(dx == 1) & (dy == 0)][0] == 0 and k[(dx == 0) & (dy == 1)][0] == 2


def test_4nn_is_the_mean_of_the_four_nearest() -> None:
    raw = np.zeros((9, 9), np.float32)
    filled = np.zeros((9, 9), bool)
    for (x, y), v in {(5, 4): 10.0, (4, 2): 20.0, (2, 4): 30.0, (6, 6): 40.0, (7, 4): 99.0}.items():
        raw[y, x], filled[y, x] = v, True
    # from (4, 4): distances 1, 2, 2, 2.83, 3 -> the first four
    assert interpolate_4nn(raw, filled)[4, 4] == pytest.approx((10 + 20 + 30 + 40) / 4)


# ------------------------------------------------------------ edge pairs


def test_fig_3_10_pair_accepted_at_120_not_at_180() -> None:
    filled = np.zeros((7, 7), bool)
    edges = np.zeros((7, 7), np.float32)
    for x, y in [(4, 4), (2, 3)]:  # offsets (1, 1) and (-1, 0) from (3, 3)
        filled[y, x], edges[y, x] = True, 1.0
    p120 = find_on_edge_pairs(filled, edges, theta_t_deg=120.0)
    at = {(int(y), int(x)) for y, x in zip(p120.ys, p120.xs, strict=True)}
    assert (3, 3) in at
    i = list(zip(p120.ys.tolist(), p120.xs.tolist(), strict=True)).index((3, 3))
    assert p120.theta_deg[i] == pytest.approx(135.0)
    p180 = find_on_edge_pairs(filled, edges, theta_t_deg=180.0)
    assert (3, 3) not in set(zip(p180.ys.tolist(), p180.xs.tolist(), strict=True))


def test_eq_3_9_uses_the_straightest_pair() -> None:
    raw = np.full((9, 9), 0, np.uint8)
    filled = np.zeros((9, 9), bool)
    edges = np.zeros((9, 9), np.float32)
    # a vertical edge line through (4, 4): 100 one above, 40 two below (180 deg);
    # a bent pair (135 deg) that must lose: 250 at (+1, +1), 250 at (-1, 0)
    for (x, y), v, e in [
        ((4, 3), 100, 1.0),
        ((4, 6), 40, 1.0),
        ((5, 5), 250, 1.0),
        ((3, 4), 250, 1.0),
    ]:
        raw[y, x], filled[y, x], edges[y, x] = v, True, e
    out = interpolate_edge_preserving(raw, filled, edges)
    assert out[4, 4] == round((100 / 1 + 40 / 2) / (1 / 1 + 1 / 2))  # 80
    # below e_t the pair is not an edge: two-layered value instead
    out2 = interpolate_edge_preserving(raw, filled, edges * 0.3)
    assert out2[4, 4] == interpolate_two_layered(raw, filled)[4, 4] != 80


def test_sobel_edge_value_normalized() -> None:
    img = np.zeros((20, 20), np.uint8)
    img[:, 10:] = 200
    e = sobel_edge_value(img)
    assert e.dtype == np.float32 and float(e.max()) == 1.0
    assert float(e[:, :8].max()) == 0.0 and float(e[:, 12:].max()) == 0.0
    assert np.all(e[:, 9:11] == 1.0)
    assert not sobel_edge_value(np.full((5, 5), 7, np.uint8)).any()


# ------------------------------------------------------------ window growth


def test_window_growth_fills_a_big_hole() -> None:
    yy, xx = np.mgrid[0:60, 0:60]
    truth = (2.0 * xx + 1.0 * yy).astype(np.float32)  # a linear ramp
    filled = np.ones((60, 60), bool)
    filled[15:40, 20:45] = False  # 25 x 25: centre pixels 12 px from support
    out = interpolate_two_layered(truth * filled, filled)
    out_nn = interpolate_4nn(truth * filled, filled)
    # the centre needs R = 25 x 25; a symmetric ring gives the ramp's value exactly
    assert out[27, 32] == pytest.approx(truth[27, 32], abs=1e-3)
    # every hole got a convex combination of support values: inside their range
    lo, hi = float(truth[filled].min()), float(truth[filled].max())
    for o in (out, out_nn):
        assert np.isfinite(o).all()
        assert float(o[~filled].min()) >= lo and float(o[~filled].max()) <= hi


def test_beyond_max_window_takes_the_nearest_filled_value() -> None:
    raw = np.zeros((30, 30, 3), np.uint8)
    filled = np.zeros((30, 30), bool)
    raw[2, 2], filled[2, 2] = (9, 8, 7), True
    raw[27, 27], filled[27, 27] = (90, 80, 70), True
    out = interpolate_two_layered(raw, filled, max_window=9)
    assert tuple(out[5, 5]) == (9, 8, 7)  # within 9 x 9 of (2, 2)
    assert tuple(out[20, 21]) == (90, 80, 70)  # nearest is (27, 27), outside 9 x 9
    assert tuple(out[12, 14]) == (9, 8, 7)  # nearest is (2, 2), outside 9 x 9


# ------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda r, f, e: interpolate_two_layered(r, f[:-1]), "filled has shape"),
        (lambda r, f, e: interpolate_4nn(r, f.astype(np.uint8)), "filled must be a bool"),
        (lambda r, f, e: interpolate_edge_preserving(r, f, e[:, :-1]), "edges has shape"),
        (lambda r, f, e: interpolate_two_layered(r, f, window=6), "window must be an odd"),
        (lambda r, f, e: interpolate_two_layered(r, np.zeros_like(f)), "no True pixel"),
        (lambda r, f, e: interpolate_4nn(r[:, :, None].repeat(2, 2), f), "raw must be"),
        (lambda r, f, e: sobel_edge_value(e), "gray must be"),
    ],
)
def test_bad_input_one_line_value_error(call: object, message: str) -> None:
    raw = np.zeros((10, 12), np.uint8)
    filled = np.ones((10, 12), bool)
    edges = np.zeros((10, 12), np.float32)
    assert callable(call)
    with pytest.raises(ValueError, match=message) as ei:
        call(raw, filled, edges)
    assert "\n" not in str(ei.value)

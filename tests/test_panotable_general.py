"""The generalized pano-mapping table: fit, refusals, files, fast maps (against exact cameras)."""

from __future__ import annotations

import dataclasses
import gzip
import math
import tracemalloc

import numpy as np
import pytest

import omnidev
from omnidev.calibfile import read_kind, write_storage
from omnidev.camera import build_maps, project_maps
from omnidev.errors import CalibrationError
from omnidev.panotable import general
from omnidev.panotable.camfile import PanoTableCamera, load_table, save_table
from omnidev.panotable.general import Terms, fit_general
from omnidev.panotable.table import (
    PanoTable,
    calibrate,
    calibrate_general,
    dissertation_misfit,
)
from omnidev.sim.imperfect import ImperfectCamera, PolyFisheyeCamera, rotation_vector
from omnidev.sim.mirrors import SvpHyperbolicCamera
from omnidev.sim.pano_cases import make_case
from omnidev.views import Panorama, Perspective, Plane, TopView


def landmarks(
    cam,
    n: int,
    seed: int,
    noise: float = 0.0,
    dist=(1.0, 3.0),
    margin_deg=0.5,
    top_deg=90.0,
    bottom_deg=-90.0,
):
    """n landmarks in directions the camera sees, ``margin_deg`` inside both ends of its
    elevations and none outside bottom_deg..top_deg, at random distances; pixels exact +
    noise."""
    rng = np.random.default_rng(seed)
    lo, hi = cam.default_elevation_deg()
    lo, hi = max(lo, bottom_deg - margin_deg), min(hi, top_deg + margin_deg)
    uv, xyz = [], []
    while len(uv) < n:
        th = rng.uniform(0, 2 * math.pi)
        rho = math.radians(rng.uniform(lo + margin_deg, hi - margin_deg))
        d = np.array([math.cos(rho) * math.cos(th), math.cos(rho) * math.sin(th), math.sin(rho)])
        p = d * rng.uniform(*dist)
        q, ok = cam.project(p[None], finite=True)
        if ok[0]:
            uv.append(q[0])
            xyz.append(p)
    return np.array(uv) + rng.normal(0, noise, (n, 2)), np.array(xyz)


def truth_error(cam, mapping) -> tuple[float, float]:
    """RMS and max pixel distance between the fitted mapping and the exact camera, px."""
    lo, hi = cam.default_elevation_deg()
    th, rho = np.meshgrid(
        np.linspace(0, 2 * np.pi, 180), np.radians(np.linspace(lo + 0.5, hi - 0.5, 50))
    )
    d = np.stack([np.cos(rho) * np.cos(th), np.cos(rho) * np.sin(th), np.sin(rho)], -1)
    uv, ok = cam.project(d.reshape(-1, 3), finite=False)
    e = np.hypot(*(mapping.project_world(d.reshape(-1, 3)) - uv)[ok].T)
    return float(np.sqrt(np.mean(e**2))), float(e.max())


def assert_fast_maps_match(cam, views, min_valid: float = 0.0) -> None:
    """The fast maps of ``cam`` for each view equal the point route to 2e-3 px, and at
    least ``min_valid`` of each view is mapped."""
    for view in views:
        fast = build_maps(cam, view)
        slow = project_maps(cam, view)
        np.testing.assert_array_equal(fast.valid, slow.valid)
        assert fast.valid.mean() >= min_valid
        assert np.max(np.abs(fast.map_x - slow.map_x)[fast.valid], initial=0) < 2e-3
        assert np.max(np.abs(fast.map_y - slow.map_y)[fast.valid], initial=0) < 2e-3


FISHEYE = PolyFisheyeCamera(290.0, -0.03, 0.004, (960, 960), (476.3, 482.9), math.radians(96))
TILTED = ImperfectCamera(FISHEYE, rotation_vector(35.0, 7.0))
_BASE = SvpHyperbolicCamera.default(960)
SQUEEZED = ImperfectCamera(
    dataclasses.replace(_BASE, image_size=(1280, 960), center=(641.7, 476.2)),
    np.eye(3),
    aspect=0.75,
    center_px=(641.7, 356.9),
    size=(1280, 720),
)


@pytest.mark.parametrize(
    "cam,what", [(TILTED, "tilt"), (SQUEEZED, "aspect")], ids=["tilt", "aspect"]
)
def test_general_fit_recovers_tilt_and_aspect(cam, what):
    uv, xyz = landmarks(cam, 100, seed=4, noise=0.2)
    start = (cam.center[0] + 3.0, cam.center[1] - 2.0)
    g = fit_general(uv, xyz, start)
    m = g.mapping
    rms, mx = truth_error(cam, m)
    print(
        f"{what}: kept {g.terms.describe()}, held-out {g.heldout_rms_px:.3f} px, "
        f"truth {rms:.3f}/{mx:.3f}"
    )
    assert math.hypot(m.image_center[0] - cam.center[0], m.image_center[1] - cam.center[1]) < 0.3
    if what == "tilt":
        assert g.terms.tilt and abs(m.tilt_deg - 7.0) < 0.1
    else:
        assert g.terms.aspect and abs(m.aspect - 0.75) < 1e-3
    assert g.heldout_rms_px < 0.35  # the landmarks' 0.2 px noise is 0.28 px in 2-D
    assert rms < 0.15 and mx < 0.6
    # the dissertation's table cannot absorb either, and says why
    d = calibrate(uv, xyz, np.zeros(3), cam.center, cam.image_size)
    assert np.sqrt(np.mean(d.reprojection_px**2)) > 5.0
    assert "vary with azimuth" in dissertation_misfit(d, 2.0)


def test_aligned_camera_keeps_the_simple_order():
    """No aspect, tilt or harmonics are bought when the camera is the dissertation's."""
    uv, xyz = landmarks(_BASE, 100, seed=2, noise=0.3)
    g = fit_general(uv, xyz, (_BASE.center[0] - 2, _BASE.center[1] + 2))
    assert not g.terms.tilt and g.terms.harmonics == 0
    assert truth_error(_BASE, g.mapping)[0] < 0.15


def test_hyperbolic_mirror_keeps_the_unified_radial_over_the_polynomials():
    """A hyperbolic mirror's r(rho) is the unified model's, not a quartic: the fit keeps it."""
    cam = dataclasses.replace(_BASE, a=_BASE.a * 1.1, b=_BASE.b * 0.9)
    uv, xyz = landmarks(cam, 300, seed=11, noise=0.1)
    start = (cam.center[0] + 1.5, cam.center[1] - 1.0)
    g = fit_general(uv, xyz, start)
    errs = {}
    for name, terms in (("quartic", Terms()), ("degree 6", Terms(degree=6))):
        errs[name] = truth_error(cam, fit_general(uv, xyz, start, candidates=(terms,)).mapping)
    rms, mx = truth_error(cam, g.mapping)
    print(f"kept {g.terms.describe()}: {rms:.3f} / {mx:.3f} px; {errs}")
    assert g.terms == Terms(unified=True, degree=-1)
    assert rms < 0.5 * errs["quartic"][0] and mx < 0.5 * errs["quartic"][1]
    assert rms < 0.03 and mx < 0.1


def test_a_non_square_mirror_keeps_the_unified_twin_of_its_quartic():
    """A hyperbolic mirror seen with non-square pixels, 100 landmarks at 0.3 px: the
    quartic twin of "center, aspect, tilt" comes first and is within 5 % of the best
    held-out RMS, but the unified twin (three parameters fewer) is no worse there and is
    the mirror's own form: it is kept (measured max 0.13 px off the exact camera
    against 0.72 for the quartic, which the fit kept before)."""
    uv, xyz = landmarks(SQUEEZED, 100, seed=6, noise=0.3)
    start = (SQUEEZED.center[0] + 1.5, SQUEEZED.center[1] - 1.0)
    g = fit_general(uv, xyz, start)
    quartic = Terms(aspect=True, tilt=True)
    rms4, mx4 = truth_error(SQUEEZED, fit_general(uv, xyz, start, candidates=(quartic,)).mapping)
    rms, mx = truth_error(SQUEEZED, g.mapping)
    print(f"kept {g.terms.describe()}: {rms:.3f} / {mx:.3f} px; quartic {rms4:.3f} / {mx4:.3f}")
    assert g.terms == Terms(aspect=True, tilt=True, unified=True, degree=-1)
    assert mx < 0.2 and mx < 0.5 * mx4


def test_few_mirror_landmarks_extrapolate_with_the_unified_radial():
    """32 landmarks over part of the band: the table still holds beyond them.

    The landmarks' elevations stop 6 degrees short of each end of the mirror's
    field (a table's range reaches 30 % of the span past them); a quartic or
    sextic swings there, the two-parameter unified term does not.
    """
    cam = _BASE
    uv, xyz = landmarks(cam, 32, seed=5, noise=0.1, margin_deg=6.0)
    start = (cam.center[0] - 2.0, cam.center[1] + 1.0)
    g = fit_general(uv, xyz, start)
    rms, mx = truth_error(cam, g.mapping)  # over the whole field, both ends included
    rms4, mx4 = truth_error(cam, fit_general(uv, xyz, start, candidates=(Terms(),)).mapping)
    print(f"kept {g.terms.describe()}: {rms:.3f} / {mx:.3f} px; quartic {rms4:.3f} / {mx4:.3f}")
    assert g.terms.unified
    assert mx < 0.25 and mx < 0.5 * mx4


def test_few_fisheye_landmarks_extrapolate_to_the_zenith_through_the_pole():
    """32 landmarks stop 20 degrees short of a tilted fisheye's zenith: the radial
    polynomial through r = 0 at the pole holds up there, a free quartic swings."""
    uv, xyz = landmarks(TILTED, 32, seed=2, noise=0.1, top_deg=70.0)
    start = (TILTED.center[0] + 2.0, TILTED.center[1] - 1.0)
    g = fit_general(uv, xyz, start)
    rms, mx = truth_error(TILTED, g.mapping)  # up to the zenith
    free = fit_general(uv, xyz, start, candidates=general.ORDERS)
    rms_f, mx_f = truth_error(TILTED, free.mapping)
    print(f"kept {g.terms.describe()}: {rms:.3f} / {mx:.3f} px; free {rms_f:.3f} / {mx_f:.3f}")
    assert g.terms.polar
    assert abs(g.mapping.radial(np.array([math.pi / 2]))[0]) < 1e-6
    assert mx < 0.3 and mx < 0.5 * mx_f


class EquisolidFisheye(PolyFisheyeCamera):
    """A fisheye looking up with r = 2 f sin(a / 2): odd in the angle a from its axis, but
    no polynomial (the renderers' fisheyes are Kannala-Brandt polynomials)."""

    def radius(self, a):
        return np.asarray(2 * self.f * np.sin(np.asarray(a, np.float64) / 2), np.float64)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_few_equisolid_landmarks_keep_an_odd_radial_to_the_zenith(seed):
    """32 landmarks 20 degrees short of a tilted equisolid fisheye's zenith: the odd
    powers of the angle from the pole are kept (three parameters) and hold to the zenith."""
    base = EquisolidFisheye(300.0, 0.0, 0.0, (960, 960), (476.3, 482.9), math.radians(95))
    cam = ImperfectCamera(base, rotation_vector(35.0, 7.0))
    uv, xyz = landmarks(cam, 32, seed=seed, noise=0.1, top_deg=70.0)
    g = fit_general(uv, xyz, (cam.center[0] + 2.0, cam.center[1] - 1.0))
    rms, mx = truth_error(cam, g.mapping)
    print(f"kept {g.terms.describe()}: {rms:.3f} / {mx:.3f} px")
    assert g.terms == Terms(aspect=True, tilt=True, polar=True, odd=True, degree=5)
    assert abs(g.mapping.radial(np.array([math.pi / 2]))[0]) < 1e-6
    assert rms < 0.06 and mx < 0.2


def _evaluate(kind: str, seed: int, n: int = 32):
    from omnidev.panotable.evaluate import evaluate_case

    case = make_case(kind, seed, size=640, n_landmarks=300)  # type: ignore[arg-type]
    return evaluate_case(case, n_landmarks=n, seed=seed, noise_px=0.1)


@pytest.mark.parametrize(
    "kind,seed,kept",
    [
        # a tilted fisheye: a polynomial through the pole extrapolated 3.41 dB below
        ("fisheye-tilt", 1908, "center, aspect, tilt, radial odd degree 5 through the pole"),
        # a misaligned mirror: the quartic through the pole, 1 % ahead of its unified twin
        # on the held-out landmarks, 3.85 dB below
        ("mirror-misaligned", 1808, "center, aspect, tilt, keystone, unified radial"),
        # an aligned mirror: the quartic, 5.2 % ahead of the unified (within one standard
        # error of 32 landmarks), 2.09 dB below
        ("svp-aligned", 2002, "center, unified radial"),
    ],
)
def test_few_landmarks_keep_the_radial_form_that_extrapolates(kind, seed, kept):
    """32 landmarks at 0.1 px (tuning seeds of docs/results.md): the order kept, and every
    view within 2 dB of the exact maps (the issue's bound for 32 landmarks)."""
    r = _evaluate(kind, seed)
    gap = r.gap("general")
    print(f"{kind} {seed}: kept {r.fit['general']['terms']}; dB below the ceiling {gap}")
    assert r.fit["general"]["terms"] == kept
    assert max(gap.values()) < 1.5


def test_odd_radial_table_round_trips_and_its_fast_maps_match(tmp_path):
    """A tilted fisheye's table with the odd radial: its file rebuilds the same mapping and
    the fast maps equal the point route."""
    uv, xyz = landmarks(TILTED, 100, seed=3, noise=0.1)
    cal = calibrate_general(uv, xyz, np.zeros(3), TILTED.center, TILTED.image_size)
    assert cal.fit.terms.odd
    p = tmp_path / "fisheye.yml"
    save_table(p, cal)
    back = load_table(p)
    np.testing.assert_allclose(back.mapping.coeffs, cal.fit.mapping.coeffs, rtol=1e-9, atol=1e-9)
    assert truth_error(TILTED, back.mapping)[1] < 0.2
    views = (Panorama(720, 180), Perspective(160, 120, 90, 40, 60))
    assert_fast_maps_match(PanoTableCamera(back, "analytic"), views, min_valid=0.5)


def test_table_reaches_below_high_landmarks_inside_the_image():
    """Landmarks 30-83 degrees up a tilted fisheye: the table reaches on below them while
    the radius stays inside the image's inscribed circle, so a panorama down to 5 degrees
    is covered (the 30 % range of the landmarks' span alone left rows black)."""
    uv, xyz = landmarks(TILTED, 32, seed=3, noise=0.1, bottom_deg=30.0)
    cal = calibrate_general(uv, xyz, np.zeros(3), TILTED.center, TILTED.image_size)
    m = cal.fit.mapping
    _, rho = general.table_angles(xyz, m.tilt)
    w, h = TILTED.image_size
    u0, v0 = m.image_center
    r_in = min(u0, w - 1 - u0, v0 / m.aspect, (h - 1 - v0) / m.aspect)
    lo = cal.table.rho_range[0]
    span = float(np.ptp(rho))
    view = Panorama(720, 180, elevation_deg=(5.0, 60.0))
    t = cal.table
    narrow = PanoTable.from_mapping(
        m, t.image_size, (rho.min() - 0.3 * span, t.rho_range[1]), t.M, t.N, t.cutoff_radius
    )
    got = build_maps(PanoTableCamera(cal.table), view).valid.mean()
    before = build_maps(PanoTableCamera(narrow), view).valid.mean()
    print(
        f"range from {math.degrees(lo):.1f} deg (landmarks from {math.degrees(rho.min()):.1f}, "
        f"30 %: {math.degrees(rho.min() - 0.3 * span):.1f}); covered {got:.4f} (30 %: {before:.4f})"
    )
    assert lo < rho.min() - 0.4 * span
    assert m.radial(np.array([lo]))[0] <= r_in + 1e-6
    assert got > 0.995 and before < 0.95


def test_a_disc_measured_about_another_center_bounds_the_range_at_its_far_edge():
    """A disc (rim, image circle) detected about a point 6 px from the fitted center (a
    misaligned lens): the table reaches the disc's far edge from the fitted center, not its
    radius about it (which cut one side of a misaligned mirror's panorama: worst view
    median 2.54 dB against 0.48 with the far edge, seeds 900-904, docs/results.md)."""
    uv, xyz = landmarks(TILTED, 60, seed=4, noise=0.1, bottom_deg=20.0)
    c_disc = (TILTED.center[0] + 6.0, TILTED.center[1])
    R = 400.0
    cal = calibrate_general(uv, xyz, np.zeros(3), c_disc, TILTED.image_size, disc_radius=R)
    m = cal.fit.mapping
    shift = math.hypot(m.image_center[0] - c_disc[0], m.image_center[1] - c_disc[1])
    r_end = float(m.radial(np.array([cal.table.rho_range[0]]))[0])
    assert shift > 5.0
    assert R + 0.9 * shift < r_end <= R + shift + 1e-6


def test_a_far_pole_leaves_the_radial_polynomial_free():
    """A mirror's nadir farther below the landmarks than half their span: no order through
    it (an SVP mirror's r(rho) near its nadir is left to the unified term)."""
    uv, xyz = landmarks(_BASE, 100, seed=3, noise=0.1)
    lo = np.degrees(np.arcsin(xyz[:, 2] / np.linalg.norm(xyz, axis=1))).min()
    hi = np.degrees(np.arcsin(xyz[:, 2] / np.linalg.norm(xyz, axis=1))).max()
    g = fit_general(uv, xyz, _BASE.center)
    assert (lo + 90) > general.POLAR_REACH * (hi - lo)
    assert not any(s.terms.polar for s in g.scores)


def test_few_landmarks_do_not_overfit():
    """32 landmarks: the order stays small, the held-out residual honest."""
    uv, xyz = landmarks(TILTED, 32, seed=9, noise=0.3)
    g = fit_general(uv, xyz, (TILTED.center[0] + 2, TILTED.center[1]))
    assert g.terms.n_params() <= 16
    rms, _ = truth_error(TILTED, g.mapping)
    assert rms < 0.35
    assert g.heldout_rms_px < 0.6


def test_refusal_names_the_outlier_line():
    uv, xyz = landmarks(TILTED, 80, seed=1, noise=0.2)
    uv[17] += (40.0, -25.0)
    rows = list(range(2, 82))
    with pytest.raises(CalibrationError, match="line 19"):
        calibrate_general(
            uv, xyz, np.zeros(3), TILTED.center, TILTED.image_size, max_heldout_px=2.0, rows=rows
        )


def test_a_wild_landmark_does_not_overflow_the_fit():
    # found by the fuzz sweep: u = 1.7e7 px (a lost decimal point) drove the fitted log
    # aspect so far that exp() overflowed (a traceback); the fit ends, the residual says why
    uv, xyz = landmarks(TILTED, 48, seed=5, noise=0.2)
    uv[0, 0] = 1.7e7
    g = fit_general(uv, xyz, TILTED.center)
    assert g.heldout_rms_px > 1e3


def test_cli_refuses_a_landmark_outside_the_image(tmp_path, capsys):
    from omnidev.cli.main import main

    uv, xyz = landmarks(TILTED, 40, seed=5, noise=0.2)
    uv[3, 0] = 17053611.0
    csv = tmp_path / "lm.csv"
    rows = [",".join(f"{c:.6f}" for c in (*p, *q)) for p, q in zip(uv, xyz, strict=True)]
    csv.write_text("u,v,X,Y,Z\n" + "\n".join(rows) + "\n")
    w, h = TILTED.image_size
    rc = main(["calibrate", "pano-table", str(csv), "--model", "general", "--mirror-center",
               "0,0,0", "--image-center", "480,480", "--image-size", f"{w}x{h}",
               "-o", str(tmp_path / "c.yml")])  # fmt: skip
    assert rc == 2
    err = capsys.readouterr().err
    assert f"{csv} line 5: landmark (u, v) = (1.70536e+07, " in err
    assert f"lies outside the {w}x{h} image" in err


def test_cli_general_table_of_a_mirror_reports_its_orders(tmp_path, capsys):
    from omnidev.cli.main import main

    uv, xyz = landmarks(_BASE, 60, seed=8, noise=0.1)
    csv = tmp_path / "lm.csv"
    rows = [",".join(f"{c:.6f}" for c in (*p, *q)) for p, q in zip(uv, xyz, strict=True)]
    csv.write_text("u,v,X,Y,Z\n" + "\n".join(rows) + "\n")
    w, h = _BASE.image_size
    out = tmp_path / "c.yml"
    rc = main(["calibrate", "pano-table", str(csv), "--model", "general", "--mirror-center",
               "0,0,0", "--image-center", f"{_BASE.center[0] + 2},{_BASE.center[1] - 1}",
               "--image-size", f"{w}x{h}", "-o", str(out)])  # fmt: skip
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "held-out RMS(px)" in text and "kept: center, unified radial" in text
    assert "radial: " in text and "cos(rho) / (" in text
    t = load_table(out)
    assert t.radial_base[0] != 0.0
    assert truth_error(_BASE, t.mapping)[1] < 0.15


def test_refusal_names_a_wrong_mirror_center():
    uv, xyz = landmarks(TILTED, 80, seed=3, noise=0.2, dist=(0.4, 4.0))
    with pytest.raises(CalibrationError, match=r"moving the mirror center by .*--mirror-center"):
        calibrate_general(
            uv,
            xyz,
            np.array([0.08, -0.06, 0.05]),
            TILTED.center,
            TILTED.image_size,
            max_heldout_px=1.0,
        )


def test_too_few_landmarks_is_a_clear_error():
    uv, xyz = landmarks(TILTED, 6, seed=3)
    with pytest.raises(CalibrationError, match="too few for the generalized table"):
        fit_general(uv, xyz, TILTED.center)


@pytest.fixture(scope="module")
def general_table():
    uv, xyz = landmarks(TILTED, 120, seed=5, noise=0.1)
    return calibrate_general(uv, xyz, np.zeros(3), TILTED.center, TILTED.image_size)


def test_format_2_file_is_small_and_rebuilds_the_table(tmp_path, general_table):
    p = tmp_path / "cam.yml.gz"
    save_table(p, general_table)
    assert p.stat().st_size < 4000  # the definition, not 10^6 entries
    assert read_kind(p) == "pano-table"
    t = load_table(p)
    assert t.method == "general" and t.tilt == general_table.table.tilt
    np.testing.assert_allclose(t.table, general_table.table.table, atol=1e-3)
    cam = omnidev.load_camera(p)
    assert isinstance(cam, PanoTableCamera)
    d = np.random.default_rng(0).normal(size=(500, 3))
    d[:, 2] = np.abs(d[:, 2])
    a, ok_a = cam.project(d, finite=False)
    b, ok_b = PanoTableCamera(general_table.table).project(d, finite=False)
    np.testing.assert_array_equal(ok_a, ok_b)
    assert np.max(np.abs(a - b)[ok_a]) < 1e-3


def test_format_1_files_keep_loading_with_their_table(tmp_path):
    uv, xyz = landmarks(_BASE, 30, seed=1)
    cal = calibrate(uv, xyz, np.zeros(3), _BASE.center, _BASE.image_size, table_size=(720, 120))
    t = cal.table
    stored = t.table.copy()
    stored[5, 7] += (3.0, -2.0)  # a table not filled from its coefficients is used as stored
    p = tmp_path / "old.yml.gz"
    write_storage(
        p,
        "pano-table",
        1,
        {
            "image_width": t.image_size[0],
            "image_height": t.image_size[1],
            "image_center": np.array(t.image_center).reshape(1, 2),
            "radial_coeffs": t.coeffs.reshape(1, -1),
            "rho_start_deg": math.degrees(t.rho_range[0]),
            "rho_end_deg": math.degrees(t.rho_range[1]),
            "M": t.M,
            "N": t.N,
            "azimuth_sign": t.azimuth_sign,
            "azimuth_offset_deg": math.degrees(t.azimuth_offset),
            "cutoff_radius": 0.0,
            "table": stored,
        },
    )
    with gzip.open(p, "rb") as fh:
        assert b"kind: pano-table" in fh.read(200)
    back = load_table(p)
    np.testing.assert_allclose(back.table, stored, atol=1e-4)
    p3 = tmp_path / "future.yml"
    write_storage(p3, "pano-table", 3, {"M": 1})
    with pytest.raises(CalibrationError, match="version 3; this omnidev reads versions 1, 2"):
        load_table(p3)


@pytest.mark.parametrize("lookup", ["bilinear", "nearest", "analytic"])
@pytest.mark.parametrize("tilted", [False, True], ids=["level", "tilted"])
def test_fast_maps_equal_the_point_route(lookup, tilted, general_table):
    table = (
        general_table.table if tilted else dataclasses.replace(general_table.table, tilt=(0.0, 0.0))
    )
    views = (Panorama(720, 180), Perspective(160, 120, 90, 40, 30), TopView(80, 80, 3, 3, 1.5))
    assert_fast_maps_match(PanoTableCamera(table, lookup), views)


def test_unified_radial_table_round_trips_and_its_fast_maps_match(tmp_path):
    """A mirror's table with the unified radial term: its file keeps the term, maps agree."""
    uv, xyz = landmarks(_BASE, 100, seed=6, noise=0.1)
    cal = calibrate_general(uv, xyz, np.zeros(3), _BASE.center, _BASE.image_size)
    t = cal.table
    assert cal.fit.terms.unified and t.radial_base[0] != 0.0
    p = tmp_path / "mirror.yml"
    save_table(p, cal)
    back = load_table(p)
    assert back.radial_base == t.radial_base and back.method == "general"
    np.testing.assert_allclose(back.table, t.table, atol=1e-3)
    assert truth_error(_BASE, back.mapping)[1] < 0.1
    views = (Panorama(720, 180), Perspective(160, 120, 90, 40, -30))
    for lookup in ("bilinear", "analytic"):
        assert_fast_maps_match(PanoTableCamera(back, lookup), views, min_valid=0.5)


def test_keystone_unified_table_of_a_misaligned_mirror_round_trips(tmp_path):
    """A mirror whose lens sits off its focus (omnidev.sim.pano_cases, tuning seed 901),
    32 landmarks at 0.1 px: the fit keeps "center, aspect, tilt, keystone, unified
    radial"; its file keeps keystone and the unified term, and the fast maps equal the
    point route."""
    case = make_case("mirror-misaligned", 901, size=640, n_landmarks=300)
    rng = np.random.default_rng([901, 32, 7])  # as omnidev.panotable.evaluate picks them
    pick = rng.choice(len(case.uv), 32, replace=False)
    uv = case.uv[pick] + rng.normal(0.0, 0.1, (32, 2))
    xyz = case.dirs[pick] * case.distance[pick, None]
    cal = calibrate_general(uv, xyz, np.zeros(3), case.image_center, case.image_size)
    assert cal.fit.terms == Terms(aspect=True, tilt=True, keystone=True, unified=True, degree=-1)
    assert cal.fit.mapping.keystone != (0.0, 0.0) and cal.table.radial_base[0] != 0.0
    p = tmp_path / "misaligned.yml"
    save_table(p, cal)
    back = load_table(p)
    np.testing.assert_allclose(back.table, cal.table.table, atol=1e-3)
    cam = PanoTableCamera(back, "analytic")
    view = Panorama(720, 180)
    fast, slow = build_maps(cam, view), project_maps(cam, view)
    np.testing.assert_array_equal(fast.valid, slow.valid)
    assert fast.valid.mean() > 0.5
    assert np.max(np.abs(fast.map_x - slow.map_x)[fast.valid], initial=0) < 2e-3
    assert np.max(np.abs(fast.map_y - slow.map_y)[fast.valid], initial=0) < 2e-3


VIEWS = {  # what the upward-looking fisheye of general_table sees
    "panorama": Panorama(2048, 512),
    "perspective": Perspective(1280, 720, 90.0, 30.0, 40.0),
    "top": TopView(800, 800, 4.0, 4.0, 1.5),
    "plane": Plane(800, 600, (1.0, 0.5, 1.2), (1.0, 0.2, -0.6), 1.2, 0.9, 10.0),
}


@pytest.mark.parametrize("view_name", list(VIEWS))
@pytest.mark.parametrize("tilted", [False, True], ids=["level", "tilted"])
def test_maps_take_at_most_32_bytes_per_pixel_and_no_table(view_name, tilted, general_table):
    tilt = general_table.table.tilt if tilted else (0.0, 0.0)
    table = dataclasses.replace(general_table.table, tilt=tilt, _table=None)
    cam = PanoTableCamera(table)  # the default lookup of a table defined by its mapping
    assert cam.resolved_lookup == "analytic"
    view = VIEWS[view_name]
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    maps = build_maps(cam, view)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    per_px = peak / (view.width * view.height)
    kind = "tilted" if tilted else "level"
    print(f"{kind} {view_name} maps: {per_px:.1f} bytes per output pixel")
    assert table._table is None  # no table entries were built
    assert maps.valid.mean() > 0.8
    # 9 are the maps themselves, the rest one block's temporaries (a fixed few MB, so
    # smaller views pay more per pixel); measured 10.6-20.2
    assert per_px <= 32.0
    ref = build_maps(PanoTableCamera(table, "bilinear"), view)  # through the table's entries
    np.testing.assert_array_equal(maps.valid, ref.valid)
    d = np.hypot(maps.map_x - ref.map_x, maps.map_y - ref.map_y)[maps.valid]
    assert d.max() < 2e-3  # measured 3e-4 .. 1.3e-3 px


def test_load_camera_reads_the_definition_only(general_table, tmp_path):
    p = tmp_path / "cam.yml.gz"
    save_table(p, general_table)
    cam = omnidev.load_camera(p)
    assert cam.table._table is None and not cam.table.stored_entries
    assert cam.resolved_lookup == "analytic"
    assert PanoTableCamera(cam.table, "nearest").resolved_lookup == "nearest"
    save_table(tmp_path / "stored.yml.gz", general_table, store_table=True)
    stored = omnidev.load_camera(tmp_path / "stored.yml.gz")
    assert stored.table.stored_entries and stored.resolved_lookup == "bilinear"

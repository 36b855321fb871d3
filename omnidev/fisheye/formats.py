"""Other tools' fisheye and omni-camera calibrations in and out.

Read (:func:`import_calibration`, format picked by :func:`detect_format` or given):

=========== ================================================== ===============================
format      file                                               lens model
=========== ================================================== ===============================
ocamcalib   OCamCalib ``calib_results.txt`` (export_data.m):   :class:`Scaramuzza`
            ss, invpol, centre row/column (0-based), c d e,
            height width
pyocamcalib py-OCamCalib calibration JSON: ``taylor_coefficient``, :class:`Scaramuzza` (converted
            ``distortion_center`` (column, row, 0-based),      exactly, see
            ``stretch_matrix``, ``inverse_poly`` (optional)    :func:`parse_pyocamcalib`)
kalibr      Kalibr camchain YAML, one ``camN`` per camera:     pinhole-equidistant
            ``camera_model``, ``intrinsics``,                  -> :class:`KannalaBrandt`;
            ``distortion_model``, ``distortion_coeffs``,        omni(-radtan), pinhole(-radtan)
            ``resolution``; also a YAML of named parameters    -> :class:`Unified`; ds -> DS;
            per camera (``camN: {fx, fy, cx, cy, k1..k4}`` +   eucm -> EUCM; pinhole-fov
                                                               -> :class:`FieldOfView`
            ``width``, ``height``, as TUM-VI publishes it)
basalt      basalt ``calibration.json`` (cereal ``value0``):   kb4, ds, eucm, ucm, pinhole, fov
            ``intrinsics[N].camera_type`` + named params,
            ``resolution[N]``
cim         camera-intrinsic-model-rs JSON ``{"EUCM": {...}}`` :class:`EUCM`, :class:`FieldOfView`
            or ``{"FovCamera": {...}}``
opencv      cv2.FileStorage (YAML/XML/JSON): ``K`` or          with ``xi``: :class:`Unified`
            ``camera_matrix`` + ``D`` or                       (cv2.omnidir); 4 coefficients:
            ``distortion_coefficients`` [+ ``xi``], optional   :class:`KannalaBrandt`
            ``image_width``/``image_height``; also omnidev's   (cv2.fisheye); omnidev's own:
            own ``kind: fisheye`` files and ROS camera_info    its model
=========== ================================================== ===============================

Parameter orders (Kalibr ``intrinsics``): pinhole ``[fu fv pu pv]``, omni
``[xi fu fv pu pv]``, ds ``[xi alpha fu fv pu pv]``, eucm ``[alpha beta fu fv pu pv]``;
``distortion_coeffs``: equidistant ``[k1 k2 k3 k4]``, radtan ``[k1 k2 r1 r2]`` (= OpenCV
``k1 k2 p1 p2``), fov ``[w]``. basalt names every parameter. A UCM (basalt ``ucm``, parameter
``alpha``) is the unified model with ``xi = alpha / (1 - alpha)`` and focal lengths
divided by ``1 - alpha``; a pinhole with radial-tangential distortion is the unified
model with ``xi = 0``.

Written: :func:`opencv_nodes` / :func:`write_opencv` (``K``, ``D``, ``xi`` as cv2.fisheye
and cv2.omnidir users read them, for KB4 and unified lenses), and text in the OCamCalib,
Kalibr and basalt formats (:func:`ocamcalib_text`, :func:`kalibr_text`,
:func:`basalt_text`), so that every format round-trips (py-OCamCalib's and
camera-intrinsic-model-rs's are read only).

The ``parse_*`` functions are pure (text or dict in, :class:`Imported` out); ``source``
only names the file in errors. A bad file raises one-line
:class:`~omnidev.errors.CalibrationError` naming the file and the key.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.atomic import atomic_path
from omnidev.errors import CalibrationError
from omnidev.fisheye import miniyaml
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

FloatArray = NDArray[np.float64]

Format = Literal["ocamcalib", "pyocamcalib", "kalibr", "basalt", "cim", "opencv"]
FORMATS: tuple[Format, ...] = ("ocamcalib", "pyocamcalib", "kalibr", "basalt", "cim", "opencv")


@dataclass(frozen=True)
class Imported:
    """One camera's lens read from another tool's file.

    ``image_size`` is (width, height) px, None when the file does not say;
    ``camera`` names the camera chosen in a multi-camera file and ``cameras`` lists
    all of them; ``mount`` (3x3) and ``max_angle_deg`` come only from omnidev's own
    files (see :mod:`omnidev.fisheye.camera`).
    """

    lens: LensModel
    image_size: tuple[int, int] | None
    format: Format
    camera: str | None = None
    cameras: tuple[str, ...] = ()
    mount: FloatArray | None = None
    max_angle_deg: float | None = None


# ---------------------------------------------------------------- helpers


def _fail(source: str, what: str) -> CalibrationError:
    return CalibrationError(f"{source}: {what}")


@contextmanager
def _model_errors(source: str) -> Iterator[None]:
    """A model's own parameter check (ValueError) as a CalibrationError naming the file."""
    try:
        yield
    except ValueError as exc:
        raise _fail(source, str(exc)) from None


MAX_PARAMETER = 1e9
"""Largest magnitude of any imported number (focal lengths in px and image sizes are far below)."""


def _number(value: Any, source: str, key: str) -> float:
    """``value`` as a finite float; the error names ``key``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        if isinstance(value, np.ndarray) and value.size == 1:
            value = value.reshape(-1)[0]
        else:
            raise _fail(source, f"key {key!r} is not a number ({value!r:.40})")
    try:
        out = float(value)
    except OverflowError:  # an integer beyond float range
        out = math.inf
    if not math.isfinite(out):
        raise _fail(source, f"key {key!r} is not finite")
    if abs(out) > MAX_PARAMETER:
        raise _fail(source, f"key {key!r} is {out:g}; no calibration parameter is that large")
    return out


def _get(doc: Mapping[str, Any], key: str, source: str, prefix: str = "") -> Any:
    if not isinstance(doc, Mapping) or key not in doc or doc[key] is None:
        raise _fail(source, f"missing key {prefix + key!r}")
    return doc[key]


def _num(doc: Mapping[str, Any], key: str, source: str, prefix: str = "") -> float:
    return _number(_get(doc, key, source, prefix), source, prefix + key)


def _numbers(value: Any, source: str, key: str, count: int | None = None) -> list[float]:
    """A list of finite floats (``count`` of them if given); errors name ``key``."""
    if isinstance(value, np.ndarray):
        value = value.reshape(-1).tolist()
    if not isinstance(value, list | tuple):
        raise _fail(source, f"key {key!r} is not a list of numbers")
    out = [_number(v, source, key) for v in value]
    if count is not None and len(out) != count:
        raise _fail(source, f"key {key!r} has {len(out)} numbers, expected {count}")
    return out


def _size(w: Any, h: Any, source: str, key: str) -> tuple[int, int]:
    wf, hf = _number(w, source, key), _number(h, source, key)
    if wf != int(wf) or hf != int(hf) or not (1 <= wf <= 65500 and 1 <= hf <= 65500):
        raise _fail(source, f"key {key!r}: image size {wf:g}x{hf:g} is not positive whole pixels")
    return int(wf), int(hf)


def _pick(names: Sequence[str], camera: str | None, source: str, what: str) -> str:
    """The camera named ``camera`` (``camN`` or ``N``), else the first; errors list them."""
    if not names:
        raise _fail(source, f"no {what} in the file")
    if camera is None:
        return names[0]
    wanted = [camera]
    if camera.isdigit():
        wanted.append(f"cam{camera}")
    elif camera.startswith("cam") and camera[3:].isdigit():
        wanted.append(camera[3:])
    for name in names:
        if name in wanted:
            return name
    raise _fail(source, f"no camera {camera!r} (the file has {', '.join(names)})")


def _ucm(fx: float, fy: float, cx: float, cy: float, alpha: float, source: str) -> Unified:
    """The UCM of basalt/Kalibr (``alpha``) as the unified model (``xi``)."""
    if not 0.0 <= alpha < 1.0:
        raise _fail(source, f"ucm alpha {alpha:g} outside [0, 1)")
    s = 1.0 - alpha
    return Unified(fx=fx / s, fy=fy / s, cx=cx, cy=cy, xi=alpha / s)


# ---------------------------------------------------------------- OCamCalib


def parse_ocamcalib(text: str, source: str) -> Imported:
    """OCamCalib ``calib_results.txt`` (export_data.m) -> :class:`Scaramuzza`.

    The data lines, in order after the ``#`` comments: ``N a0 .. a(N-1)`` (ss, cam2world),
    ``M p0 .. p(M-1)`` (invpol, world2cam), ``xc yc`` (centre ROW and COLUMN, 0-based),
    ``c d e`` (affine), ``height width``. Kept in OCamCalib's own terms;
    :class:`Scaramuzza` maps its frame to the optical frame.
    """
    rows: list[list[float]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        t = line.strip()
        if not t or t.startswith("#"):
            continue
        try:
            rows.append([float(v) for v in t.split()])
        except ValueError:
            raise _fail(source, f"line {n}: {t[:40]!r} is not numbers") from None
    names = ("ss (polynomial)", "invpol", "center row/column", "affine c d e", "height width")
    if len(rows) < len(names):
        raise _fail(source, f"missing {names[len(rows)]} (OCamCalib calib_results.txt has 5 rows)")
    if not all(math.isfinite(v) for r in rows for v in r):
        raise _fail(source, "non-finite number")

    def poly(row: list[float], key: str, least: int) -> tuple[float, ...]:
        if not row or row[0] != int(row[0]) or int(row[0]) != len(row) - 1 or row[0] < least:
            raise _fail(source, f"{key}: the first number must count the coefficients after it")
        return tuple(row[1:])

    ss = poly(rows[0], names[0], 2)
    invpol = poly(rows[1], names[1], 0)
    for i, want in ((2, 2), (3, 3), (4, 2)):
        if len(rows[i]) != want:
            raise _fail(source, f"{names[i]}: {len(rows[i])} numbers, expected {want}")
    h, w = rows[4]
    with _model_errors(source):
        lens = Scaramuzza(
            ss=ss,
            xc=rows[2][0],
            yc=rows[2][1],
            c=rows[3][0],
            d=rows[3][1],
            e=rows[3][2],
            invpol=invpol or None,
        )
    return Imported(lens, _size(w, h, source, names[4]), "ocamcalib")


def ocamcalib_text(lens: Scaramuzza, image_size: tuple[int, int]) -> str:
    """``lens`` as OCamCalib's ``calib_results.txt`` (numbers written exactly)."""

    def poly(p: Sequence[float]) -> str:
        return f"{len(p)} " + " ".join(repr(float(v)) for v in p)

    w, h = image_size
    inv = lens.invpol if lens.invpol is not None else ()
    return (
        "#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). "
        "These are used by cam2world\n\n"
        f"{poly(lens.ss)}\n\n"
        "#polynomial coefficients for the inverse mapping function (ocam_model.invpol in "
        "MATLAB). These are used by world2cam\n\n"
        f"{poly(inv) if inv else '0'}\n\n"
        '#center: "row" and "column", starting from 0 (C convention)\n\n'
        f"{lens.xc!r} {lens.yc!r}\n\n"
        '#affine parameters "c", "d", "e"\n\n'
        f"{lens.c!r} {lens.d!r} {lens.e!r}\n\n"
        '#image size: "height" and "width"\n\n'
        f"{h} {w}\n"
    )


# ---------------------------------------------------------------- py-OCamCalib

PYOCAMCALIB_KEYS = ("taylor_coefficient", "distortion_center", "stretch_matrix")


def parse_pyocamcalib(doc: Any, source: str) -> Imported:
    """py-OCamCalib's calibration JSON (jakarto3d/py-OCamCalib) -> :class:`Scaramuzza`.

    py-OCamCalib's frame is the optical frame (x right, y down, z forward): sensor
    point (x_s, y_s) has the ray (x_s, y_s, P(rho)), P = ``taylor_coefficient``
    (ascending, a0 > 0: OCamCalib's ss with the sign flipped), and lies at pixel
    (column, row) = S (x_s, y_s) + ``distortion_center`` (column, row; 0-based, as
    OpenCV's corners), S = ``stretch_matrix`` [[c', d'], [e', 1]]. Its ``world2cam``
    (the projection its bundle adjustment fits and its RMS is measured with)
    applies S row by row, reusing the updated column in the row:
    row = e' (c' x_s + d' y_s) + y_s, i.e. S_eff = [[c', d'], [e' c', 1 + e' d']]; that
    is the matrix used here (it differs from S by < 1e-3 px on a 1000 px image).
    ``inverse_poly`` is rho(theta), theta = angle from the axis, DEScending powers.

    In OCamCalib's terms (x along rows): a = y_s, b = x_s, [row - xc, col - yc] =
    [[1 + e' d', e' c'], [d', c']] (a, b). OCamCalib's affine has 1 in the corner, so
    the sensor coordinates are rescaled by c': ss_i = -P_i / c'^(i - 1),
    c = (1 + e' d') / c', d = e', e = d' / c', invpol(t) = c' inverse_poly(t + pi / 2),
    an exact reparametrization (same rays for the same pixels). No image size is stored.
    """
    if not isinstance(doc, Mapping):
        raise _fail(source, "not a py-OCamCalib calibration (expected taylor_coefficient)")
    p = _numbers(_get(doc, "taylor_coefficient", source), source, "taylor_coefficient")
    if len(p) < 2 or not p[0] > 0:
        raise _fail(source, "key 'taylor_coefficient' needs >= 2 numbers with the first > 0")
    col0, row0 = _numbers(_get(doc, "distortion_center", source), source, "distortion_center", 2)
    sm = _get(doc, "stretch_matrix", source)
    rows = sm if isinstance(sm, list) and len(sm) == 2 else None
    if rows is None:
        raise _fail(source, "key 'stretch_matrix' is not a 2x2 matrix")
    (c1, d1), (e1, one) = (_numbers(r, source, "stretch_matrix", 2) for r in rows)
    if one != 1.0 or not c1 > 0:
        raise _fail(source, "key 'stretch_matrix' must be [[c, d], [e, 1]] with c > 0")
    lam = 1.0 / c1
    ss = tuple(-v * lam ** (i - 1) for i, v in enumerate(p))
    invpol = None
    if doc.get("inverse_poly") is not None:
        q = _numbers(doc["inverse_poly"], source, "inverse_poly")
        if q:
            shifted = np.polynomial.Polynomial(q[::-1])(np.polynomial.Polynomial([math.pi / 2, 1]))
            invpol = tuple(float(v) * c1 for v in shifted.coef)
    with _model_errors(source):
        lens = Scaramuzza(
            ss=ss,
            xc=row0,
            yc=col0,
            c=(1.0 + e1 * d1) * lam,
            d=e1,
            e=d1 * lam,
            invpol=invpol,
        )
    return Imported(lens, None, "pyocamcalib")


# ---------------------------------------------------------------- Kalibr

_KALIBR_MODELS = ("pinhole", "omni", "ds", "eucm")
_KALIBR_DISTORTIONS = ("none", "equidistant", "radtan", "fov")


def _kalibr_lens(cam: Mapping[str, Any], source: str, p: str) -> LensModel:
    model = _get(cam, "camera_model", source, p)
    dist = cam.get("distortion_model") or "none"
    if model not in _KALIBR_MODELS:
        raise _fail(
            source,
            f"{p}camera_model {model!r} is not read (known: {', '.join(_KALIBR_MODELS)})",
        )
    if dist not in _KALIBR_DISTORTIONS:
        raise _fail(
            source,
            f"{p}distortion_model {dist!r} is not read (known: {', '.join(_KALIBR_DISTORTIONS)})",
        )
    n_intr = {"pinhole": 4, "omni": 5, "ds": 6, "eucm": 6}[model]
    intr = _numbers(_get(cam, "intrinsics", source, p), source, p + "intrinsics", n_intr)
    n_dist = {"none": 0, "equidistant": 4, "radtan": 4, "fov": 1}[dist]
    coeffs = cam.get("distortion_coeffs")
    dc = [] if coeffs in (None, []) and n_dist == 0 else coeffs
    d = _numbers(dc, source, p + "distortion_coeffs", n_dist)
    if model in ("ds", "eucm") and dist != "none":
        raise _fail(source, f"{p}camera_model {model} with distortion {dist!r} is not read")
    if dist == "fov":
        if model != "pinhole":
            raise _fail(source, f"{p}camera_model {model} with distortion 'fov' is not read")
        fx, fy, cx, cy = intr
        return FieldOfView(fx=fx, fy=fy, cx=cx, cy=cy, w=d[0])
    if model == "pinhole" and dist == "equidistant":
        fx, fy, cx, cy = intr
        return KannalaBrandt(fx=fx, fy=fy, cx=cx, cy=cy, k=(d[0], d[1], d[2], d[3]))
    if model in ("pinhole", "omni"):
        xi, (fx, fy, cx, cy) = (0.0, intr) if model == "pinhole" else (intr[0], intr[1:])
        if model == "omni" and dist == "equidistant":
            raise _fail(source, f"{p}omni with equidistant distortion is not read")
        k1, k2, p1, p2 = d if d else (0.0, 0.0, 0.0, 0.0)
        return Unified(fx=fx, fy=fy, cx=cx, cy=cy, xi=xi, k1=k1, k2=k2, p1=p1, p2=p2)
    if model == "ds":
        xi, alpha, fx, fy, cx, cy = intr
        return DoubleSphere(fx=fx, fy=fy, cx=cx, cy=cy, xi=xi, alpha=alpha)
    alpha, beta, fx, fy, cx, cy = intr
    return EUCM(fx=fx, fy=fy, cx=cx, cy=cy, alpha=alpha, beta=beta)


_NAMED_KB4 = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")


def parse_kalibr(doc: Any, source: str, camera: str | None = None) -> Imported:
    """A Kalibr camchain (dict from YAML) -> the lens of camera ``camera`` (default: first).

    Also reads a YAML of named KB4 parameters per camera (``camN: {fx, fy, cx, cy,
    k1..k4}`` with top-level ``width``/``height``), the form TUM-VI publishes.
    """
    if not isinstance(doc, Mapping):
        raise _fail(source, "not a Kalibr camchain (expected camN: entries)")
    names = [k for k, v in doc.items() if isinstance(v, Mapping)]
    name = _pick(names, camera, source, "camera entries (cam0, cam1, ...)")
    cam, p = doc[name], f"{name}."
    if "camera_model" in cam or "intrinsics" in cam:
        lens = _kalibr_lens(cam, source, p)
        res = cam.get("resolution")
        size = None
        if res is not None:
            w, h = _numbers(res, source, p + "resolution", 2)
            size = _size(w, h, source, p + "resolution")
        return Imported(lens, size, "kalibr", name, tuple(names))
    if "fx" in cam:
        fx, fy, cx, cy, k1, k2, k3, k4 = (_num(cam, k, source, p) for k in _NAMED_KB4)
        lens = KannalaBrandt(fx=fx, fy=fy, cx=cx, cy=cy, k=(k1, k2, k3, k4))
        size = None
        if "width" in doc or "height" in doc:
            size = _size(_get(doc, "width", source), _get(doc, "height", source), source, "width")
        return Imported(lens, size, "kalibr", name, tuple(names))
    raise _fail(source, f"missing key {p + 'camera_model'!r}")


def kalibr_text(lens: LensModel, image_size: tuple[int, int], name: str = "cam0") -> str:
    """``lens`` as one camera of a Kalibr camchain (KB4, unified, DS, EUCM, FOV)."""
    d: tuple[float, ...]
    if isinstance(lens, KannalaBrandt):
        model, intr, dist, d = (
            "pinhole",
            [lens.fx, lens.fy, lens.cx, lens.cy],
            "equidistant",
            lens.k,
        )
    elif isinstance(lens, Unified):
        model, intr = "omni", [lens.xi, lens.fx, lens.fy, lens.cx, lens.cy]
        dist, d = "radtan", (lens.k1, lens.k2, lens.p1, lens.p2)
    elif isinstance(lens, DoubleSphere):
        model, intr = "ds", [lens.xi, lens.alpha, lens.fx, lens.fy, lens.cx, lens.cy]
        dist, d = "none", ()
    elif isinstance(lens, EUCM):
        model, intr = "eucm", [lens.alpha, lens.beta, lens.fx, lens.fy, lens.cx, lens.cy]
        dist, d = "none", ()
    elif isinstance(lens, FieldOfView):
        model, intr = "pinhole", [lens.fx, lens.fy, lens.cx, lens.cy]
        dist, d = "fov", (lens.w,)
    else:
        raise CalibrationError(f"Kalibr has no {lens.name!r} model")
    if getattr(lens, "skew", 0.0):
        raise CalibrationError("Kalibr has no skew; this lens has one")

    def seq(v: Sequence[float]) -> str:
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"

    return (
        f"{name}:\n  camera_model: {model}\n  intrinsics: {seq(intr)}\n"
        f"  distortion_model: {dist}\n  distortion_coeffs: {seq(d)}\n"
        f"  resolution: [{image_size[0]}, {image_size[1]}]\n  rostopic: /{name}/image_raw\n"
    )


# ---------------------------------------------------------------- basalt

_BASALT = {
    "kb4": ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"),
    "ds": ("fx", "fy", "cx", "cy", "xi", "alpha"),
    "eucm": ("fx", "fy", "cx", "cy", "alpha", "beta"),
    "ucm": ("fx", "fy", "cx", "cy", "alpha"),
    "pinhole": ("fx", "fy", "cx", "cy"),
    "fov": ("fx", "fy", "cx", "cy", "w"),
}


def parse_basalt(doc: Any, source: str, camera: str | None = None) -> Imported:
    """A basalt calibration (dict from JSON) -> the lens of camera ``camera`` (``N``).

    >>> eucm = {"fx": 191.1, "fy": 191.1, "cx": 254.9, "cy": 256.8, "alpha": 0.63, "beta": 1.04}
    >>> cams = [{"camera_type": "eucm", "intrinsics": eucm}]
    >>> parse_basalt({"value0": {"intrinsics": cams}}, "calibration.json").lens
    EUCM(fx=191.1, fy=191.1, cx=254.9, cy=256.8, alpha=0.63, beta=1.04)
    """
    root = doc.get("value0", doc) if isinstance(doc, Mapping) else None
    if not isinstance(root, Mapping):
        raise _fail(source, "not a basalt calibration (expected value0.intrinsics)")
    intrs = _get(root, "intrinsics", source, "value0.")
    if not isinstance(intrs, list) or not intrs:
        raise _fail(source, "key 'value0.intrinsics' is not a list of cameras")
    names = [str(i) for i in range(len(intrs))]
    name = _pick(names, camera, source, "cameras")
    i = int(name)
    entry, p = intrs[i], f"value0.intrinsics[{i}]."
    kind = _get(entry, "camera_type", source, p)
    if kind not in _BASALT:
        raise _fail(source, f"{p}camera_type {kind!r} is not read (known: {', '.join(_BASALT)})")
    params = _get(entry, "intrinsics", source, p)
    v = {k: _num(params, k, source, p + "intrinsics.") for k in _BASALT[kind]}
    fx, fy, cx, cy = v["fx"], v["fy"], v["cx"], v["cy"]
    lens: LensModel
    if kind == "kb4":
        lens = KannalaBrandt(fx=fx, fy=fy, cx=cx, cy=cy, k=(v["k1"], v["k2"], v["k3"], v["k4"]))
    elif kind == "ds":
        lens = DoubleSphere(fx=fx, fy=fy, cx=cx, cy=cy, xi=v["xi"], alpha=v["alpha"])
    elif kind == "eucm":
        lens = EUCM(fx=fx, fy=fy, cx=cx, cy=cy, alpha=v["alpha"], beta=v["beta"])
    elif kind == "ucm":
        lens = _ucm(fx, fy, cx, cy, v["alpha"], source)
    elif kind == "fov":
        lens = FieldOfView(fx=fx, fy=fy, cx=cx, cy=cy, w=v["w"])
    else:
        lens = Unified(fx=fx, fy=fy, cx=cx, cy=cy, xi=0.0)
    size = None
    res = root.get("resolution")
    if isinstance(res, list) and len(res) > i:
        w, h = _numbers(res[i], source, f"value0.resolution[{i}]", 2)
        size = _size(w, h, source, f"value0.resolution[{i}]")
    return Imported(lens, size, "basalt", name, tuple(names))


def basalt_text(lenses: Sequence[LensModel], sizes: Sequence[tuple[int, int]]) -> str:
    """``lenses`` as a basalt calibration.json (intrinsics and resolution only)."""
    out = []
    for lens in lenses:
        if isinstance(lens, KannalaBrandt) and not lens.skew:
            k = lens.k
            t, names = "kb4", dict(zip(_BASALT["kb4"][4:], k, strict=True))
        elif isinstance(lens, DoubleSphere):
            t, names = "ds", {"xi": lens.xi, "alpha": lens.alpha}
        elif isinstance(lens, EUCM):
            t, names = "eucm", {"alpha": lens.alpha, "beta": lens.beta}
        elif isinstance(lens, FieldOfView):
            t, names = "fov", {"w": lens.w}
        else:
            raise CalibrationError(f"basalt has no {lens.name!r} model here")
        params = {"fx": lens.fx, "fy": lens.fy, "cx": lens.cx, "cy": lens.cy, **names}
        out.append({"camera_type": t, "intrinsics": params})
    doc = {"value0": {"intrinsics": out, "resolution": [list(s) for s in sizes]}}
    return json.dumps(doc, indent=4)


# ---------------------------------------------------------------- camera-intrinsic-model-rs


_CIM: dict[str, tuple[type[EUCM] | type[FieldOfView], tuple[str, ...]]] = {
    "EUCM": (EUCM, ("fx", "fy", "cx", "cy", "alpha", "beta")),
    "FovCamera": (FieldOfView, ("fx", "fy", "cx", "cy", "w")),
}


def parse_cim(doc: Any, source: str) -> Imported:
    """camera-intrinsic-model-rs JSON -> :class:`EUCM` (``{"EUCM": {fx, fy, cx, cy, alpha,
    beta, width, height}}``) or :class:`FieldOfView` (``{"FovCamera": {fx, fy, cx, cy, w,
    width, height}}``). Its other models (KB4, UCM, OpenCV5, ...) are not read.

    The parameters are taken as written (pixel centres at integers). Its TUM monoVO FOV
    file is DSO's relative calibration times the image size without DSO's -0.5 px
    shift of cx and cy (docs/fisheye-import.md)."""
    if not isinstance(doc, Mapping) or len(doc) != 1:
        raise _fail(source, "not a camera-intrinsic-model file (one model key expected)")
    ((kind, params),) = doc.items()
    if kind not in _CIM:
        raise _fail(source, f"model {kind!r} is not read (known: {', '.join(_CIM)})")
    cls, keys = _CIM[kind]
    p = f"{kind}."
    v = {k: _num(params, k, source, p) for k in keys}
    size = _size(_get(params, "width", source, p), _get(params, "height", source, p), source, p)
    return Imported(cls(**v), size, "cim")


# ---------------------------------------------------------------- OpenCV FileStorage

_K_KEYS = ("K", "camera_matrix", "cameraMatrix", "intrinsic_matrix")
_D_KEYS = ("D", "distortion_coefficients", "dist_coeffs", "distCoeffs", "distortion_coeffs")


def _matrix(value: Any, source: str, key: str) -> FloatArray:
    """An ndarray, a ROS ``{rows, cols, data}`` map or a (nested) list as float array."""
    if isinstance(value, Mapping) and "data" in value:
        data = np.array(_numbers(value["data"], source, key + ".data"))
        rows = int(_number(_get(value, "rows", source, key + "."), source, key + ".rows"))
        if rows < 1 or data.size % rows:
            raise _fail(source, f"key {key!r}: {data.size} numbers do not fill {rows} rows")
        return data.reshape(rows, -1)
    if isinstance(value, list):
        try:
            arr = np.array(value, np.float64)
        except (TypeError, ValueError):
            raise _fail(source, f"key {key!r} is not a matrix") from None
    elif isinstance(value, np.ndarray):
        arr = value.astype(np.float64)
    else:
        raise _fail(source, f"key {key!r} is not a matrix")
    if not np.all(np.isfinite(arr)):
        raise _fail(source, f"key {key!r} has non-finite values")
    if arr.size and float(np.max(np.abs(arr))) > MAX_PARAMETER:
        raise _fail(source, f"key {key!r} has values beyond {MAX_PARAMETER:g}")
    return arr


def _first(doc: Mapping[str, Any], keys: Sequence[str]) -> str | None:
    return next((k for k in keys if k in doc and doc[k] is not None), None)


def parse_opencv(doc: Any, source: str) -> Imported:
    """cv2.fisheye / cv2.omnidir / ROS camera_info nodes (dict) -> KB4 or unified lens.

    ``K`` (3x3; ``K[0,1]`` is the skew) and ``D``; with ``xi`` the file is cv2.omnidir's
    (D = k1 k2 p1 p2) -> :class:`Unified`; without, 4 coefficients are cv2.fisheye's
    k1..k4 -> :class:`KannalaBrandt` unless ``distortion_model`` says ``plumb_bob``/
    ``radtan`` (a pinhole: the unified model with xi = 0; k3 must then be 0).
    """
    if not isinstance(doc, Mapping):
        raise _fail(source, "not an OpenCV calibration (expected K and D)")
    kkey = _first(doc, _K_KEYS)
    if kkey is None:
        raise _fail(source, "missing key 'K' (or 'camera_matrix')")
    K = _matrix(doc[kkey], source, kkey)
    if K.shape != (3, 3) or abs(K[1, 0]) + abs(K[2, 0]) + abs(K[2, 1]) > 0 or K[2, 2] != 1.0:
        raise _fail(source, f"key {kkey!r} is not an upper-triangular 3x3 camera matrix")
    dkey = _first(doc, _D_KEYS)
    if dkey is None:
        raise _fail(source, "missing key 'D' (or 'distortion_coefficients')")
    D = _matrix(doc[dkey], source, dkey).reshape(-1)
    fx, fy, cx, cy, s = (float(K[i, j]) for i, j in ((0, 0), (1, 1), (0, 2), (1, 2), (0, 1)))
    model = str(doc.get("distortion_model") or "").lower()
    lens: LensModel
    if "xi" in doc and doc["xi"] is not None:
        xi_value = doc["xi"]
        if not isinstance(xi_value, int | float):
            xi_value = _numbers(_matrix(xi_value, source, "xi"), source, "xi", 1)[0]
        xi = _number(xi_value, source, "xi")
        if D.size != 4:
            raise _fail(source, f"key {dkey!r}: cv2.omnidir has 4 coefficients, not {D.size}")
        k1, k2, p1, p2 = (float(v) for v in D)
        lens = Unified(fx=fx, fy=fy, cx=cx, cy=cy, xi=xi, skew=s, k1=k1, k2=k2, p1=p1, p2=p2)
    elif model in ("plumb_bob", "radtan", "radial-tangential"):
        if D.size not in (4, 5) or (D.size == 5 and D[4] != 0.0):
            raise _fail(source, f"key {dkey!r}: only k1 k2 p1 p2 (k3 = 0) are read")
        k1, k2, p1, p2 = (float(v) for v in D[:4])
        lens = Unified(fx=fx, fy=fy, cx=cx, cy=cy, xi=0.0, skew=s, k1=k1, k2=k2, p1=p1, p2=p2)
    elif model in ("", "fisheye", "equidistant", "kannala_brandt", "kb4"):
        if D.size != 4:
            raise _fail(
                source, f"key {dkey!r}: cv2.fisheye has 4 coefficients, not {D.size} (or add xi)"
            )
        k = (float(D[0]), float(D[1]), float(D[2]), float(D[3]))
        lens = KannalaBrandt(fx=fx, fy=fy, cx=cx, cy=cy, k=k, skew=s)
    else:
        raise _fail(source, f"distortion_model {model!r} is not read")
    return Imported(lens, _opencv_size(doc, source), "opencv")


def _opencv_size(doc: Mapping[str, Any], source: str) -> tuple[int, int] | None:
    if "image_width" in doc or "image_height" in doc:
        w, h = _get(doc, "image_width", source), _get(doc, "image_height", source)
        return _size(w, h, source, "image_width")
    key = _first(doc, ("image_size", "imageSize"))
    if key is not None:
        w, h = _numbers(doc[key], source, key, 2)
        return _size(w, h, source, key)
    return None


def opencv_nodes(lens: LensModel, image_size: tuple[int, int] | None) -> dict[str, Any]:
    """FileStorage nodes for ``lens`` as OpenCV reads them: ``K`` (3x3), ``D`` and, for a
    unified lens, ``xi`` (cv2.omnidir); ``distortion_model`` ``fisheye``/``omnidir``;
    ``image_width``/``image_height``. An ideal equidistant lens is written as KB4 with
    k = 0; other models have no OpenCV form (CalibrationError)."""
    if isinstance(lens, IdealFisheye) and lens.projection == "equidistant":
        lens = KannalaBrandt(
            fx=lens.f, fy=lens.f * lens.aspect, cx=lens.cx, cy=lens.cy, k=(0.0, 0.0, 0.0, 0.0)
        )
    if isinstance(lens, KannalaBrandt):
        s, d, model = lens.skew, np.array(lens.k, np.float64).reshape(4, 1), "fisheye"
    elif isinstance(lens, Unified):
        s, model = lens.skew, "omnidir"
        d = np.array([[lens.k1, lens.k2, lens.p1, lens.p2]], np.float64)
    else:
        raise CalibrationError(
            f"OpenCV has no {lens.name!r} lens (cv2.fisheye: kb4, cv2.omnidir: mei); "
            "keep the omnidev camera file"
        )
    K = np.array([[lens.fx, s, lens.cx], [0.0, lens.fy, lens.cy], [0.0, 0.0, 1.0]])
    nodes: dict[str, Any] = {"distortion_model": model, "K": K, "D": d}
    if isinstance(lens, Unified):
        nodes["xi"] = np.array([[lens.xi]])
    if image_size is not None:
        nodes["image_width"], nodes["image_height"] = int(image_size[0]), int(image_size[1])
    return nodes


def write_opencv(
    path: Path, lens: LensModel, image_size: tuple[int, int] | None, *, force: bool = False
) -> None:
    """Write :func:`opencv_nodes` to ``path`` (cv2.FileStorage, atomically)."""
    nodes = opencv_nodes(lens, image_size)
    with atomic_path(Path(path), force=force) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
        if not fs.isOpened():
            raise CalibrationError(f"{path}: cannot write (use .yml, .xml or .json)")
        for key, value in nodes.items():
            fs.write(key, value)
        fs.release()


# ---------------------------------------------------------------- files


def read_text(path: Path) -> str:
    """The file's text; a missing or binary file is a CalibrationError naming it."""
    from omnidev.inputfile import check_nesting
    from omnidev.inputfile import read_text as read_input

    text = read_input(Path(path), "calibration file", error=CalibrationError)
    check_nesting(text, path, "calibration file", CalibrationError)
    return text


def read_yaml(path: Path) -> Any:
    """A YAML file (the subset of :mod:`omnidev.fisheye.miniyaml`)."""
    try:
        return miniyaml.loads(read_text(path))
    except miniyaml.YamlError as exc:
        raise CalibrationError(f"{path}: not readable YAML ({exc})") from None


def read_json(path: Path) -> Any:
    from omnidev.inputfile import loads_json

    return loads_json(read_text(path), path, "calibration file", CalibrationError)


def _node_value(node: cv2.FileNode, path: Path, key: str) -> Any:
    """A FileNode as Python: dict, list, ndarray (matrices), float/int or str."""
    if node.isMap():
        keys = node.keys()
        if {"rows", "dt", "data"} <= set(keys):  # an opencv-matrix (cols may be cut off)
            from omnidev.calibfile import check_matrix_node

            check_matrix_node(node, path, key)
            mat = node.mat()
            if mat is not None:
                return np.asarray(mat, np.float64)
        return {k: _node_value(node.getNode(k), path, k) for k in keys}
    if node.isSeq():
        return [_node_value(node.at(i), path, key) for i in range(node.size())]
    if node.isInt():
        return int(node.real())
    if node.isReal():
        return float(node.real())
    if node.isString():
        return str(node.string())
    return None


def read_storage(path: Path) -> dict[str, Any]:
    """An OpenCV FileStorage file's top-level nodes as Python values."""
    from omnidev.calibfile import open_storage

    with open_storage(Path(path)) as fs:
        root = fs.root()
        try:
            return {k: _node_value(root.getNode(k), path, k) for k in root.keys()}  # noqa: SIM118 (a FileNode)
        except cv2.error as exc:
            msg = str(exc).split("error:", 1)[-1].strip().splitlines()[0]
            raise CalibrationError(f"{path}: not a readable OpenCV FileStorage ({msg})") from None
        except UnicodeDecodeError:  # a text node whose bytes (e.g. a "\xde" escape) are not UTF-8
            raise CalibrationError(f"{path}: a text value is not UTF-8 text") from None


def detect_format(path: Path) -> Format:
    """The format of ``path`` from its name and first lines (see the module table)."""
    path = Path(path)
    name = path.name.lower()
    if name.endswith((".xml", ".xml.gz", ".yml.gz", ".yaml.gz", ".json.gz")):
        return "opencv"
    text = read_text(path)
    head = text.lstrip()[:4000]
    if name.endswith(".txt") or "ocam_model" in head:
        return "ocamcalib"
    if name.endswith(".json") or head.startswith("{"):
        try:
            doc = json.loads(text)
        except json.JSONDecodeError:
            return "opencv"
        if isinstance(doc, Mapping):
            if all(k in doc for k in PYOCAMCALIB_KEYS):
                return "pyocamcalib"
            if "value0" in doc or "intrinsics" in doc:
                return "basalt"
            if len(doc) == 1 and isinstance(next(iter(doc.values())), Mapping):
                return "cim"
        return "opencv"
    if head.startswith("%YAML") or "!!opencv-matrix" in head:
        return "opencv"
    try:
        doc = miniyaml.loads(text)
    except miniyaml.YamlError:
        return "opencv"
    if isinstance(doc, Mapping) and _first(doc, ("kind", *_K_KEYS)) is None:
        return "kalibr"
    return "opencv"


def import_calibration(
    path: Path | str, *, fmt: Format | Literal["auto"] = "auto", camera: str | None = None
) -> Imported:
    """Read one camera's lens from ``path`` in format ``fmt`` (``auto``: :func:`detect_format`).

    ``camera`` chooses in multi-camera files (Kalibr ``cam1`` or ``1``; basalt ``1``);
    the default is the first camera.
    """
    path = Path(path)
    source = str(path)
    if fmt == "auto":
        fmt = detect_format(path)
    if camera is not None and fmt not in ("kalibr", "basalt"):
        raise CalibrationError(f"{path}: --camera applies to Kalibr and basalt files, not {fmt}")
    with _model_errors(source):
        if fmt == "ocamcalib":
            return parse_ocamcalib(read_text(path), source)
        if fmt == "pyocamcalib":
            return parse_pyocamcalib(read_json(path), source)
        if fmt == "kalibr":
            return parse_kalibr(read_yaml(path), source, camera)
        if fmt == "basalt":
            return parse_basalt(read_json(path), source, camera)
        if fmt == "cim":
            return parse_cim(read_json(path), source)
        if fmt == "opencv":
            if path.suffix.lower() in (".yaml", ".yml") and "%YAML" not in read_text(path)[:64]:
                doc: Any = _yaml_or_storage(path)
            else:
                doc = read_storage(path)
            if isinstance(doc, Mapping) and doc.get("kind") is not None:
                return _omnidev_file(path, doc)
            return parse_opencv(doc, source)
    raise CalibrationError(f"{path}: unknown format {fmt!r} (known: {', '.join(FORMATS)})")


def _yaml_or_storage(path: Path) -> Any:
    """A YAML without the %YAML header (e.g. ROS camera_info): FileStorage, else miniyaml."""
    try:
        return read_storage(path)
    except CalibrationError:
        return read_yaml(path)


def _omnidev_file(path: Path, doc: Mapping[str, Any]) -> Imported:
    from omnidev.fisheye.camera import KIND
    from omnidev.fisheye.camfile import read_camera_file

    kind = doc.get("kind")
    if kind != KIND:
        raise CalibrationError(f"{path}: an omnidev camera of kind {kind!r}, not {KIND!r}")
    cam = read_camera_file(path)
    return Imported(
        cam.lens,
        (int(cam.image_size[0]), int(cam.image_size[1])),
        "opencv",
        mount=np.asarray(cam.mount, np.float64),
        max_angle_deg=cam.max_angle_deg,
    )

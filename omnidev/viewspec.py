"""Text form of views, for the command line: ``KIND:WxH[,key=value...]``.

| kind          | keys (lengths in the calibration's unit, angles in degrees)                 |
|---------------|------------------------------------------------------------------------------|
| `panorama`    | elev=LO:HI (default: the camera's range), start=DEG, span=DEG, ccw=1         |
| `cylinder`    | d=DIST, z=BOTTOM:TOP (required), start=DEG, span=DEG, ccw=1                  |
| `plane`       | vertical: d=DIST, w=WIDTH, z=BOTTOM:TOP (required), az=DEG                  |
|               | any plane: c=X:Y:Z, n=NX:NY:NZ, w=WIDTH, h=HEIGHT (required), roll=DEG      |
| `perspective` | fov=DEG (default 90), pan=DEG, tilt=DEG, roll=DEG                            |
| `top`         | x=EXTENT, y=EXTENT, z=HEIGHT (required), cx=X, cy=Y                          |
| `equirect`    | lon=LEFT:RIGHT (default -180:180), lat=BOTTOM:TOP (default -90:90),         |
|               | pan=DEG, tilt=DEG, roll=DEG (the centre direction, as for perspective)       |

>>> parse_view("panorama:1024x256,elev=-60:10").elevation_deg
(-60.0, 10.0)
>>> parse_view("perspective:640x480,fov=70,pan=90").pan_deg
90.0
>>> parse_view("equirect:1024x512,lon=-100:100,lat=-90:90").lon_deg
(-100.0, 100.0)
>>> parse_view("plane:640x480,c=2000:0:-1000,n=1:0:1,w=1500,h=1000").normal
(1.0, 0.0, 1.0)

A plane given by ``c`` (its centre) and ``n`` (its normal) is seen upright from the viewpoint
(:func:`omnidev.views.plane_axes`); ``w`` and ``h`` are its size along the view's right and
down axes.
"""

from __future__ import annotations

import math

from omnidev.errors import OmnidevError
from omnidev.views import (
    CylinderPanorama,
    Equirectangular,
    Panorama,
    Perspective,
    Plane,
    PlaneView,
    TopView,
    View,
)

_KEYS = {
    "panorama": {"elev", "start", "span", "ccw"},
    "cylinder": {"d", "z", "start", "span", "ccw"},
    "plane": {"d", "w", "z", "az", "c", "n", "h", "roll"},
    "perspective": {"fov", "pan", "tilt", "roll"},
    "top": {"x", "y", "z", "cx", "cy"},
    "equirect": {"lon", "lat", "pan", "tilt", "roll"},
}
VIEW_HELP = """\
views (--view KIND:WxH[,KEY=VALUE...]; W x H output pixels, 1..32768 per side;
lengths in the calibration's unit, e.g. m for the fixtures; angles in degrees):
  panorama:WxH     360-degree panorama of the camera's elevation band
                   elev=LO:HI  elevation band (default: the camera's own range)
                   start=DEG   azimuth at the left edge (default 0)
                   span=DEG    azimuth range, (0, 360] (default 360)
                   ccw=1       azimuth grows to the left (default 0: clockwise seen from above)
  cylinder:WxH     panorama projected on a cylinder around the camera
                   d=DIST      cylinder radius (required)
                   z=LO:HI     bottom and top height of the cylinder (required)
                   start=DEG, span=DEG, ccw=1 as for panorama
  plane:WxH        perspective view of a vertical plane (eq. 4.14)
                   d=DIST      distance of the plane from the camera axis (required)
                   w=WIDTH     plane width (required, < 2 d)
                   z=LO:HI     bottom and top height (required)
                   az=DEG      azimuth of the plane's centre (default 0)
                   or any plane: c=X:Y:Z centre, n=NX:NY:NZ normal (either sign),
                   w=WIDTH, h=HEIGHT its size (all required), roll=DEG (default 0)
  perspective:WxH  pinhole view
                   fov=DEG     horizontal field of view, [0.0001, 180) (default 90)
                   pan=DEG, tilt=DEG, roll=DEG  view direction (default 0, 0, 0)
  top:WxH          view of a horizontal plane from above
                   x=EXTENT, y=EXTENT  plane size (required)
                   z=HEIGHT    plane height, not 0 (required; e.g. -1.2 for a floor)
                   cx=X, cy=Y  plane centre (default 0, 0)
  equirect:WxH     equirectangular (longitude x latitude) image
                   lon=LEFT:RIGHT  longitudes (default -180:180)
                   lat=BOTTOM:TOP  latitudes (default -90:90)
                   pan=DEG, tilt=DEG, roll=DEG  centre direction, as for perspective
example: --view panorama:2048x512,elev=-60:10 --view plane:640x480,d=2,w=3,z=-1:1,az=90
"""
"""The ``--view`` section of ``omnidev unwarp --help`` (every kind and key of the parser)."""

_REQUIRED = {"cylinder": {"d", "z"}, "plane": {"d", "w", "z"}, "top": {"x", "y", "z"}}


class ViewSpecError(OmnidevError):
    """A view description that cannot be parsed."""


def _num(spec: str, key: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ViewSpecError(f"view {spec!r}: {key}={text!r} is not a number") from None
    if not math.isfinite(v):
        raise ViewSpecError(f"view {spec!r}: {key} must be finite")
    return v


def _pair(spec: str, key: str, text: str) -> tuple[float, float]:
    parts = text.split(":")
    if len(parts) != 2:
        raise ViewSpecError(f"view {spec!r}: {key} must be LO:HI, got {text!r}")
    return _num(spec, key, parts[0]), _num(spec, key, parts[1])


def _triple(spec: str, key: str, text: str) -> tuple[float, float, float]:
    parts = text.split(":")
    if len(parts) != 3:
        raise ViewSpecError(f"view {spec!r}: {key} must be X:Y:Z, got {text!r}")
    x, y, z = (_num(spec, key, p) for p in parts)
    return x, y, z


_PLANE_GENERAL = {"c", "n", "h", "roll"}
_PLANE_VERTICAL = {"d", "z", "az"}


def parse_view(spec: str) -> View:
    """Parse a view description (see the module docstring)."""
    if len(spec) > 1000:
        raise ViewSpecError(
            f"view {spec[:40]!r}...: {len(spec)} characters; not a view description"
        )
    kind, _, rest = spec.partition(":")
    kind = kind.strip().lower()
    if kind not in _KEYS:
        raise ViewSpecError(f"view {spec!r}: unknown kind {kind!r}; kinds: {', '.join(_KEYS)}")
    fields = [f.strip() for f in rest.split(",") if f.strip()]
    if not fields:
        raise ViewSpecError(f"view {spec!r}: give the size, e.g. {kind}:640x480")
    try:
        w, h = (int(x) for x in fields[0].lower().split("x"))
    except ValueError:
        raise ViewSpecError(f"view {spec!r}: size must look like 640x480") from None
    if w < 1 or h < 1 or w > 32768 or h > 32768:
        raise ViewSpecError(f"view {spec!r}: size must be 1..32768 pixels per side")
    kv: dict[str, str] = {}
    for f in fields[1:]:
        key, eq, val = f.partition("=")
        key = key.strip()
        if not eq or key not in _KEYS[kind]:
            raise ViewSpecError(
                f"view {spec!r}: unknown setting {f!r}; {kind} takes "
                f"{', '.join(sorted(_KEYS[kind]))}"
            )
        kv[key] = val.strip()
    required = _REQUIRED.get(kind, set())
    if kind == "plane" and set(kv) & _PLANE_GENERAL:
        mixed = set(kv) & _PLANE_VERTICAL
        if mixed:
            raise ViewSpecError(
                f"view {spec!r}: a plane is either c, n, w, h[, roll] (any plane) or d, w, "
                f"z[, az] (vertical); {', '.join(sorted(mixed))} does not go with c and n"
            )
        required = {"c", "n", "w", "h"}
    missing = required - set(kv)
    if missing:
        raise ViewSpecError(f"view {spec!r}: {kind} needs {', '.join(sorted(missing))}")

    def num(key: str, default: float) -> float:
        return _num(spec, key, kv[key]) if key in kv else default

    def clockwise() -> bool:
        text = kv.get("ccw", "0").lower()
        if text not in ("0", "1", "yes", "no", "true", "false"):
            raise ViewSpecError(f"view {spec!r}: ccw must be 0 or 1, got {text!r}")
        return text in ("0", "no", "false")

    if "elev" in kv:
        lo, hi = _pair(spec, "elev", kv["elev"])
        if not -90 <= lo < hi <= 90:
            raise ViewSpecError(f"view {spec!r}: elev=LO:HI must have -90 <= LO < HI <= 90 degrees")
    if "span" in kv and not 0 < _num(spec, "span", kv["span"]) <= 360:
        raise ViewSpecError(f"view {spec!r}: span must be in (0, 360] degrees")
    for key in ("start", "az", "pan", "tilt", "roll"):
        if key in kv and not abs(_num(spec, key, kv[key])) <= 3600:
            raise ViewSpecError(f"view {spec!r}: {key} must be within +-3600 degrees")
    if kind == "top" and _num(spec, "z", kv["z"]) == 0:
        raise ViewSpecError(f"view {spec!r}: z (the plane's height) must not be 0, the mirror's")
    try:
        if kind == "panorama":
            elev = _pair(spec, "elev", kv["elev"]) if "elev" in kv else None
            return Panorama(w, h, elev, num("start", 0.0), num("span", 360.0), clockwise())
        if kind == "cylinder":
            zb, zt = _pair(spec, "z", kv["z"])
            return CylinderPanorama(
                w, h, num("d", 0), zb, zt, num("start", 0.0), num("span", 360.0), clockwise()
            )
        if kind == "plane" and "c" in kv:
            return Plane(
                w,
                h,
                _triple(spec, "c", kv["c"]),
                _triple(spec, "n", kv["n"]),
                num("w", 0),
                num("h", 0),
                num("roll", 0.0),
            )
        if kind == "plane":
            zb, zt = _pair(spec, "z", kv["z"])
            return PlaneView(w, h, num("d", 0), num("w", 0), zb, zt, num("az", 0.0))
        if kind == "perspective":
            return Perspective(
                w, h, num("fov", 90.0), num("pan", 0.0), num("tilt", 0.0), num("roll", 0.0)
            )
        if kind == "equirect":
            lon = _pair(spec, "lon", kv["lon"]) if "lon" in kv else (-180.0, 180.0)
            lat = _pair(spec, "lat", kv["lat"]) if "lat" in kv else (-90.0, 90.0)
            return Equirectangular(
                w, h, lon, lat, num("pan", 0.0), num("tilt", 0.0), num("roll", 0.0)
            )
        return TopView(w, h, num("x", 0), num("y", 0), num("z", 0), num("cx", 0.0), num("cy", 0.0))
    except ValueError as exc:
        raise ViewSpecError(f"view {spec!r}: {exc}") from None

"""The daemon's TOML configuration, validated with messages that name the key.

[source]
uri = "v4l2:/dev/video0?width=640&height=480&fps=30"   # any omnidev source URI

[tracker]
name = "bright-blob"          # a plugin of group omnidev.trackers
calibration = ""              # optional path of the tracker's calibration file
[tracker.options]             # passed to the tracker as they are
threshold = 200

[filter]
kind = "one-euro"             # or "none"
min_cutoff = 0.1              # Hz: the cutoff when still (lower: steadier)
beta = 20.0                   # s per screen width: how fast the cutoff rises with speed
d_cutoff = 2.0                # Hz: the cutoff of the speed estimate
max_gap_s = 0.0               # s: restart after a gap longer than this (0: never)
# (defaults tuned on the camera mouse at 30 fps: docs/camera-mouse.md, One Euro tuning;
#  the laser-pointer tracker has its own defaults: TRACKER_FILTER_DEFAULTS)

[sink]
name = "uinput"               # a plugin of group omnidev.sinks
[sink.options]                # passed to the sink as they are

[buttons]                     # optional: pointer buttons from other inputs
input = "evdev:/dev/input/by-id/usb-Some_Keyboard-event-kbd?KEY_SPACE=left"
                              # or "hid:VVVV:PPPP?key.0x4e=left" (docs/buttons.md)
dwell = false                 # click when the cursor rests ...
dwell_s = 0.8                 # ... this long (s)
dwell_radius_px = 12.0        # ... within this radius (target-screen px)
dwell_button = "left"
release_when_lost = true      # release every button on a frame with no target

[screen]
rect = "1920x1080+0+0"        # the target screen in the desktop layout (WxH+X+Y)
layout = "1920x1080"          # the whole desktop (default: the rect's extent)

[daemon]
socket = "/run/omnidev/control.sock"
queue = 1                     # frames waiting for the tracker (1 .. 16); when it is full a
                              # camera's oldest frame is dropped, a file waits
retry_initial_s = 0.5         # camera retry backoff: first wait ...
retry_max_s = 10.0            # ... doubling up to this

[[stream]]                    # optional, any number: video streams beside the pointer
                              # (omnidev.daemon.streams); a configuration may have only
                              # streams (then no [source], [tracker] or [sink]), only the
                              # pointer, or both
name = "room"
source = "v4l2:/dev/video2"
camera = "room.yml"
[[stream.view]]
name = "ptz"
view = "perspective:1280x720,fov=70"
output = "v4l2:/dev/video10"
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omnidev.daemon.control import DEFAULT_SOCKET
from omnidev.daemon.streams import StreamConfig, parse_streams
from omnidev.errors import ConfigError
from omnidev.inputfile import not_a_file, read_toml
from omnidev.screen import ScreenMapping, ScreenRect
from omnidev.sources import resolve_uri

DEFAULT_CONFIG = Path("/etc/omnidev/omnidev.toml")
# Frames the queue may hold: a live source's frames beyond one or two only add
# latency, a file's only memory (16 frames of 1920x1080 BGR are 100 MB).
MAX_QUEUE = 16

MAX_CUTOFF_HZ = 1000.0
"""Largest One Euro cutoff accepted (Hz): far above any camera's frame rate."""
MAX_BETA = 1e6

_SECTIONS: dict[str, set[str]] = {
    "source": {"uri"},
    "tracker": {"name", "calibration", "options"},
    "filter": {"kind", "min_cutoff", "beta", "d_cutoff", "max_gap_s"},
    "sink": {"name", "options"},
    "buttons": {
        "input",
        "dwell",
        "dwell_s",
        "dwell_radius_px",
        "dwell_button",
        "release_when_lost",
    },
    "screen": {"rect", "layout"},
    "daemon": {"socket", "queue", "retry_initial_s", "retry_max_s"},
}


@dataclass(frozen=True)
class FilterConfig:
    """Smoothing: ``kind`` "one-euro" (Casiez et al. 2012) or "none"; cutoffs in Hz;
    ``max_gap_s``: a sample more than this after the previous one restarts the filter
    (0: never)."""

    kind: str = "one-euro"
    min_cutoff: float = 0.1
    beta: float = 20.0
    d_cutoff: float = 2.0
    max_gap_s: float = 0.0


# Filter defaults of trackers whose samples differ from the camera mouse's: keys the
# [filter] table leaves out come from here. The laser spot is measured to a fraction
# of a pixel but found in bursts (the laser goes off, the spot jumps): a higher
# cutoff and a restart after 0.1 s without a spot, so positions many frames apart
# are never blended (omnidev eval laser reports both filters' RMS against the truth).
TRACKER_FILTER_DEFAULTS: dict[str, FilterConfig] = {
    "laser-pointer": FilterConfig("one-euro", 1.5, 20.0, 2.0, 0.1),
}


@dataclass(frozen=True)
class ButtonsConfig:
    """Pointer buttons from other inputs: ``input`` an omnidev.buttons spec ("" = none),
    the dwell click (time in s, radius in target-screen pixels), and whether a frame
    with no target (the tracker gives nothing) releases every button."""

    input: str = ""
    dwell: bool = False
    dwell_s: float = 0.8
    dwell_radius_px: float = 12.0
    dwell_button: str = "left"
    release_when_lost: bool = True


@dataclass(frozen=True)
class DaemonConfig:
    """A validated configuration (see the module docstring for the file format)."""

    path: Path
    source: str
    tracker: str
    sink: str
    screen: ScreenMapping
    tracker_options: dict[str, Any] = field(default_factory=dict)
    calibration: Path | None = None
    filter: FilterConfig = FilterConfig()
    buttons: ButtonsConfig = ButtonsConfig()
    sink_options: dict[str, Any] = field(default_factory=dict)
    socket: Path = DEFAULT_SOCKET
    queue: int = 1
    retry_initial_s: float = 0.5
    retry_max_s: float = 10.0
    streams: tuple[StreamConfig, ...] = ()
    pointer: bool = True  # False: a streams-only configuration (source, tracker, sink "")


def load_config(path: Path) -> DaemonConfig:
    """Read and validate ``path``; a :class:`ConfigError` names the file and key."""
    path = Path(path)
    doc = read_toml(path, "configuration file", error=ConfigError)
    return parse_config(doc, path)


def parse_config(doc: dict[str, Any], path: Path) -> DaemonConfig:
    """Validate a parsed TOML document (``path`` only names it in messages)."""

    def fail(key: str, msg: str) -> ConfigError:
        return ConfigError(f"{path}: {key}: {msg}")

    doc = dict(doc)
    streams = parse_streams(doc.pop("stream", None), path)
    pointer = bool(streams) is False or any(k in doc for k in ("source", "tracker", "sink"))
    for section, value in doc.items():
        if section not in _SECTIONS:
            known = ", ".join([*_SECTIONS, "stream"])
            raise fail(section, f"unknown section (sections: {known})")
        if not isinstance(value, dict):
            raise fail(section, "must be a table ([" + section + "])")
        for key in value:
            if key not in _SECTIONS[section]:
                known = ", ".join(sorted(_SECTIONS[section]))
                raise fail(f"{section}.{key}", f"unknown key (keys of [{section}]: {known})")

    def get(section: str, key: str, kind: type | tuple[type, ...], default: Any = None) -> Any:
        value = doc.get(section, {}).get(key, default)
        if value is None:
            if default is None:
                raise fail(f"{section}.{key}", "missing (required)")
            return default
        if isinstance(value, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
            raise fail(f"{section}.{key}", f"must be {_kind_name(kind)}, got {value!r}")
        if not isinstance(value, kind):
            raise fail(f"{section}.{key}", f"must be {_kind_name(kind)}, got {value!r}")
        if isinstance(value, str) and "\0" in value:
            raise fail(f"{section}.{key}", "contains a NUL character")
        return value

    def positive(
        section: str, key: str, default: float, limit: float, allow_zero: bool = False
    ) -> float:
        value = float(get(section, key, (int, float), default))
        low = "0 <=" if allow_zero else "0 <"
        if not (value > 0 or (allow_zero and value == 0)) or not value <= limit:
            raise fail(f"{section}.{key}", f"must be a number with {low} value <= {limit:g}")
        return value

    if not pointer:
        for section in ("filter", "buttons", "screen"):
            if section in doc:
                raise fail(section, "belongs to the pointer: give [source], [tracker] and [sink]")
        doc = {**doc, "source": {"uri": "-"}, "tracker": {"name": ""}, "sink": {"name": ""}}
    source = get("source", "uri", str)
    if not source.strip():
        raise fail("source.uri", "is empty")
    source = resolve_uri(source, path.parent)
    tracker = get("tracker", "name", str)
    calib_text = get("tracker", "calibration", str, "")
    calibration = Path(calib_text) if calib_text else None
    if calibration is not None and not calibration.is_absolute():
        calibration = path.parent / calibration
    why = None if calibration is None else not_a_file(calibration, "calibration file")
    if why is not None:
        raise fail("tracker.calibration", f"{calibration}: {why}")
    tracker_options = get("tracker", "options", dict, {})
    sink = get("sink", "name", str)
    sink_options = dict(get("sink", "options", dict, {}))
    sink_path = sink_options.get("path")
    if isinstance(sink_path, str) and sink_path not in ("", "-") and "\0" not in sink_path:
        # one rule for every path a configuration names: relative to the file
        p = Path(sink_path)
        sink_options["path"] = str(p if p.is_absolute() else path.parent / p)

    kind = get("filter", "kind", str, "one-euro")
    if kind not in ("one-euro", "none"):
        raise fail("filter.kind", f"must be 'one-euro' or 'none', got {kind!r}")
    base = TRACKER_FILTER_DEFAULTS.get(tracker, FilterConfig())
    filt = FilterConfig(
        kind,
        positive("filter", "min_cutoff", base.min_cutoff, MAX_CUTOFF_HZ),
        positive("filter", "beta", base.beta, MAX_BETA, allow_zero=True),
        positive("filter", "d_cutoff", base.d_cutoff, MAX_CUTOFF_HZ),
        positive("filter", "max_gap_s", base.max_gap_s, 3600.0, allow_zero=True),
    )

    button_spec = get("buttons", "input", str, "").strip()
    if button_spec:
        from omnidev.buttons import parse_spec

        try:
            parse_spec(button_spec)
        except ConfigError as exc:
            raise fail("buttons.input", str(exc)) from None
    dwell_button = get("buttons", "dwell_button", str, "left")
    if dwell_button not in ("left", "right", "middle"):
        raise fail("buttons.dwell_button", f"must be left, right or middle, got {dwell_button!r}")
    buttons = ButtonsConfig(
        button_spec,
        get("buttons", "dwell", bool, False),
        positive("buttons", "dwell_s", ButtonsConfig.dwell_s, 3600.0),
        positive("buttons", "dwell_radius_px", ButtonsConfig.dwell_radius_px, 100_000.0),
        dwell_button,
        get("buttons", "release_when_lost", bool, True),
    )

    rect_text = get("screen", "rect", str, "1920x1080+0+0")
    try:
        rect = ScreenRect.parse(rect_text)
    except ValueError as exc:
        raise fail("screen.rect", str(exc)) from None
    layout_text = get("screen", "layout", str, f"{rect.x + rect.width}x{rect.y + rect.height}")
    try:
        layout = ScreenRect.parse(layout_text)
        mapping = ScreenMapping(rect, layout.width, layout.height)
    except ValueError as exc:
        raise fail("screen.layout", str(exc)) from None

    queue = get("daemon", "queue", int, 1)
    if not 1 <= queue <= MAX_QUEUE:
        raise fail(
            "daemon.queue",
            f"must be 1 .. {MAX_QUEUE} frames, got {queue} (a camera's extra frames only add "
            "latency; a file waits for the tracker whatever the queue)",
        )
    retry_initial = positive("daemon", "retry_initial_s", 0.5, 3600.0)
    retry_max = positive("daemon", "retry_max_s", 10.0, 3600.0)
    if retry_max < retry_initial:
        raise fail("daemon.retry_max_s", "must be >= daemon.retry_initial_s")
    socket = Path(get("daemon", "socket", str, str(DEFAULT_SOCKET)))
    if not socket.is_absolute():
        socket = path.parent / socket
    return DaemonConfig(
        path=path,
        source=source if pointer else "",
        tracker=tracker,
        sink=sink,
        screen=mapping,
        tracker_options=tracker_options,
        calibration=calibration,
        filter=filt,
        buttons=buttons,
        sink_options=sink_options,
        socket=socket,
        queue=queue,
        retry_initial_s=retry_initial,
        retry_max_s=retry_max,
        streams=streams,
        pointer=pointer,
    )


def _kind_name(kind: type | tuple[type, ...]) -> str:
    names = {
        str: "a string",
        int: "an integer",
        float: "a number",
        dict: "a table",
        bool: "true/false",
    }
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if set(kinds) == {int, float}:
        return "a number"
    return " or ".join(names.get(k, k.__name__) for k in kinds)

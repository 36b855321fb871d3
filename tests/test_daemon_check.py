"""``omnidev daemon --check`` resolves a configuration as the real start does.

Each configuration below is one the real start refuses or crashes on (unknown
plugins, plugin options out of range or non-finite, missing devices and files,
a record sink with no path, ...): ``--check`` must exit 2 with one line naming
the configuration key, and the valid base configuration must pass (exit 0)
without writing anything. The same configurations are then started for real
(Daemon(...).run is not needed: the constructor opens tracker, buttons and sink
as the start does) to show that --check and the start agree.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from omnidev.cli.main import main
from omnidev.daemon.config import load_config
from omnidev.daemon.pipeline import Pipeline
from omnidev.errors import OmnidevError

REPO = Path(__file__).resolve().parents[1]


def base_config(folder: Path) -> dict[str, dict]:
    shutil.copy(REPO / "fixtures" / "blob" / "blob.avi", folder / "blob.avi")
    return {
        "source": {"uri": "video:blob.avi"},
        "tracker": {"name": "bright-blob", "options": {"threshold": 200}},
        "filter": {"kind": "one-euro", "min_cutoff": 0.1, "beta": 20.0, "d_cutoff": 2.0},
        "sink": {"name": "record", "options": {"path": "pointer.jsonl"}},
        "screen": {"rect": "1920x1080+0+0"},
        "daemon": {"socket": "control.sock"},
    }


def to_toml(doc: dict[str, dict]) -> str:
    lines = []
    for section, table in doc.items():
        lines.append(f"[{section}]")
        subs = {k: v for k, v in table.items() if isinstance(v, dict)}
        for k, v in table.items():
            if not isinstance(v, dict):
                lines.append(f"{k} = {_value(v)}")
        for k, sub in subs.items():
            lines.append(f"[{section}.{k}]")
            lines += [f"{kk} = {_value(vv)}" for kk, vv in sub.items()]
    return "\n".join(lines) + "\n"


def _value(v: object) -> str:
    if isinstance(v, float) and v != v:
        return "nan"
    if isinstance(v, float) and v in (float("inf"), -float("inf")):
        return "inf" if v > 0 else "-inf"
    return json.dumps(v)


NAN, INF = float("nan"), float("inf")

# (what, section, key, value or None to delete, words the error must name)
KINDS = [
    ("unknown tracker", "tracker", "name", "bright-blbo", "tracker.name"),
    ("unknown sink", "sink", "name", "recrd", "sink.name"),
    ("record sink without path", "sink", "options", {}, "sink.options"),
    ("record sink path in a missing folder", "sink", "options", {"path": "no/such/dir/p.jsonl"},
     "sink.options"),
    ("record sink path is a folder", "sink", "options", {"path": "."}, "sink.options"),
    ("record sink unknown option", "sink", "options", {"path": "p.jsonl", "pth": 1},
     "sink.options"),
    ("uinput sink, device missing", "sink", "options", {"device": "/nonexistent/uinput"},
     "sink.options"),
    ("uinput resolution 0", "sink", "options", {"resolution": 0}, "sink.options"),
    ("hidg sink, gadget missing", "sink", "options", {"device": "/nonexistent/hidg0"},
     "sink.options"),
    ("xtest sink, no X server", "sink", "options", {"display": ":97"}, "sink.options"),
    ("tracker unknown option", "tracker", "options", {"thresold": 200}, "tracker ("),
    ("tracker threshold NaN", "tracker", "options", {"threshold": NAN}, "tracker ("),
    ("tracker threshold inf", "tracker", "options", {"threshold": INF}, "tracker ("),
    ("tracker threshold out of range", "tracker", "options", {"threshold": 300},
     "tracker ("),
    ("tracker min_area 0", "tracker", "options", {"min_area": 0}, "tracker ("),
    ("tracker press_area < min_area", "tracker", "options", {"min_area": 20, "press_area": 5},
     "tracker ("),
    ("tracker threshold a string", "tracker", "options", {"threshold": "200"}, "tracker ("),
    ("bright-blob given a calibration", "tracker", "calibration", "blob.avi", "tracker ("),
    ("tracker calibration missing", "tracker", "calibration", "nothere.yml", "tracker.calibration"),
    ("filter min_cutoff inf", "filter", "min_cutoff", INF, "filter.min_cutoff"),
    ("filter beta NaN", "filter", "beta", NAN, "filter.beta"),
    ("filter d_cutoff 1e308", "filter", "d_cutoff", 1e308, "filter.d_cutoff"),
    ("filter kind unknown", "filter", "kind", "kalman", "filter.kind"),
    ("button device missing (evdev)", "buttons", "input",
     "evdev:/dev/input/event99?KEY_SPACE=left", "buttons.input"),
    ("button device missing (HID)", "buttons", "input", "hid:0001:0002?key.0x4e=left",
     "buttons.input"),
    ("button spec malformed", "buttons", "input", "evdev:", "buttons.input"),
    ("dwell time inf", "buttons", "dwell_s", INF, "buttons.dwell_s"),
    ("dwell radius NaN", "buttons", "dwell_radius_px", NAN, "buttons.dwell_radius_px"),
    ("video source missing", "source", "uri", "video:nothere.avi", "source.uri"),
    ("unknown source scheme", "source", "uri", "mystery:thing", "source.uri"),
    ("video rate inf", "source", "uri", "video:blob.avi?rate=inf", "source.uri"),
    ("v4l2 fps NaN", "source", "uri", "v4l2:/dev/video0?fps=nan", "source.uri"),
    ("v4l2 node is not a camera", "source", "uri", "v4l2:/dev/zero", "source.uri"),
    ("socket path is a file", "daemon", "socket", "blob.avi", "daemon.socket"),
    ("queue 0", "daemon", "queue", 0, "daemon.queue"),
    ("screen rect 0x0", "screen", "rect", "0x0+0+0", "screen.rect"),
    ("camera-mouse without its layout", "tracker", "name", "camera-mouse", "tracker ("),
]  # fmt: skip


def write(folder: Path, section: str, key: str, value: object) -> Path:
    doc = base_config(folder)
    doc.setdefault(section, {})[key] = value
    if key == "options" and section == "sink" and value and "path" not in value:
        # uinput/hidg/xtest options: name the sink they belong to
        doc["sink"]["name"] = (
            "uinput" if "resolution" in value or "uinput" in str(value)
            else "hidg" if "hidg" in str(value) else "xtest"
        )  # fmt: skip
    path = folder / "omnidev.toml"
    path.write_text(to_toml(doc))
    return path


def test_base_config_passes_and_writes_nothing(tmp_path, capsys):
    path = write(tmp_path, "filter", "kind", "one-euro")
    assert main(["daemon", "--config", str(path), "--check"]) == 0
    out = capsys.readouterr().out
    assert "ok (video:" in out and "sink record: appends JSON lines" in out
    assert not (tmp_path / "pointer.jsonl").exists() and not (tmp_path / "control.sock").exists()


@pytest.mark.parametrize("what,section,key,value,names", KINDS, ids=[k[0] for k in KINDS])
def test_check_refuses(tmp_path, capsys, what, section, key, value, names):
    path = write(tmp_path, section, key, value)
    assert main(["daemon", "--config", str(path), "--check"]) == 2, what
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "error:" in err, err
    assert names in err and str(path) in err, err
    # the real start refuses it too (configuration, tracker, buttons, sink: as Pipeline opens)
    with pytest.raises(OmnidevError):
        config = load_config(path)
        pipeline = Pipeline(config)
        try:
            from omnidev.daemon.check import check_config

            check_config(config)  # the source and socket parts the start retries or binds
        finally:
            pipeline.stop()


def test_at_least_32_kinds():
    assert len(KINDS) >= 32

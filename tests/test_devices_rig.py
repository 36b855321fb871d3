"""``omnidev devices`` over a fake sysfs, and rig files."""

from __future__ import annotations

import argparse

import pytest

from omnidev.cli import devices_cmd
from omnidev.devices import list_video_devices
from omnidev.rig import RigError, load_rig
from tests.test_sources import fake_usb_camera


def test_devices_listing(tmp_path, capsys):
    sysfs, dev = tmp_path / "sys", tmp_path / "dev"
    dev.mkdir()
    fake_usb_camera(sysfs, 0, "046d", "0826", "ABC123")
    fake_usb_camera(sysfs, 1, "046d", "0826", "ABC123", index=1)
    (dev / "video0").write_text("")
    devices = list_video_devices(sysfs, dev)
    assert [d.node for d in devices] == [str(dev / "video0"), str(dev / "video1")]
    assert devices[0].usb_id == "046d:0826:ABC123" and devices[0].capture
    assert devices[0].card == "HD Webcam C525" and devices[0].node_exists
    assert not devices[1].capture and not devices[1].node_exists
    assert devices_cmd.run(argparse.Namespace(sysfs=str(sysfs), dev=str(dev))) == 0
    out = capsys.readouterr().out
    assert "046d:0826:ABC123" in out and "HD Webcam C525" in out and "(no /dev node)" in out


def test_devices_none(tmp_path, capsys):
    assert devices_cmd.run(argparse.Namespace(sysfs=str(tmp_path), dev=str(tmp_path))) == 0
    assert "no V4L2 capture devices found" in capsys.readouterr().out


def test_rig_files(tmp_path):
    rig = tmp_path / "hall.toml"
    rig.write_text('[camera]\nname = "hall"\nusb = "046d:0826"\ncalibration = "hall.yml.gz"\n')
    r = load_rig(rig)
    assert r.name == "hall" and r.source_uri == "usb:046d:0826"
    assert r.calibration == tmp_path / "hall.yml.gz"
    rig.write_text('[camera]\nsource = "video:/x.avi"\ncalibration = "/abs/c.yml"\n')
    r = load_rig(rig)
    assert (
        r.source_uri == "video:/x.avi" and str(r.calibration) == "/abs/c.yml" and r.name == "hall"
    )
    for text, msg in [
        ('[camera]\ncalibration = "c.yml"\n', "exactly one of camera.source or camera.usb"),
        ('[camera]\nsource = "a"\nusb = "b"\ncalibration = "c"\n', "exactly one of"),
        ('[camera]\nsource = "a"\n', "missing key camera.calibration"),
        ('[camera]\nsource = 3\ncalibration = "c"\n', "camera.source must be a string"),
        ('[camera]\nsource = "a"\ncalibration = "c"\nlens = "x"\n', "unknown key camera.lens"),
        ("[camera\n", "not valid TOML"),
        ("x = 1\n", r"missing table \[camera\]"),
    ]:
        rig.write_text(text)
        with pytest.raises(RigError, match=msg):
            load_rig(rig)
    with pytest.raises(RigError, match="rig file not found"):
        load_rig(tmp_path / "none.toml")

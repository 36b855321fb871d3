"""Frame sources over real files (videos and images written here with OpenCV) and a fake sysfs."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.errors import SourceError
from omnidev.sources import open_source, split_uri
from omnidev.sources.usb import parse_usb_id, resolve_usb
from omnidev.sources.v4l2 import parse_v4l2_options


def write_video(path: Path, n: int = 10) -> list[np.ndarray]:
    frames = []
    w = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 10, (64, 48))
    for i in range(n):
        img = np.full((48, 64, 3), 20 * i + 5, np.uint8)
        cv2.putText(img, str(i), (10, 35), cv2.FONT_HERSHEY_SIMPLEX, 1, (255, 255, 255), 2)
        w.write(img)
        frames.append(img)
    w.release()
    return frames


def test_video_frames_indices_and_timestamps(tmp_path):
    truth = write_video(tmp_path / "v.avi")
    with open_source(str(tmp_path / "v.avi")) as src:
        assert src.frame_count == 10 and src.fps == pytest.approx(10) and not src.live
        frames = list(src)
    assert [f.index for f in frames] == list(range(10))
    ts = [f.timestamp_ns for f in frames]
    assert all(b > a for a, b in itertools.pairwise(ts))
    for f, t in zip(frames, truth, strict=True):
        assert np.abs(f.image.astype(int) - t).mean() < 4  # MJPG round trip


def test_truncated_video_names_the_frame(tmp_path):
    write_video(tmp_path / "v.avi")
    data = (tmp_path / "v.avi").read_bytes()
    (tmp_path / "t.avi").write_bytes(data[: len(data) * 6 // 10])
    with open_source(f"video:{tmp_path / 't.avi'}") as src:
        it = iter(src)
        with pytest.raises(
            SourceError, match=r"frame \d is corrupt or missing.*last good frame \d"
        ):
            for _ in it:
                pass


def test_corrupt_frame_in_the_middle_is_reported_with_its_index(tmp_path):
    write_video(tmp_path / "v.avi")
    data = bytearray((tmp_path / "v.avi").read_bytes())
    soi = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xD8]
    assert len(soi) == 10
    data[soi[5] : soi[5] + 400] = bytes(400)  # wipe frame 5's JPEG header
    (tmp_path / "c.avi").write_bytes(bytes(data))
    seen = []
    with pytest.raises(SourceError, match="frame 5 is corrupt or missing.*last good frame 4"):
        with open_source(str(tmp_path / "c.avi")) as src:
            for f in src:
                seen.append(f.index)
    assert seen == [0, 1, 2, 3, 4]


def test_images_glob_folder_and_single(tmp_path):
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"im{i}.png"), np.full((8, 8, 3), i * 50, np.uint8))
    for uri in (f"images:{tmp_path}/*.png", str(tmp_path), f"{tmp_path}/im*.png"):
        with open_source(uri) as src:
            frames = list(src)
        assert [int(f.image.mean()) for f in frames] == [0, 50, 100]
        assert src.frame_count == 3
    with open_source(str(tmp_path / "im1.png")) as src:
        assert [int(f.image.mean()) for f in src] == [50]
    (tmp_path / "im3.png").write_bytes(b"not a png")
    with pytest.raises(SourceError, match=r"cannot read image .*im3.png \(frame 3\)"):
        with open_source(str(tmp_path)) as src:
            list(src)
    with pytest.raises(SourceError, match="no images match"):
        open_source(f"images:{tmp_path}/*.jpg")


def test_uri_parsing_and_errors(tmp_path):
    assert split_uri("v4l2:/dev/video2?width=640&height=480") == (
        "v4l2",
        "/dev/video2",
        {"width": "640", "height": "480"},
    )
    assert split_uri("/some/file.mp4")[0] == "video"
    assert split_uri("frames/*.png")[0] == "images"
    with pytest.raises(SourceError, match="no plugin for source scheme 'rtsp'.*installed: images"):
        open_source("rtsp://camera/stream")
    with pytest.raises(SourceError, match="file not found"):
        open_source(str(tmp_path / "missing.mp4"))
    with pytest.raises(SourceError, match="unknown option 'speed'"):
        open_source(f"video:{tmp_path / 'x.avi'}?speed=2")
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"\x00" * 100)
    with pytest.raises(SourceError, match="cannot read this file as a video"):
        open_source(str(bad))


def test_v4l2_options_and_missing_device():
    uri = "v4l2:/dev/video0"
    assert parse_v4l2_options(
        uri, {"width": "1280", "height": "720", "fps": "30", "fourcc": "MJPG"}
    ) == {"width": 1280, "height": 720, "fps": 30.0, "fourcc": "MJPG"}
    for opts, msg in [
        ({"width": "-1"}, "positive integer"),
        ({"fps": "x"}, "positive number"),
        ({"fourcc": "MJPEG"}, "4 characters"),
        ({"gain": "1"}, "unknown option"),
    ]:
        with pytest.raises(SourceError, match=msg):
            parse_v4l2_options(uri, opts)
    with pytest.raises(SourceError, match="no such device node"):
        open_source("v4l2:/dev/video99")


def fake_usb_camera(
    sysfs: Path, n: int, vid: str, pid: str, serial: str | None, index: int = 0, bus: str = "1-2"
) -> None:
    usbdev = sysfs / "devices" / "pci0000:00" / "usb1" / bus
    intf = usbdev / f"{bus}:1.0"
    intf.mkdir(parents=True, exist_ok=True)
    (usbdev / "idVendor").write_text(vid + "\n")
    (usbdev / "idProduct").write_text(pid + "\n")
    if serial:
        (usbdev / "serial").write_text(serial + "\n")
    node = intf / "video4linux" / f"video{n}"
    node.mkdir(parents=True)
    (node / "name").write_text("HD Webcam C525\n")
    (node / "index").write_text(f"{index}\n")
    os.symlink(intf, node / "device")
    cls = sysfs / "class" / "video4linux"
    cls.mkdir(parents=True, exist_ok=True)
    os.symlink(node, cls / f"video{n}")


def test_usb_resolution_through_sysfs(tmp_path):
    sysfs = tmp_path / "sys"
    fake_usb_camera(sysfs, 0, "046d", "0826", "ABC123")
    fake_usb_camera(sysfs, 1, "046d", "0826", "ABC123", index=1)  # metadata node
    fake_usb_camera(sysfs, 2, "1bcf", "2c99", None, bus="1-3")
    dev = tmp_path / "dev"
    assert resolve_usb("046d:0826", sysfs, dev) == str(dev / "video0")
    assert resolve_usb("046D:0826:ABC123", sysfs, dev) == str(dev / "video0")
    assert resolve_usb("1bcf:2c99", sysfs, dev) == str(dev / "video2")
    with pytest.raises(SourceError, match=r"no such USB camera \(USB cameras present: 046d:0826"):
        resolve_usb("046d:0826:OTHER", sysfs, dev)
    with pytest.raises(SourceError, match="USB cameras present: none"):
        resolve_usb("046d:0826", tmp_path / "empty", dev)
    assert parse_usb_id("046D:0825") == ("046d", "0825", None)
    with pytest.raises(SourceError, match="4-digit hex"):
        parse_usb_id("46d:825")


def test_a_frame_of_another_size_is_refused_naming_it(tmp_path):
    """A damaged MJPEG whose frame 5 says 65 px wide in its JPEG header (fuzz seed 37: PyAV
    asserted "width has to be even" on the 4:2:0 planes, a traceback). PyAV's reader and the
    batch range reader refuse it naming the frame; frames 0..4 come first."""
    from omnidev.batch.avrange import index_video, read_range
    from omnidev.sources.avfile import AvVideoSource

    write_video(tmp_path / "v.avi")
    data = bytearray((tmp_path / "v.avi").read_bytes())
    sof = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xC0]
    assert len(sof) == 10
    assert data[sof[5] + 7 : sof[5] + 9] == b"\x00\x40"  # FF C0, length, precision, h, w = 64
    data[sof[5] + 7 : sof[5] + 9] = b"\x00\x41"
    bad = tmp_path / "w.avi"
    bad.write_bytes(bytes(data))
    said = r"video:.*w.avi: frame 5 is 65x48, not the stream's 64x48"
    for layout in ("native", "bgr"):
        src = AvVideoSource(bad)
        assert src.native_layout in ("yuv420p", "yuvj420p")  # the layout PyAV asserted on
        seen = []
        with pytest.raises(SourceError, match=said):
            for f in src.frames(src.native_layout if layout == "native" else layout):
                seen.append(f.index)
        src.close()
        assert seen == [0, 1, 2, 3, 4]
    whole = index_video(bad, 100).ranges[0]
    with pytest.raises(SourceError, match=said):
        list(read_range(bad, whole, "bgr"))

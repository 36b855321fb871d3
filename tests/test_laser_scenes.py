"""The laser scenes' truth: a spot is judged visible on the radiance and delivered on
the encoded frame against the same frames encoded without the laser."""

from __future__ import annotations

import dataclasses

from omnidev.sim.codec import Compression
from omnidev.sim.laser_scenes import LaserScene


def _visible_delivered(seed: int, comp: Compression) -> tuple[int, int]:
    sc = LaserScene(seed, frames=20)
    sc.scene = dataclasses.replace(sc.scene, compression=comp)
    truths = [t for _, t in sc.frames()]
    assert all(t.visible for t in truths if t.delivered)
    return sum(t.visible for t in truths), sum(t.delivered for t in truths)


def test_uncompressed_spots_are_all_delivered() -> None:
    # seed 1006: 320x240, a 2.5 px colour-only red spot; 12 of its 20 frames show it
    visible, delivered = _visible_delivered(1006, Compression("none"))
    assert visible == 12 and delivered == visible


def test_a_codec_that_washes_the_spot_out_leaves_it_visible_but_not_delivered() -> None:
    # H.264 at 0.005 bits per pixel: the 2.5 px spot no longer raises the red channel
    # by VISIBLE_RISE anywhere near its centre in any frame
    visible, delivered = _visible_delivered(1006, Compression("h264", bits_per_pixel=0.005))
    assert visible == 12 and delivered == 0

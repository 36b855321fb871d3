"""The randomized screen scenes (omnidev.sim.screen_scenes): truth, rendering, light, codecs."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from omnidev.sim.codec import Compression, compress_frames
from omnidev.sim.screen_scenes import (
    FrameInput,
    SceneRanges,
    SceneRenderer,
    capture_stills,
    draw_scene,
    render_sequence,
)

SMALL = SceneRanges(resolutions=((640, 480),), occluder_prob=0.0, crop_prob=0.0)


@pytest.mark.parametrize("seed", range(8))
def test_truth_round_trip(seed: int) -> None:
    sc = draw_scene(seed)
    W, H = sc.screen_px
    xy = np.stack(np.meshgrid(np.linspace(0, W - 1, 9), np.linspace(0, H - 1, 7)), -1)
    xy = xy.reshape(-1, 2)
    uv = sc.screen_to_image(xy)
    ok = np.isfinite(uv).all(axis=1)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(sc.image_to_screen(uv[ok]), xy[ok], atol=1e-6)


def test_scenes_cover_the_issue_ranges() -> None:
    scenes = [draw_scene(s) for s in range(60)]
    k1 = [s.camera.k1 for s in scenes]
    ang = [max(abs(s.yaw_deg), abs(s.pitch_deg)) for s in scenes]
    assert min(k1) < -0.25 and max(k1) > 0.12
    assert max(ang) > 28
    assert {s.compression.codec for s in scenes} == {"none", "jpeg", "mpeg4", "h264"}
    assert {s.screen_kind for s in scenes} == {"monitor", "projector"}
    assert {s.classes()["camera"] for s in scenes} == {"<640x480", ">=640x480"}
    gammas = [s.display_gamma for s in scenes] + [s.camera_gamma for s in scenes]
    assert 1.8 <= min(gammas) < 1.9 and 2.3 < max(gammas) <= 2.4
    assert any(s.occluder is not None for s in scenes)
    assert sum(len(s.objects) for s in scenes) > 100
    again = draw_scene(17)
    assert again.to_dict() == scenes[17].to_dict()  # deterministic from the seed


TINY = SceneRanges(
    resolutions=((320, 240),), screen_resolutions=((2560, 1440),), occluder_prob=0.0, crop_prob=0.0
)


@pytest.mark.parametrize(("seed", "ranges"), [(3, SMALL), (11, SMALL), (4, TINY)])
def test_rendered_disc_lands_where_the_truth_says(seed: int, ranges: SceneRanges) -> None:
    """A small white disc on a black screen: its image centroid (white minus black,
    noise-free sums) is the truth's image of the disc centre within 0.1 px (0.03 px for
    the tiny camera, whose content goes through the pre-filter's mip levels)."""
    sc = replace(draw_scene(seed, ranges), compression=Compression("none"), defocus_px=0.0)
    r = SceneRenderer(sc)
    tiny = ranges is TINY
    assert (r.mip >= 2) == tiny
    W, H = sc.screen_px
    x, y = 0.3 * W + 0.37, 0.6 * H - 0.21
    black = np.zeros((H, W, 3), np.uint8)
    disc = black.copy()
    rad = 40 if tiny else 12
    cv2.circle(disc, (round(x * 16), round(y * 16)), 16 * rad, (255, 255, 255), -1, cv2.LINE_AA, 4)
    diff = (r.radiance(disc) - r.radiance(black))[..., 1]
    uv = sc.screen_to_image(np.array([[x, y]]))[0]
    u0, v0 = int(uv[0]), int(uv[1])
    win = diff[v0 - 15 : v0 + 16, u0 - 15 : u0 + 16].astype(np.float64)
    gy, gx = np.mgrid[v0 - 15 : v0 + 16, u0 - 15 : u0 + 16]
    c = np.array([(win * gx).sum(), (win * gy).sum()]) / win.sum()
    # the disc's image centroid is off the image of its centre by the perspective bias
    # (tiny for a 12 px disc); the box filter and sub-pixel sampling add no shift
    assert np.hypot(*(c - uv)) < (0.03 if tiny else 0.1), (c, uv)


def test_red_spot_clips_red_only() -> None:
    """A pure-red laser light 30x the display's white: red clips at 255, green and blue
    stay below (each channel clips on its own)."""
    sc = replace(
        draw_scene(5, SMALL),
        compression=Compression("none"),
        bloom=(0.0, 0.0, 1.0),
        flare=(0.0, 10.0),
        bayer=False,
        sharpen=0.0,
        colour_gain=(1.0, 1.0, 1.0),
    )
    r = SceneRenderer(sc)
    W, H = sc.screen_px
    x0, y0 = 0.5 * W, 0.5 * H

    def spot(xy: np.ndarray) -> np.ndarray:
        d2 = (xy[:, 0] - x0) ** 2 + (xy[:, 1] - y0) ** 2
        level = 30.0 * np.exp(-d2 / (2 * 6.0**2))
        return np.stack([0.004 * level, 0.008 * level, level], axis=1)

    grey = np.full((H, W, 3), 128, np.uint8)
    img = r.render(grey, extra_light=spot, extra_light_bbox=(x0 - 40, y0 - 40, x0 + 40, y0 + 40))
    uv = sc.screen_to_image(np.array([[x0, y0]]))[0]
    u, v = round(uv[0]), round(uv[1])
    px = img[v, u]
    assert px[2] == 255 and px[1] < 250 and px[0] < 250, px
    plain = r.render(grey)
    assert np.array_equal(img[: v - 30], plain[: v - 30])  # the light stays in its window


def test_timed_extra_light_sees_rolling_shutter() -> None:
    """extra_light_t receives each sample's time: row 0 starts at the frame's time, the
    last row readout_s later (the sample sits in the middle of each row's exposure)."""
    sc = replace(draw_scene(2, SMALL), readout_s=0.02, compression=Compression("none"))
    r = SceneRenderer(sc)
    seen: list[np.ndarray] = []

    def light(xy: np.ndarray, t: np.ndarray) -> np.ndarray:
        seen.append(t.copy())
        return np.zeros((len(xy), 3))

    W, H = sc.screen_px
    r.radiance(np.zeros((H, W), np.uint8), 1.0, extra_light_t=light)
    t = np.concatenate(seen) - 1.0 - 0.5 * sc.exposure_s  # one sample: mid-exposure
    assert -0.001 < t.min() < 0.001 and 0.019 < t.max() < 0.0201, (t.min(), t.max())


def test_auto_exposure_brightens_the_room_in_the_black_capture() -> None:
    sc = replace(draw_scene(4, SMALL), ae_strength=1.0, ae_lag=1.0, compression=Compression("none"))
    W, H = sc.screen_px
    white, black = capture_stills(
        sc, [np.full((H, W), 255, np.uint8), np.zeros((H, W), np.uint8)], frames_per_still=2
    )
    r = SceneRenderer(sc)
    off = r.cover < 0.01
    assert np.mean(black[off]) > np.mean(white[off]) + 3  # auto-exposure raised the gain


@pytest.mark.parametrize("codec", ["jpeg", "mpeg4", "h264"])
def test_codecs_round_trip_with_loss(codec: str) -> None:
    sc = replace(draw_scene(6, SMALL), compression=Compression("none"))
    W, H = sc.screen_px
    content = np.zeros((H, W, 3), np.uint8)
    cv2.putText(content, "omnidev", (100, H // 2), cv2.FONT_HERSHEY_SIMPLEX, 8, (255, 200, 60), 20)
    caps = render_sequence(sc, [FrameInput(content, k / 30) for k in range(6)])
    frames = [c.image for c in caps]
    comp = Compression(codec, quality=60, bits_per_pixel=0.05)
    out = compress_frames(frames, comp)
    assert len(out) == len(frames) and out[0].shape == frames[0].shape
    err = np.abs(out[-1].astype(np.int16) - frames[-1]).astype(np.float64)
    psnr = 10 * np.log10(255**2 / max(np.mean(err**2), 1e-9))
    assert 24 < psnr < 60, psnr  # lossy, but the picture survives

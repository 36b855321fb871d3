"""The colour laser detector (omnidev.laser.colour_spot), the laser eval task on a small
sample of randomized scenes (seeds 700004, 700018, 700024, 700037: test seeds, neither
the tuning range 1000-1019 nor the reported range 500000+), the laser's filter default
and the tracker's options.

The sample's figures are regression bounds at the measured values (``pytest -s``
prints them); issue 12's acceptance (>= 99 % of spot frames) is NOT met by either
detector on these scenes: docs/laser-pointer.md gives the evaluation's figures.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from omnidev.daemon.config import parse_config
from omnidev.errors import TrackerError
from omnidev.evaluation.framework import load_task
from omnidev.evaluation.tasks.laser import miss_cause, on_moving_content
from omnidev.filters import OneEuroFilter
from omnidev.laser.colour_spot import ColourSpotDetector, _fit_beams
from omnidev.sim.laser_scenes import LaserScene, LaserTruth, ref_scale, screen_mask
from omnidev.sim.screen import Spot, render, screen_rig
from omnidev.sim.screen_content import slide
from omnidev.tracking import open_tracker

SAMPLE = (700004, 700018, 700024, 700037)


@pytest.fixture(scope="module")
def sample() -> dict[int, dict[str, int]]:
    task = load_task("laser")
    opts = dict(task.options, frames=30)
    out = {}
    for seed in SAMPLE:
        res = task.run_scene(seed, opts, None)
        assert res.status == "ok"
        out[seed] = dict(res.counts)
        print(f"\nscene {seed} {res.classes}: {res.counts}")
    return out


def test_sample_colour_beats_white_core(sample: dict[int, dict[str, int]]) -> None:
    hit = sum(c["hit"] for c in sample.values())
    spot = sum(c["spot"] for c in sample.values())
    ohit = sum(c["other.hit"] for c in sample.values())
    assert spot == sum(c["other.spot"] for c in sample.values()) > 40
    print(f"\ncolour {hit}/{spot}, white-core {ohit}/{spot} spot frames within tolerance")
    assert hit >= ohit + 0.2 * spot  # the colour detector finds what needs no white core
    # measured 46 / 67 (69 %) with the beam fitted in three channels (42 / 67 in the
    # laser channel alone; 33 / 67 before the beam fit, min_rise, fringe_ratio and
    # hold_spot; the sim's encoders run on one thread, so it is repeatable)
    assert hit >= 0.65 * spot


def test_sample_false_spots(sample: dict[int, dict[str, int]]) -> None:
    off = sum(c["off"] for c in sample.values())
    false = sum(c["false"] for c in sample.values())
    assert off >= 4 * 8  # the lead-in at least
    assert false == 0


def test_sample_every_spot_frame_not_within_has_one_cause(
    sample: dict[int, dict[str, int]],
) -> None:
    for counts in sample.values():
        causes = sum(v for k, v in counts.items() if k.startswith("cause."))
        assert causes == counts["missed"] + counts["far"]
        far = sum(v for k, v in counts.items() if k.startswith("cause.far: "))
        assert far == counts["far"]
        assert counts["false.moving"] + counts["false.still"] == counts["false"]


def test_false_spots_on_moving_content_are_told_apart() -> None:
    sc = LaserScene(700024, frames=30)  # a scene with a video window and a drifting blob
    boxes = sc.moving_boxes(20)
    (vx0, vy0, vx1, vy1), (dx0, dy0, dx1, dy1) = boxes
    assert (vx1 - vx0, vy1 - vy0) == (461, 388)  # the video window, screen px
    assert dx1 - dx0 == dy1 - dy0 < 20  # the drifting blob
    assert sc.moving_boxes(0)[1] != boxes[1]  # it drifts
    assert on_moving_content(sc, 20, np.array([0.5 * (vx0 + vx1), 0.5 * (vy0 + vy1)]))
    assert on_moving_content(sc, 20, np.array([vx1 + 15.0, vy0]))  # within 1 % of 1920 px
    assert not on_moving_content(sc, 20, np.array([vx1 + 25.0, vy0]))
    assert on_moving_content(sc, 20, np.array([0.5 * (dx0 + dx1), 0.5 * (dy0 + dy1)]))
    assert not on_moving_content(sc, 0, np.array([0.5 * (dx0 + dx1), 0.5 * (dy0 + dy1)]))
    assert not on_moving_content(LaserScene(700004, frames=30), 20, np.array([960.0, 540.0]))


def _dark_rig_frames(n: int, *, spot: bool) -> list[np.ndarray]:
    rig = screen_rig((640, 480), 0.1)
    content = slide("dark", 1920, 1080, 0.0)
    frames = [render(rig, content, frame_seed=0)]
    for i in range(n):
        s = Spot(600.0 + 9 * i, 500.0, "red", 6.0, 1.0) if spot else None
        frames.append(render(rig, content, spot=s, frame_seed=i + 1))
    return frames


def test_first_frame_only_starts_the_model() -> None:
    """No spot is reported on the first frame (nothing to compare with), one is from
    the next frame on when it moves."""
    det = ColourSpotDetector("red")
    frames = _dark_rig_frames(6, spot=True)
    assert det.detect(frames[0]) is None
    found = [det.detect(f) for f in frames[1:]]
    assert all(s is not None for s in found)


def test_confirm_withholds_a_new_track_one_frame() -> None:
    """confirm=2: a spot is reported from the second frame in a row it is found on."""
    frames = _dark_rig_frames(6, spot=True)
    det = ColourSpotDetector("red", confirm=2)
    assert det.detect(frames[0]) is None
    found = [det.detect(f) for f in frames[1:]]
    assert found[0] is None and all(s is not None for s in found[1:])
    ref = ColourSpotDetector("red")
    ref.detect(frames[0])
    first = [ref.detect(f) for f in frames[1:]]
    for a, b in zip(found[1:], first[1:], strict=True):
        assert a is not None and b is not None and (a.u, a.v) == (b.u, b.v)


def _busy_then_spot(n: int) -> tuple[list[np.ndarray], tuple[float, float]]:
    """Content that flickers (darker every other frame, as a video) for 8 frames in a
    96 x 96 px box where the spot then appears, and n frames with the spot."""
    spot_frames = _dark_rig_frames(n, spot=True)
    probe = ColourSpotDetector("red")
    probe.detect(spot_frames[0])
    first = probe.detect(spot_frames[1])
    assert first is not None
    u, v = round(first.u), round(first.v)
    video = []
    for i in range(8):
        f = spot_frames[0].copy()
        if i % 2:
            box = f[v - 48 : v + 48, u - 48 : u + 48]
            box //= 2
        video.append(f)
    return [spot_frames[0], *video, *spot_frames[1:]], (first.u, first.v)


def test_busy_confirm_withholds_a_track_starting_in_a_busy_region() -> None:
    """busy_confirm=2 (the default): a spot whose track starts where content moves is
    reported from its second frame; busy_confirm=1 reports it at once. Elsewhere the
    default reports at once (test_first_frame_only_starts_the_model)."""
    frames, (u, v) = _busy_then_spot(4)
    found = {}
    for bc in (1, 2):
        det = ColourSpotDetector("red", busy_confirm=bc)
        found[bc] = [det.detect(f) for f in frames]
        assert all(s is None for s in found[bc][:9])  # no spot in the flicker
    one, two = found[1][9:], found[2][9:]
    assert one[0] is not None and math.hypot(one[0].u - u, one[0].v - v) < 0.5
    assert two[0] is None and all(s is not None for s in two[1:])
    for a, b in zip(one[1:], two[1:], strict=True):
        assert a is not None and b is not None and (a.u, a.v) == (b.u, b.v)
    with pytest.raises(ValueError, match="busy_confirm 1..10"):
        ColourSpotDetector("red", busy_confirm=0)


def test_hold_spot_keeps_a_spot_out_of_the_model() -> None:
    """A spot held still over content that flickers darker every other frame (a video
    under it): where the frame got darker the model takes the frame's pixels, and
    without ``hold_spot`` the spot's own pixels with them, so it is lost for good; with
    it (the default) the spot is found on every frame after the first flicker."""
    rig = screen_rig((640, 480), 0.1)
    content = slide("dark", 1920, 1080, 0.0)
    frames = [render(rig, content, frame_seed=0)]
    for i in range(12):
        s = Spot(600.0 + 0.5 * i, 500.0, "red", 6.0, 1.0)
        frames.append(render(rig, content, spot=s, frame_seed=i + 1))
    probe = ColourSpotDetector("red")
    probe.detect(frames[0])
    first = probe.detect(frames[1])
    assert first is not None
    u, v = round(first.u), round(first.v)
    for f in frames[2::2]:  # the 60 x 60 px around the spot darker, the spot as it was
        box = f[v - 30 : v + 30, u - 30 : u + 30]
        spot = (box.astype(np.int16) - frames[0][v - 30 : v + 30, u - 30 : u + 30]).max(axis=2) > 20
        dark = box // 2
        dark[spot] = box[spot]
        box[:] = dark
    found = {}
    for hold in (True, False):
        det = ColourSpotDetector("red", hold_spot=hold)
        found[hold] = [det.detect(f) is not None for f in frames]
    assert found[True][3:] == [True] * 10  # measured: every frame from the 4th on
    assert not any(found[False][3:])  # measured: none


def _scene_errors(seed: int, **options: object) -> tuple[list[float | None], int]:
    """Per spot frame of randomized laser scene ``seed`` (30 frames), the error (screen
    px of a 1920x1080 screen) as a fraction of the frame's tolerance (None: no spot),
    and the number of false spots."""
    sc = LaserScene(seed, frames=30)
    k = ref_scale(sc.scene)
    det = ColourSpotDetector(sc.laser.colour, screen_mask(sc.scene), **options)  # type: ignore[arg-type]
    errors: list[float | None] = []
    false = 0
    for img, t in sc.frames():
        s = det.detect(img)
        if not t.on:
            false += s is not None
        elif t.visible and t.xy is not None:
            if s is None:
                errors.append(None)
                continue
            xy = sc.scene.image_to_screen(np.array([[s.u, s.v]]))[0]
            errors.append(float(np.hypot(*((xy - np.asarray(t.xy)) * k))) / t.tol_px)
    return errors, false


def test_spot_on_a_page_of_its_own_colour() -> None:
    """Randomized scene 1020 (tuning range; 320x240, H.264, a green laser on a green
    page whose green channel the camera shows at 228-235, a video window): the spot
    clips green but rises it by only 20-26 grey levels, so with ``bright_rise`` off no
    clipped pixel of it is new and it is never found; with the default the other two
    channels' rise (40-80 grey levels: the laser's light leaking into them) makes it
    new. Measured: 21 of 21 spot frames within tolerance against 0, and no false
    spot on its spot-off frames either way."""
    figures = {}
    for bright in (0, 10):
        errors, false = _scene_errors(1020, bright_rise=bright)
        hit = sum(e is not None and e <= 1.0 for e in errors)
        figures[bright] = (hit, len(errors), false)
    assert figures[0] == (0, 21, 0)
    assert figures[10][1:] == (21, 0) and figures[10][0] >= 19
    with pytest.raises(ValueError, match="bright_rise 0..254"):
        ColourSpotDetector("green", bright_rise=255)


def test_a_new_spot_is_not_taken_into_the_model() -> None:
    """Randomized scene 1046 (tuning range; 320x240, MPEG-4, a green white-core spot on
    a dark slide): on the frame the spot appears, the codec's chroma bleed darkens the
    red and blue channels around it, and the model's fix for darker content used to
    take the spot's left half in with them before the frame was searched; the spot was
    then placed from its right half, 1.3-1.7 image px off (frames 15-18: 10.8-23.5
    screen px against a tolerance of 6.7). Searched first, every spot frame is within
    tolerance (measured: 17 of 17, the largest error 0.94 of the tolerance)."""
    errors, false = _scene_errors(1046)
    assert len(errors) == 17 and false == 0
    assert all(e is not None and e <= 1.0 for e in errors), errors


def test_static_content_never_fires() -> None:
    det = ColourSpotDetector("any")
    assert all(det.detect(f) is None for f in _dark_rig_frames(10, spot=False))


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="colour must be one of"):
        ColourSpotDetector("blue")
    with pytest.raises(ValueError, match="min_area"):
        ColourSpotDetector("red", min_area=5, max_area=2)
    with pytest.raises(ValueError, match="confirm 1..10"):
        ColourSpotDetector("red", confirm=0)
    with pytest.raises(ValueError, match="new_margin"):
        ColourSpotDetector("red", new_margin=0)
    with pytest.raises(ValueError, match="min_rise"):
        ColourSpotDetector("red", min_rise=-1.0)
    with pytest.raises(ValueError, match="fringe_ratio"):
        ColourSpotDetector("red", fringe_ratio=-0.5)
    with pytest.raises(ValueError, match="peak_margin 0..255"):
        ColourSpotDetector("red", peak_margin=256)
    det = ColourSpotDetector("red", np.ones((10, 10), bool))
    with pytest.raises(ValueError, match="mask is 10x10, image 20x10"):
        det.detect(np.zeros((10, 20, 3), np.uint8))


def test_beam_fit_is_not_bent_by_the_content_under_the_spot() -> None:
    """A beam half on a dark page, half on one that leaves its channel little room
    below clipping: the clipped blob's centroid is pulled toward the bright side, the
    censored Gaussian fit (position "beam") is not. Synthetic, exact truth."""
    yy, xx = np.mgrid[0:41, 0:41].astype(np.float64)
    cu, cv_, amp, sig = 20.3, 19.6, 4.0, 3.0
    content = np.where(xx > 20.0, 0.8, 0.05)  # linear light of the page, laser channel
    room = 1.0 - content
    beam = amp * np.exp(-((xx - cu) ** 2 + (yy - cv_) ** 2) / (2 * sig**2))
    obs = np.minimum(room, beam)
    cens = beam >= room
    blob_u = float(xx[cens].mean())
    assert blob_u - cu > 1.0  # the clipped blob reaches further over the bright page
    start = np.array([blob_u, float(yy[cens].mean()), math.log(2.0), math.log(3.0), 0.0])
    one = (room.reshape(1, -1), cens.reshape(1, -1))  # one channel: K = 1
    fit = _fit_beams(xx.ravel(), yy.ravel(), obs.reshape(1, -1), *one, start)
    assert fit is not None  # it stops once the centre moves < 0.05 px: measured 0.045 off
    assert math.hypot(fit[0] - cu, fit[1] - cv_) < 0.05
    noisy = obs + np.random.default_rng(3).normal(0.0, 0.01, obs.shape)
    fit = _fit_beams(xx.ravel(), yy.ravel(), noisy.reshape(1, -1), *one, start)
    assert fit is not None and math.hypot(fit[0] - cu, fit[1] - cv_) < 0.1


def test_beam_fit_in_three_channels_where_the_laser_channel_has_little_room() -> None:
    """A beam on a page of the laser's own colour (its channel 0.9 of white in linear
    light, so it clips over most of the spot) that also reaches the other two channels
    (crosstalk 0.25 and 0.15, dark there): fitting the three channels about one centre
    (``beam_channels`` 3) is about 3x closer than the laser channel alone over 20 noise
    draws (measured RMS 0.032 px against 0.094). Synthetic, exact truth."""
    yy, xx = np.mgrid[0:41, 0:41].astype(np.float64)
    cu, cv_, amp, sig = 20.3, 19.6, 4.0, 3.0
    beam = amp * np.exp(-((xx - cu) ** 2 + (yy - cv_) ** 2) / (2 * sig**2))
    content = np.where(xx > 14.0, 0.9, 0.05)
    room = np.stack([1.0 - content, np.full(xx.shape, 0.95), np.full(xx.shape, 0.9)])
    light = np.stack([beam, 0.25 * beam, 0.15 * beam])
    cens = light >= room
    x, y = xx.ravel(), yy.ravel()
    start1 = np.array([18.0, 18.0, math.log(2.0), math.log(3.0), 0.0])
    start3 = np.array([18.0, 18.0, *[math.log(2.0), math.log(3.0), 0.0] * 3])
    e1, e3 = [], []
    for seed in range(20):
        obs = np.minimum(room, light) + np.random.default_rng(seed).normal(0, 0.03, light.shape)
        f1 = _fit_beams(
            x, y, obs[:1].reshape(1, -1), room[:1].reshape(1, -1), cens[:1].reshape(1, -1), start1
        )
        f3 = _fit_beams(x, y, obs.reshape(3, -1), room.reshape(3, -1), cens.reshape(3, -1), start3)
        assert f1 is not None and f3 is not None
        e1.append(math.hypot(f1[0] - cu, f1[1] - cv_))
        e3.append(math.hypot(f3[0] - cu, f3[1] - cv_))
    rms1, rms3 = float(np.sqrt(np.mean(np.square(e1)))), float(np.sqrt(np.mean(np.square(e3))))
    assert rms3 < 0.05 and rms3 < 0.5 * rms1
    with pytest.raises(ValueError, match="beam_channels 1 or 3"):
        ColourSpotDetector("red", beam_channels=2)


def test_one_euro_max_gap_restarts() -> None:
    f = OneEuroFilter(0.1, 20.0, 2.0, max_gap_s=0.1)
    f(0.0, [0.0, 0.0])
    f(1 / 30, [0.0, 0.0])
    out = f(0.5, [0.5, 0.5])  # found again elsewhere after 0.47 s: not blended
    assert np.allclose(out, [0.5, 0.5])
    old = OneEuroFilter(0.1, 20.0, 2.0)  # without max_gap_s: the original filter
    old(0.0, [0.0, 0.0])
    old(1 / 30, [0.0, 0.0])
    assert old(0.5, [0.5, 0.5])[0] < 0.5
    with pytest.raises(ValueError, match="max_gap_s"):
        OneEuroFilter(max_gap_s=0.0)


def test_laser_filter_defaults(tmp_path: Path) -> None:
    doc = {"source": {"uri": "x"}, "tracker": {"name": "laser-pointer"}, "sink": {"name": "r"}}
    cfg = parse_config(doc, tmp_path / "c.toml")
    assert (cfg.filter.min_cutoff, cfg.filter.max_gap_s) == (1.5, 0.1)
    doc["tracker"] = {"name": "camera-mouse"}
    cfg = parse_config(doc, tmp_path / "c.toml")
    assert (cfg.filter.min_cutoff, cfg.filter.max_gap_s) == (0.1, 0.0)
    doc["tracker"] = {"name": "laser-pointer"}
    doc["filter"] = {"max_gap_s": 0.25}
    assert parse_config(doc, tmp_path / "c.toml").filter.max_gap_s == 0.25


def test_tracker_method_options(tmp_path: Path) -> None:
    cases = [
        ({"method": "fast"}, "method must be one of colour, white-core"),
        ({"method": "colour", "core": 200}, "unknown option 'core' for method 'colour'"),
        ({"busy_frames": 3}, "it is an option of method 'colour'"),
        ({"method": "colour", "saturated": "high"}, "saturated must be a whole number"),
        ({"method": "colour", "halo": True}, "halo must be a number"),
        ({"method": "colour", "hold_spot": "maybe"}, "hold_spot must be true or false"),
        ({"method": "colour", "peak_margin": 2.5}, "peak_margin must be a whole number"),
        # a good flag passes the option checks: the missing calibration is what stops it
        ({"method": "colour", "hold_spot": "false"}, "screen calibration .* does not exist"),
    ]
    for options, text in cases:
        with pytest.raises(TrackerError, match=text) as info:
            open_tracker("laser-pointer", options, tmp_path / "absent.yml")
        assert "\n" not in str(info.value)


def _spot_truth(u: float, v: float) -> LaserTruth:
    return LaserTruth(1, True, (0.0, 0.0), (u, v), True, 1.5, 0.0, False)


def test_a_missed_spot_names_why() -> None:
    """Each missed spot frame names its cause (``omnidev eval laser``'s "by cause"):
    a blob at the spot that failed a test names the test, a spot whose new track awaits
    confirmation says so, a spot too faint to clip its channel is "not clipped"."""
    frames, (u, v) = _busy_then_spot(3)
    det = ColourSpotDetector("red", busy_gain=1000.0)  # no ring is that strong
    assert all(det.detect(f) is None for f in frames[:9])
    assert det.detect(frames[9]) is None
    assert [why for box, why in det.rejected if box[0] <= v < box[1] and box[2] <= u < box[3]]
    assert miss_cause(det, frames[9], _spot_truth(u, v), 4.0, 2, refused=False) == (
        "rejected: busy"
    )
    two = _dark_rig_frames(3, spot=True)
    det = ColourSpotDetector("red", confirm=2)
    det.detect(two[0])
    assert det.detect(two[1]) is None and det.unconfirmed
    assert miss_cause(det, two[1], _spot_truth(u, v), 4.0, 2, refused=False) == "unconfirmed"
    assert det.detect(two[2]) is not None and not det.unconfirmed
    rig = screen_rig((640, 480), 0.1)
    content = slide("dark", 1920, 1080, 0.0)
    faint = [render(rig, content, frame_seed=0)]
    faint.append(render(rig, content, spot=Spot(600.0, 500.0, "red", 6.0, 0.02), frame_seed=1))
    det = ColourSpotDetector("red")
    det.detect(faint[0])
    assert det.detect(faint[1]) is None
    up = faint[1][:, :, 2].astype(np.int16) - faint[0][:, :, 2]
    fv, fu = np.unravel_index(np.argmax(up), up.shape)
    assert up[fv, fu] >= 15 and faint[1][fv, fu, 2] < det.saturated  # the spot is there
    truth = _spot_truth(float(fu), float(fv))
    assert miss_cause(det, faint[1], truth, 4.0, 2, refused=False) == "not clipped"
    assert miss_cause(det, faint[1], truth, 4.0, 2, refused=True) == "refused"

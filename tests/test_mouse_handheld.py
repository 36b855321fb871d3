"""Randomized hand-held camera-mouse videos (omnidev.sim.handheld) and a small sample of
``omnidev eval mouse`` with real assertions (issue 13).

The sample's seeds are from the tuning range (0-59); the figures reported for the issue
come from seeds 10000 and up, never looked at while tuning (docs/camera-mouse.md).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from omnidev.evaluation.framework import evaluate, load_task
from omnidev.mouse.detect import DetectParams, detect_landmarks, rigid_plane_error
from omnidev.mouse.evaluate import cursor_error_px
from omnidev.mouse.geometry import (
    cursor_homography,
    homography_from_4_points,
    image_center,
    screen_corners_from_landmarks,
)
from omnidev.sim.handheld import KINDS, HandheldRenderer, draw_video, write_video


def test_draws_cover_the_ranges_of_the_issue():
    """200 draws: every kind and resolution, roll to 30 degrees, 45 degrees off-axis,
    blur bounds up to 25 px, excursions, rolling and global shutters."""
    vids = [draw_video(s, frames=300) for s in range(200)]
    assert {v.kind for v in vids} == set(KINDS)
    sizes = {(v.camera.width, v.camera.height) for v in vids}
    assert (320, 240) in sizes and (1280, 720) in sizes and (640, 480) in sizes
    assert max(abs(float(r)) for v in vids for r in v.path.roll) > 25.0
    assert max(v.max_blur_px for v in vids) > 24.0
    assert any(k == "excursion" for v in vids for _, k in v.path.segments)
    shutters = {v.imaging.readout_s > 0 for v in vids}
    assert shutters == {True, False}
    # obliqueness: the camera's offset from the screen normal through the screen centre
    off = []
    for v in vids:
        c = np.array([v.layout.screen_width_mm / 2000, v.layout.screen_height_mm / 2000, 0])
        d = v.path.cam - c
        off.append(np.degrees(np.arccos(np.abs(d[:, 2]) / np.linalg.norm(d, axis=1))).max())
    assert max(off) > 40.0
    assert {v.monitor.content_kind for v in vids if v.monitor is not None} >= {
        "desktop", "document", "dark", "slide", "photo", "saturated", "video",
    }  # fmt: skip


def test_truth_is_exact_for_a_pinhole_global_shutter_camera():
    """With distortion and rolling shutter turned off, the homography of the truth's
    landmark positions puts the image centre on the truth's screen point (< 0.6 px:
    the truth counts screen pixel centres, the corners' unit square their edges)."""
    v = draw_video(6, frames=60)
    cam = dataclasses.replace(v.camera, k1=0.0, k2=0.0, k3=0.0, p1=0.0, p2=0.0)
    v = dataclasses.replace(v, camera=cam, imaging=dataclasses.replace(v.imaging, readout_s=0.0))
    r = HandheldRenderer(v)
    errs = []
    for i in range(0, 60, 2):
        t = r.truth(i)
        if sum(t["visible"]) < 4 or not t["on_screen"]:
            continue
        uv = np.array(t["landmarks_uv"])
        c = cursor_homography(
            screen_corners_from_landmarks(uv, v.layout), image_center(cam.width, cam.height)
        )
        errs.append(cursor_error_px(c, t["screen_xy"]))
    assert len(errs) >= 6
    assert max(errs) < 0.6


def test_rendered_landmarks_sit_where_the_truth_puts_them():
    """Detection on a still first frame finds every disc within 0.4 px of the truth."""
    v = draw_video(6, frames=30)
    r = HandheldRenderer(v)
    img, t = r.render(0), r.truth(0)
    det = detect_landmarks(img, v.layout)
    assert det is not None
    d = np.linalg.norm(det.centers - np.array(t["landmarks_uv"]), axis=1)
    print(f"\nseed 6 frame 0: detection vs truth {np.round(d, 3).tolist()} px")
    assert d.max() < 0.4


def test_rigid_plane_check_rejects_a_square_quad_for_a_wide_layout():
    """A 40x40 px quad (a text window's corners) is no view of a 16:9 layout under any
    focal length of 30-120 degrees; a perspective view of the layout is."""
    v = draw_video(6, frames=30)
    lay = v.layout
    w, h = v.camera.width, v.camera.height
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    frange = (w / 2 / math.tan(math.radians(60)), w / 2 / math.tan(math.radians(15)))
    square = np.array([[300.0, 200.0], [340.0, 200.0], [340.0, 240.0], [300.0, 240.0]])
    bad, _ = rigid_plane_error(homography_from_4_points(lay.landmark_centers_mm(), square),
                               centre, frange)  # fmt: skip
    r = HandheldRenderer(v)
    good_uv = np.array(r.truth(10)["landmarks_uv"])
    good, f = rigid_plane_error(homography_from_4_points(lay.landmark_centers_mm(), good_uv),
                                centre, frange)  # fmt: skip
    print(f"\nrigid-plane error: square quad {bad:.3f}, true view {good:.4f} (f {f:.0f} px)")
    assert bad > 0.3
    assert good < 0.05


def test_write_video_gives_a_fixture_folder(tmp_path):
    out = tmp_path / "v"
    doc = write_video(47, out, frames=4)
    assert (out / "mouse.avi").stat().st_size > 0
    assert json.loads((out / "landmarks.json").read_text())["circle_diameter_mm"] > 0
    assert len(doc["per_frame"]) == 4 and doc["video"]["seed"] == 47


@pytest.fixture(scope="module")
def sample():
    """``omnidev eval mouse`` on seeds 45-49 (tuning range), 60 frames each."""
    task = load_task("mouse")
    opts = {"frames": 60, "configs": "default,calibrated,translation"}
    return evaluate(task, scenes=5, seed=45, options=opts, progress=False)


def test_eval_sample_no_false_cursors_and_accurate_cursors(sample):
    """Seeds 45, 47 (look-alike cards, 47 with four on a layout-shaped rectangle: it
    once locked) and 48 (no monitor) give no cursor; 46 and 49 (monitors at 640x480
    and 1280x720) give cursors on nearly every on-screen frame, within bounds."""
    per = {r["seed"]: r for r in sample["per_scene"]}
    assert sample["pooled"]["errors"] == 0
    for s in (45, 47, 48):
        assert per[s]["classes"]["kind"] in ("lookalikes", "no-monitor")
        assert per[s]["counts"]["false_cursors"] == 0
    for s in (46, 49):
        m = per[s]["metrics"]
        print(f"\nseed {s}: {per[s]['classes']}, all-four RMS {m.get('all4.rms')}, "
              f"cursor rate {m.get('cursor_rate')}")  # fmt: skip
        assert per[s]["classes"]["kind"] == "normal"
        assert m["cursor_rate"] >= 0.9
        # the default tracker knows neither lens nor rolling shutter (measured 2.51 and
        # 2.08 px); given the video camera's calibration and readout time, 0.89 and 0.54
        assert m["all4.rms"] <= 3.0
        assert m["calibrated.all4.rms"] <= 2.0
        assert m["calibrated.cursor_rate"] >= 0.9
        assert per[s]["counts"]["gross_errors"] == 0
    summary = sample["summary"]
    names = {a["name"]: a for a in summary["acceptance"]}
    assert names["cursors on videos with look-alikes only"]["passed"]
    assert "translation" in summary["configs (same frames)"]


def test_slide_content_on_a_small_screen_texture():
    """A slide on a texture under 200 px (a small screen far away: held-out seed 20014
    crashed in screen_content's slide) is drawn larger and scaled down."""
    from omnidev.sim.handheld_textures import screen_content

    for seed in range(64):  # every slide kind, the photo (which needs 200 px) among them
        c = screen_content(np.random.default_rng(seed), 300, 150, kind="slide")
        assert c.base.shape == (150, 300, 3)
        assert float(c.base.std()) > 0.02  # content (linear 0-1), not a blank


def assert_detected_only_by_the_change(
    seed: int, before: DetectParams, step: int, min_frames: int, blurred_px: float = 0.3
) -> None:
    """On the frames (every ``step``-th of 100) of video ``seed`` with the four landmarks
    in view, detection with ``before`` finds nothing and with the defaults finds all four,
    each within 0.3 px of the truth (``blurred_px`` under 2 px of motion blur or more)."""
    video = draw_video(seed, frames=100)
    r = HandheldRenderer(video)
    frames = [i for i in range(0, 100, step) if all(r.truth(i)["visible"])]
    assert len(frames) >= min_frames
    for i in frames:
        img = r.render(i)
        assert detect_landmarks(img, video.layout, before) is None, f"frame {i}"
        found = detect_landmarks(img, video.layout)
        assert found is not None, f"frame {i}"
        true_uv = np.array(r.truth(i)["landmarks_uv"])
        bound = 0.3 if r.truth(i)["blur_px"] < 2.0 else blurred_px
        assert float(np.hypot(*(found.centers - true_uv).T).max()) < bound, f"frame {i}"


def test_border_step_sampled_farther_out_finds_landmarks_the_nearest_samples_missed() -> None:
    """Tuning video 103 (640x480): with the colour step sampled only at the nearest
    offset (``border_step_scales=(1.0,)``, the code before) no side of the true landmark
    group stepped and no frame was detected; with 1.5 x and 2 x too every frame is,
    each landmark within 0.3 px of the truth."""
    # (and straight borders: a bent one at the nearest offset finds some of these frames)
    nearest_only = dataclasses.replace(DetectParams(), border_step_scales=(1.0,), border_bends=())
    assert_detected_only_by_the_change(103, nearest_only, step=5, min_frames=15)


def test_a_white_bezel_next_to_a_white_page_votes_with_the_faint_edge_map() -> None:
    """Tuning video 231 (640x360, a light grey bezel, a white slide): the colour steps
    across the screen border on every side, but by 12-20 grey levels, under the edge
    map's Canny thresholds (30 / 90) on three sides; no frame was detected
    (``faint_canny=None``, the code before). With the faint map (10 / 30) on those
    sides every frame with the four in view is, each landmark within 0.3 px (1 px
    under 4-10 px of motion blur)."""
    one_map = dataclasses.replace(DetectParams(), faint_canny=None)
    assert_detected_only_by_the_change(231, one_map, step=3, min_frames=10, blurred_px=1.0)


def test_a_tracked_set_that_is_no_longer_a_flat_rectangle_goes_back_to_detection() -> None:
    """Tuning video 137 (640x360): predictions drifted and tracked windows caught content
    while the tracked quadrilateral still passed the convexity and side checks: all-four
    RMS 70 px, max 285 px (``max_rigid_error=0``, the code before). Checked against the
    detection's rigid-plane bound, such a set is dropped and detected again. (Measured
    with the rotation prediction, the default when this was found: flow, the default
    since, does not drift off on this video, max 26 px without the check.)"""
    from omnidev.evaluation.tasks.mouse import run_video

    rot = {"predict": "rotation"}
    configs = {"checked": rot, "off": {**rot, "max_rigid_error": 0}}
    res = run_video(137, frames=100, configs=configs)
    new, old = res["errors"]["checked"].errors["all4"], res["errors"]["off"].errors["all4"]
    assert max(old) > 100  # the failure this guards against is in this video
    assert len(new) >= 0.9 * len(old)  # nearly every frame keeps its cursor
    assert float(np.sqrt(np.mean(np.square(new)))) < 2.0
    assert max(new) < 5.0


def test_flow_takes_no_features_on_a_playing_video() -> None:
    """Tuning video 189 (320x240, a video playing on the screen): with features taken on
    the screen, the playing video carried the monitor plane's fit and the frames with one
    or two landmarks predicted had the cursor 46.9 px RMS off; with the screen left out
    (the plugin's ``flow.exclude``, from the layout) the fit follows the bezel, cards and
    wall: 8.8 px."""
    import tempfile
    from pathlib import Path

    from omnidev.frame import Frame
    from omnidev.mouse.evaluate import video_errors
    from omnidev.tracking import open_tracker

    video = draw_video(189, frames=100)
    assert video.describe()["monitor"]["content"] == "video"
    r = HandheldRenderer(video)
    with tempfile.TemporaryDirectory() as tmp:
        layout = Path(tmp) / "landmarks.json"
        layout.write_text(json.dumps(video.layout_dict()))
        trackers = {n: open_tracker("camera-mouse", {}, layout) for n in ("off", "on")}
    trackers["on"].tracker.flow.exclude = None  # features on the screen too (before)
    cursors: dict[str, list] = {n: [] for n in trackers}
    truth = []
    for i in range(100):
        img = r.render(i)
        truth.append(r.truth(i))
        for n, t in trackers.items():
            s = t.track(Frame(img, round(i / video.imaging.fps * 1e9), i))
            cursors[n].append(None if s is None else (s.x, s.y))
    pred = {
        n: video_errors(c, truth, kind=video.kind).errors["predicted"] for n, c in cursors.items()
    }
    rms = {n: float(np.sqrt(np.mean(np.square(e)))) for n, e in pred.items()}
    print(f"\nvideo 189, one or two predicted: screen left out {rms['off']:.1f} px "
          f"({len(pred['off'])} frames), features on the screen {rms['on']:.1f} px")  # fmt: skip
    assert len(pred["off"]) >= 40
    assert rms["on"] > 30.0  # the failure this guards against is in this video
    assert rms["off"] < 12.0


def test_landmarks_coming_back_while_coasting_are_judged_by_the_plane() -> None:
    """Tuning video 151: flow coasts through frames with fewer than two landmarks found;
    two come back. When landmarks coming back were exempt from the plane's check there
    too, the cursor stayed about 48 px off for 20 frames (37.7 px RMS over 37 predicted
    frames); judged by the plane while coasting, 2.8 px over 15."""
    from omnidev.evaluation.tasks.mouse import run_video

    res = run_video(151, frames=100, configs={"default": {}})
    pred = res["errors"]["default"].errors["predicted"]
    print(f"\nvideo 151, one or two predicted: {len(pred)} frames, RMS "
          f"{float(np.sqrt(np.mean(np.square(pred)))):.2f} px, max {max(pred):.1f}")  # fmt: skip
    assert len(pred) >= 10
    assert float(np.sqrt(np.mean(np.square(pred)))) < 5.0
    assert max(pred) < 15.0


def test_a_relock_gives_flow_the_frame_it_was_detected_on() -> None:
    """Video 50270 (held out, then looked at): detection re-locked on frame 97 after a
    stretch without a lock; the tracker still held a frame from before, and on frame 98
    flow took the plane's motion from that stale frame to the new one: the windows went
    astray and the cursor was 971 px off. Locked with its own frame, every all-four frame
    is within a few px."""
    from omnidev.evaluation.tasks.mouse import run_video

    res = run_video(50270, frames=100, configs={"default": {}})
    all4 = res["errors"]["default"].errors["all4"]
    print(f"\nvideo 50270, all four visible: {len(all4)} frames, max {max(all4):.2f} px")
    assert len(all4) >= 30
    assert max(all4) < 10.0


def test_exact_reference_is_the_floor_set_by_lens_and_shutter() -> None:
    """``configs=exact``: the cursor from the truth's landmark positions. Without lens
    distortion and rolling shutter it is the truth (< 0.6 px, as above); on video 1 as
    drawn (640x480, k1 -0.12, 32 ms readout) it is 2.9 px RMS with all four visible, over
    issue 13's 2 px: no tracker of the landmark centres without a lens and shutter model
    can do better there."""
    from omnidev.evaluation.tasks.mouse import exact_cursors, run_video
    from omnidev.mouse.evaluate import video_errors

    v = draw_video(6, frames=60)
    cam = dataclasses.replace(v.camera, k1=0.0, k2=0.0, k3=0.0, p1=0.0, p2=0.0)
    v = dataclasses.replace(v, camera=cam, imaging=dataclasses.replace(v.imaging, readout_s=0.0))
    r = HandheldRenderer(v)
    truth = [r.truth(i) for i in range(60)]
    e = video_errors(exact_cursors(v, truth), truth, kind=v.kind)
    assert len(e.errors["all4"]) >= 20 and max(e.errors["all4"]) < 0.6

    res = run_video(1, frames=150, configs={"exact": {}})
    exact = np.asarray(res["errors"]["exact"].errors["all4"])
    assert res["errors"]["exact"].cursors["all4"] == res["errors"]["exact"].frames["all4"]
    rms = float(np.sqrt(np.mean(exact**2)))
    assert 2.5 < rms < 3.3, rms  # measured 2.91


def test_a_strong_barrel_lens_bends_the_border_and_detection_follows() -> None:
    """Tuning video 225 (640x480, k1 -0.45): the screen border bows out 10-16 px from the
    straight line between the corners the landmarks predict, so two sides neither stepped
    nor showed an edge there and no frame was detected (``border_bends=()``, the code
    before: a cursor on 0 of 68 frames that wanted one in the evaluation). Bent borders
    find the landmarks on most frames, each within 1 px of the truth (measured 0.22-0.80
    px: the lens distorts the discs too)."""
    straight = dataclasses.replace(DetectParams(), border_bends=())
    video = draw_video(225, frames=100)
    r = HandheldRenderer(video)
    frames = [i for i in range(0, 100, 5) if all(r.truth(i)["visible"])]
    assert len(frames) >= 6
    found_frames = 0
    for i in frames:
        img = r.render(i)
        assert detect_landmarks(img, video.layout, straight) is None, f"frame {i}"
        found = detect_landmarks(img, video.layout)
        if found is None:
            continue
        found_frames += 1
        true_uv = np.array(r.truth(i)["landmarks_uv"])
        assert float(np.hypot(*(found.centers - true_uv).T).max()) < 1.0, f"frame {i}"
    assert found_frames >= len(frames) - 2, (found_frames, len(frames))  # measured 5 of 7


def test_shares_count_a_video_without_a_cursor_beyond_the_bound() -> None:
    """The acceptance's shares of videos within 2 px (>= 640) / 4 px (320x240) see only
    videos with a cursor on frames with all four landmarks visible; the shares beside
    them count a video with such frames but no cursor as beyond the bound."""
    from omnidev.evaluation.framework import SceneResult
    from omnidev.evaluation.tasks.mouse import summarize

    def video(seed: int, size: str, rms: float | None) -> SceneResult:
        camera = ">=640" if size != "320x240" else size
        r = SceneResult(seed, classes={"kind": "normal", "size": size, "camera": camera})
        r.counts["all4.frames"] = 10
        if rms is not None:
            r.metrics["all4.rms"] = rms
        return r

    rs = [video(1, "640x480", 1.0), video(2, "640x480", 3.0), video(3, "1280x720", None),
          video(4, "320x240", 2.0), video(5, "320x240", None)]  # fmt: skip
    s = summarize(rs, {"configs": "default"})
    names = {a["name"]: a["value"] for a in s["acceptance"]}
    assert names["cameras >= 640 wide, all four visible: share of videos with RMS <= 2 px"] == 0.5
    assert names["320x240, all four visible: share of videos with RMS <= 4 px"] == 1.0
    strict = s["shares, a video without a cursor counted beyond"]
    assert strict[">=640 all4 RMS <= 2 px"] == pytest.approx(1 / 3)
    assert strict["320x240 all4 RMS <= 4 px"] == 0.5
    assert strict["videos >=640 / 320x240 with all four visible but no cursor"] == "1 / 1"
    cfg = s["configs (same frames)"]["default"]
    assert cfg["share >=640 all4 RMS <= 2 px, no cursor counted beyond"] == pytest.approx(1 / 3)

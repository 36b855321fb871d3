"""``camera-mouse`` tracker: the screen point under the image center of a hand-held webcam.

Dissertation ch. 6: the detection stage (sec. 6.2.1) finds the four corner
landmarks, the tracking stage (sec. 6.2.4) follows them with the eight-bar
circular template and predicts one or two missing ones (sec. 6.2.5); with three
or more missing the tracker reports nothing (the daemon holds the cursor) and
detects again on the next frame. The cursor is the image center in screen
coordinates, by the dissertation's affine correction (eqs. 6.1-6.4) or by the
homography of the four screen corners (``method``).

Re-detection when tracking confidence falls: while landmarks are being
predicted, the detection stage runs every ``redetect_every`` frames and
re-locks when it finds all four (predictions drift; a landmark back in the
picture may be far from its predicted place). A tracked set that is no longer a
plausible landmark quadrilateral (not convex, sides collapsed, or its shape
jumping between frames: a landmark captured by similar screen content) is
dropped at once and the same frame goes to detection; so is a set that is no
longer the image of the flat landmark rectangle through a pinhole camera
(``max_rigid_error``, default 0.15, the detection's own bound; 0 turns it off):
a prediction drifting off, or a landmark captured by content, bends it. Issue 13,
tuning videos 100-199: frames with a cursor 0.924 -> 0.906, gross errors 321 ->
100; held out 40000-40059: all-four pooled RMS 197 -> 5.4 px, cursor share
0.939 -> 0.919 (docs/camera-mouse.md).

Calibration file: the landmark layout (JSON or TOML with the keys of
:meth:`omnidev.mouse.landmarks.LandmarkLayout.to_dict`: screen size, landmark
offsets from the screen corners, circle and square sizes, all in mm).

Options: ``method`` ("homography", default, or the dissertation's "affine");
``predict`` ("flow", default: the monitor plane's motion from a reference frame, fitted
to features tracked on the bezel, the cards and the wall around them (not on the screen,
whose content can move) and the landmarks found, see :mod:`omnidev.mouse.flow`; the
missing landmarks are carried by the plane's homography or, where a camera turn with a
fitted focal length extrapolates the features nearest them better, by that turn; the
same image motion places the tracking windows and rejects hits off the plane's motion
during fast moves, and the landmarks keep following it for up to 2 s while fewer than
two are found; "rotation": the camera turning about its center, fitted to the landmarks
found (the default before 2026-12-06; flow's fallback); "similarity"; or the
dissertation's "translation"). Issue 13, held out 50100-50199, rotation -> flow: one or
two predicted, pooled RMS 41.5 -> 21.1 px, all four visible 23.7 -> 6.4 px, cursor
share 0.912 -> 0.919 (docs/camera-mouse.md);
``fov_deg`` (the webcam's horizontal field of view for "rotation", default 60);
``redetect_every`` (frames, default 5; 0 turns re-detection while predicting
off); ``camera``: the webcam's calibration (an OpenCV file with ``camera_matrix`` and
``distortion_coefficients``, as cv2.calibrateCamera tools write it, or ``K`` and ``D``):
the landmark centres and the image centre are undistorted before the homography, which
removes the lens's share of the error (docs/camera-mouse.md); ``readout_ms``: the
sensor's rolling-shutter readout time (rows top to bottom; default 0, a global shutter):
each landmark is brought back to the centre row's instant by its image velocity;
``screen_px`` ("WxH", default 1920x1080): the target screen's pixels, for the pointer's
pixel-centre convention (0 and 1 are the centres of the first and last pixel);
``max_rigid_error`` (above).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from omnidev import Frame, PointerSample
from omnidev.errors import ConfigError, TrackerError
from omnidev.inputfile import loads_json, loads_toml, read_text
from omnidev.mouse import DEFAULT_PREDICT, PREDICTIONS
from omnidev.mouse.detect import (
    DetectParams,
    detect_landmarks,
    focal_range_px,
    rigid_plane_error,
    to_gray,
)
from omnidev.mouse.geometry import (
    Lens,
    cursor_from_corners,
    edges_to_pixel_centres,
    homography_from_4_points,
    image_center,
    rolling_shutter_correct,
    screen_corners_from_landmarks,
)
from omnidev.mouse.landmarks import LandmarkLayout
from omnidev.mouse.track import LandmarkTracker


class CameraMouse:
    """Detection, tracking with prediction, and the cursor (see the module docstring)."""

    def __init__(
        self,
        layout: LandmarkLayout,
        method: str = "homography",
        predict: str = DEFAULT_PREDICT,
        redetect_every: int = 5,
        fov_deg: float = 60.0,
        *,
        lens: Lens | None = None,
        readout_ms: float = 0.0,
        screen_px: tuple[int, int] = (1920, 1080),
        max_rigid_error: float = 0.15,
    ) -> None:
        if method not in ("homography", "affine"):
            raise TrackerError(f"camera-mouse: method must be homography or affine, got {method!r}")
        if predict not in PREDICTIONS:
            raise TrackerError(
                f"camera-mouse: predict must be one of {', '.join(PREDICTIONS)}, got {predict!r}"
            )
        if not 10.0 <= fov_deg <= 170.0:
            raise TrackerError(f"camera-mouse: fov_deg must be 10..170 degrees, got {fov_deg}")
        if redetect_every < 0:
            raise TrackerError(f"camera-mouse: redetect_every must be >= 0, got {redetect_every}")
        if not 0.0 <= max_rigid_error <= 10.0:
            raise TrackerError(
                f"camera-mouse: max_rigid_error must be 0 (off) .. 10, got {max_rigid_error}"
            )
        self.max_rigid_error = max_rigid_error
        self.layout = layout
        self.method = method
        self.redetect_every = redetect_every
        self.fov_deg = fov_deg
        if not 0.0 <= readout_ms <= 200.0:
            raise TrackerError(f"camera-mouse: readout_ms must be 0..200 ms, got {readout_ms}")
        if min(screen_px) < 2:
            raise TrackerError(f"camera-mouse: screen_px must be at least 2x2, got {screen_px}")
        self.lens = lens
        self.readout_s = readout_ms / 1000.0
        self.screen_px = screen_px
        self._prev: tuple[NDArray[np.float64], int, NDArray[np.bool_]] | None = None
        self.tracker = LandmarkTracker(predict=predict)
        self.tracker.flow.exclude = lambda quad: screen_corners_from_landmarks(quad, layout)
        self.locked = False
        self.size: tuple[int, int] | None = None
        self._weak = 0  # consecutive frames with predicted landmarks
        self.relocks = 0  # re-detections that replaced a tracked set (for figures)

    def _radius_px(self, centers: NDArray[np.float64]) -> NDArray[np.float64]:
        """Each landmark's radius in pixels: its mm radius times the pixels per mm along
        the two sides that meet at it (an oblique view makes the far ones smaller)."""
        mm = self.layout.landmark_centers_mm()
        px_side = np.linalg.norm(np.roll(centers, -1, axis=0) - centers, axis=1)
        mm_side = np.linalg.norm(np.roll(mm, -1, axis=0) - mm, axis=1)
        scale = px_side / mm_side  # side i joins landmarks i and i + 1
        radii: NDArray[np.float64] = (
            self.layout.circle_diameter_mm / 2 * (scale + np.roll(scale, 1)) / 2
        )
        return radii

    def _rigid(self, centers: NDArray[np.float64]) -> bool:
        """Whether the tracked centres (TL, TR, BR, BL, px) are still the image of the
        flat landmark rectangle through a pinhole with square pixels and a focal length
        of the detection's field-of-view range, to within ``max_rigid_error`` (the
        detection's own check, looser: motion, shutter and lens bend a true set a little;
        one landmark captured by content or a drifting prediction bends it more)."""
        if self.max_rigid_error <= 0 or self.size is None:
            return True
        w, h = self.size
        focal = focal_range_px(w, DetectParams().fov_range_deg)
        hmat = homography_from_4_points(self.layout.landmark_centers_mm(), centers)
        err, _ = rigid_plane_error(hmat, image_center(w, h), focal)
        return bool(err <= self.max_rigid_error)

    def track(self, frame: Frame) -> PointerSample | None:
        sample = self._track(frame)
        if sample is None:
            self._prev = None
        return sample

    def _track(self, frame: Frame) -> PointerSample | None:
        h, w = frame.image.shape[:2]
        if self.size is None:
            self.size = (w, h)
            self.tracker.focal_px = (w / 2) / math.tan(math.radians(self.fov_deg) / 2)
            self.tracker.principal = ((w - 1) / 2, (h - 1) / 2)
            if self.lens is not None:
                if self.lens.size is not None and self.lens.size != (w, h):
                    raise TrackerError(
                        f"camera-mouse: frame {frame.index} is {w}x{h}, the camera "
                        f"calibration is for {self.lens.size[0]}x{self.lens.size[1]}"
                    )
                self.tracker.focal_px = float(self.lens.K[0, 0])
                self.tracker.principal = (float(self.lens.K[0, 2]), float(self.lens.K[1, 2]))
        elif self.size != (w, h):
            raise TrackerError(
                f"camera-mouse: frame {frame.index} is {w}x{h}, the stream was "
                f"{self.size[0]}x{self.size[1]}"
            )
        gray = to_gray(frame.image)
        centers: NDArray[np.float64] | None = None
        if self.locked:
            last = self.tracker.centers
            centers = self.tracker.update(gray)
            if centers is None:
                if self.tracker.coasting:
                    # held; the landmarks follow the monitor's image motion, and the
                    # detection stage looks for all four on every such frame
                    if self.redetect_every:
                        det = detect_landmarks(frame.image, self.layout)
                        if det is not None:
                            self.tracker.lock(det.centers, self._radius_px(det.centers), gray)
                            self.relocks += 1
                            return self._sample(frame, det.centers, w, h)
                    return None
                self.locked = False  # three or more missing: detect again next frame
                return None
            if not _plausible(centers, last, self.tracker.radius) or not self._rigid(centers):
                self.locked = False  # captured by something else: detect on this frame
                centers = None
            elif all(self.tracker.found):
                self._weak = 0
            else:
                self._weak += 1
                if self.redetect_every and self._weak % self.redetect_every == 0:
                    det = detect_landmarks(frame.image, self.layout)
                    if det is not None:
                        centers = det.centers
                        self.tracker.lock(centers, self._radius_px(centers), gray)
                        self._weak = 0
                        self.relocks += 1
        if not self.locked:
            det = detect_landmarks(frame.image, self.layout)  # colour edges help step 6
            if det is None:
                return None
            centers = det.centers
            self.tracker.lock(centers, self._radius_px(centers), gray)
            self.locked = True
            self._weak = 0
        assert centers is not None
        return self._sample(frame, centers, w, h)

    def _sample(
        self, frame: Frame, centers: NDArray[np.float64], w: int, h: int
    ) -> PointerSample | None:
        """The cursor sample of the landmark centres (TL, TR, BR, BL, px) of ``frame``."""
        # the discs' radii from the landmark geometry, for next frame's sub-pixel step
        self.tracker.disc_radii = self._radius_px(centers)
        found = np.array(self.tracker.found, bool)
        pts = np.asarray(centers, np.float64)
        if self.readout_s > 0 and self._prev is not None:
            prev, prev_ns, prev_found = self._prev
            dt = (frame.timestamp_ns - prev_ns) / 1e9
            if not 0.001 <= dt <= 0.5:  # no usable capture times: assume 30 fps
                dt = 1 / 30
            pts = rolling_shutter_correct(pts, prev, dt, self.readout_s, h, found & prev_found)
        self._prev = (np.asarray(centers, np.float64).copy(), frame.timestamp_ns, found)
        centre = image_center(w, h)
        if self.lens is not None:
            pts = self.lens.undistort(pts)
            centre = self.lens.undistort(centre[None])[0]
        corners = screen_corners_from_landmarks(pts, self.layout)
        uv = cursor_from_corners(corners, centre, method=self.method)  # type: ignore[arg-type]
        if not np.all(np.isfinite(uv)):
            return None
        uv = edges_to_pixel_centres(uv, self.screen_px)
        return PointerSample(
            float(uv[0]),
            float(uv[1]),
            frame.timestamp_ns,
            confidence=sum(self.tracker.found) / 4.0,
        )

    def reset(self) -> None:
        self.locked = False
        self._prev = None
        self.size = None
        self._weak = 0


def _plausible(
    centers: NDArray[np.float64], last: NDArray[np.float64] | None, radius: float
) -> bool:
    """Whether tracked centers (TL, TR, BR, BL, px) can still be the landmarks.

    The quadrilateral must stay convex and clockwise in the image (y down), no
    side may shrink below two landmark diameters, and no side may change its
    length by more than a third between frames (a hand cannot do that in 1/30 s;
    one landmark captured by screen content does).
    """
    d = np.roll(centers, -1, axis=0) - centers
    cross = d[:, 0] * np.roll(d, -1, axis=0)[:, 1] - d[:, 1] * np.roll(d, -1, axis=0)[:, 0]
    if not np.all(cross > 0):
        return False
    sides = np.linalg.norm(d, axis=1)
    if np.any(sides < 4 * radius):
        return False
    if last is not None:
        before = np.linalg.norm(np.roll(last, -1, axis=0) - last, axis=1)
        if np.any(np.abs(sides / np.maximum(before, 1e-9) - 1.0) > 1 / 3):
            return False
    return True


def load_layout(path: Path) -> LandmarkLayout:
    """The landmark layout of a JSON or TOML file; errors name the file and key."""
    what = "camera-mouse landmark layout"
    text = read_text(path, what, error=TrackerError)
    if path.suffix == ".toml":
        data = loads_toml(text, path, what, TrackerError)
    else:
        data = loads_json(text, path, what, TrackerError)
    try:
        return LandmarkLayout.from_dict(data)
    except ConfigError as exc:
        raise TrackerError(f"camera-mouse: {path}: {exc}") from None


_Num = TypeVar("_Num", int, float)


def _number(
    options: Mapping[str, Any], key: str, default: _Num, cast: type[_Num], what: str
) -> _Num:
    """Option ``key`` as ``cast`` (``default`` when absent); a one-line error naming it."""
    try:
        return cast(options.get(key, default))
    except (TypeError, ValueError):
        raise TrackerError(f"camera-mouse: {key} must be {what}, got {options[key]!r}") from None


def open_tracker(options: Mapping[str, Any], calibration: Path | None) -> CameraMouse:
    """Entry point: the calibration is the landmark layout file; option ``method``."""
    known = {
        "method", "predict", "redetect_every", "fov_deg", "camera", "readout_ms", "screen_px",
        "max_rigid_error",
    }  # fmt: skip
    unknown = set(options) - known
    if unknown:
        raise TrackerError(
            f"camera-mouse: unknown option {sorted(unknown)[0]!r} "
            f"(options: {', '.join(sorted(known))})"
        )
    readout = _number(options, "readout_ms", 0.0, float, "a number of ms")
    screen_px = _screen_px(options.get("screen_px", "1920x1080"))
    lens = None if options.get("camera") in (None, "") else load_lens(Path(str(options["camera"])))
    fov = _number(options, "fov_deg", 60.0, float, "a number of degrees")
    redetect = _number(options, "redetect_every", 5, int, "a whole number of frames")
    rigid = _number(options, "max_rigid_error", 0.15, float, "a number")
    if calibration is None:
        raise TrackerError(
            "camera-mouse: needs the landmark layout as its calibration file "
            '([tracker] calibration = "landmarks.json": screen size and landmark offsets in mm)'
        )
    return CameraMouse(
        load_layout(calibration),
        str(options.get("method", "homography")),
        str(options.get("predict", DEFAULT_PREDICT)),
        redetect,
        fov,
        lens=lens,
        readout_ms=readout,
        screen_px=screen_px,
        max_rigid_error=rigid,
    )


def _screen_px(value: Any) -> tuple[int, int]:
    """``screen_px`` as "WxH" or [W, H] -> (W, H); a clear error otherwise."""
    try:
        w, h = (int(v) for v in (value.lower().split("x") if isinstance(value, str) else value))
    except (TypeError, ValueError, AttributeError):
        raise TrackerError(
            f"camera-mouse: screen_px must be WxH pixels (e.g. 1920x1080), got {value!r}"
        ) from None
    return w, h


def load_lens(path: Path) -> Lens:
    """The webcam calibration of an OpenCV file (YAML, XML or JSON): ``camera_matrix`` (or
    ``K``), ``distortion_coefficients`` (or ``D``), optional ``image_width`` and
    ``image_height``; errors name the file and key."""
    from omnidev.calibfile import open_storage, read_mat
    from omnidev.errors import CalibrationError

    try:
        with open_storage(path) as fs:
            mats = {}
            for want in (("camera_matrix", "K"), ("distortion_coefficients", "D")):
                key = next((k for k in want if not fs.getNode(k).empty()), None)
                if key is None:
                    raise CalibrationError(f"{path}: missing key {want[0]!r} (or {want[1]!r})")
                mats[want[0]] = (key, read_mat(fs, path, key))
            size = None
            wn, hn = fs.getNode("image_width"), fs.getNode("image_height")
            if not wn.empty() and not hn.empty():
                size = (int(wn.real()), int(hn.real()))
    except CalibrationError as exc:
        raise TrackerError(f"camera-mouse: {exc}") from None
    kkey, K = mats["camera_matrix"]
    dkey, D = mats["distortion_coefficients"]
    if K.shape != (3, 3):
        raise TrackerError(f"camera-mouse: {path}: key {kkey!r} is not a 3x3 camera matrix")
    if D.size not in (4, 5, 8, 12, 14):
        raise TrackerError(
            f"camera-mouse: {path}: key {dkey!r} must hold 4, 5, 8, 12 or 14 coefficients"
        )
    return Lens(K, D, size)

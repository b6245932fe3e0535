"""Sequences: N frames of one scene with camera motion (a scene file's ``[sequence]`` table, issue 29).

The camera's motion is a homography H(t) from the *reference frame* (the static scene, as ``camsim render`` draws
it) to the sensor at time t: a scene point at reference pixel q is seen at sensor pixel p = H(t) q (pixel
coordinates: x the column, y the row, a pixel's centre at integers). Three motions compose,
``H(t) = P(t) · S(t) · Hᵢ``:

- **pan** ``pan_px_per_s = [vx, vy]``: a translation (vx · t, vy · t), t from the first frame's start;
- **shake** ``shake_px``, ``shake_deg``: a Gaussian random walk of translation (tx, ty) and rotation θ (about the
  frame's centre) with steps N(0, shake_px²) per axis and N(0, shake_deg²) at each frame interval: the pose is 0
  at t = 0, takes an independent step at every t = j · frame_interval_s (j ≥ 1), and in between moves linearly from
  one pose to the next (so the shake blurs within an exposure). Drawn from the scene's seed alone
  (:func:`shake_generator`), so a seed gives the same motion;
- **homographies** ``homographies``: one 3 × 3 matrix per frame, Hᵢ for frame i, constant over its exposure
  (no blur from it).

A frame i exposes [tᵢ, tᵢ + T], tᵢ = i · frame_interval_s, T the sensor's ``exposure_s`` (at most the interval).
Its expected signal electrons at sensor pixel p are the time average of the static scene's expectation along the
path, ``S̄ᵢ(p) = (1/T) ∫ S̄(H(t)⁻¹ p) dt``, sub-sampled at the midpoints of ``blur_subsamples`` equal parts of the
exposure (default: enough that no pixel moves more than :data:`MAX_SUBSAMPLE_STEP_PX` between sub-samples). The
motion itself is here; sampling the expectation is :func:`camsim.render.sequence.moving_expectation`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.schema import param, validate

#: The most frames a sequence may have (each is written as its own files).
MAX_FRAMES = 10000
#: The most sub-samples of one exposure.
MAX_SUBSAMPLES = 1024
#: The automatic sub-sampling keeps every pixel's motion between sub-samples at most this far. Unit: px.
MAX_SUBSAMPLE_STEP_PX = 0.25
#: The farthest the camera may move a pixel in a sequence: float32 sampling coordinates keep 1 px up to 1.6e7.
#: Unit: px.
MAX_MOTION_PX = 1e7
#: First spawn-key word of the shake's stream ("SHAKE").
SHAKE_KEY = 0x54A4E

SEQUENCE_KEYS = {"frames", "frame_interval_s", "shake_px", "shake_deg", "pan_px_per_s", "homographies",
                 "blur_subsamples"}


@dataclass(frozen=True)
class SequenceParams:
    """A scene's ``[sequence]`` table: how many frames, when, and how the camera moves.

    Attributes
    ----------
    frames : int
    frame_interval_s : float
        Time from one frame's start to the next's (≥ the exposure). Unit: s.
    shake_px, shake_deg : float
        σ of the shake's random-walk steps per frame interval: translation per axis (px), rotation (degrees).
    pan_px_per_s : tuple of 2 float
        (vx, vy). Unit: px / s.
    homographies : tuple or None
        One 3 × 3 matrix (tuple of row tuples) per frame, or None.
    blur_subsamples : int or None
        Sub-samples per exposure; None: chosen from the motion (:data:`MAX_SUBSAMPLE_STEP_PX`).
    """

    frames: int = param(8, "int", "number of frames of the sequence", low=1)
    frame_interval_s: float = param(0.033, "float", "time from one frame's start to the next's; at least the "
                                    "sensor's exposure_s", "s", above=0)
    shake_px: float = param(0.0, "float", "camera shake: σ of the random walk's translation step per axis per "
                            "frame interval (the pose moves linearly between steps)", "px", low=0)
    shake_deg: float = param(0.0, "float", "camera shake: σ of the random walk's rotation step (about the frame's "
                             "centre) per frame interval", "deg", low=0)
    pan_px_per_s: tuple = (0.0, 0.0)
    homographies: tuple | None = None
    blur_subsamples: int | None = param(None, "int", "sub-samples of the motion within each exposure; none = as "
                                        "many as keep every pixel's step ≤ 0.25 px", low=1, optional=True)

    def __post_init__(self):
        validate(self, "[sequence]")
        if self.frames > MAX_FRAMES:
            raise CamsimError(f"[sequence]: frames must be at most {MAX_FRAMES}, got {self.frames}")
        if self.blur_subsamples is not None and self.blur_subsamples > MAX_SUBSAMPLES:
            raise CamsimError(f"[sequence]: blur_subsamples must be at most {MAX_SUBSAMPLES}, got "
                              f"{self.blur_subsamples}")
        duration = self.frames * self.frame_interval_s
        pan = max(abs(v) for v in self.pan_px_per_s) * duration
        shake = self.shake_px * 10 * math.sqrt(self.frames)  # ten σ of the walk's end (a rotation wraps)
        if not (pan <= MAX_MOTION_PX and shake <= MAX_MOTION_PX):
            raise CamsimError(f"[sequence]: the camera would move the scene by {max(pan, shake):.3g} px (the pan over "
                              f"{duration:g} s, or ten σ of the shake's walk over {self.frames} frames), beyond "
                              f"{MAX_MOTION_PX:g} px, where the frame has long left the scene")

    @property
    def moves(self) -> bool:
        """Whether any motion is set."""
        return bool(self.shake_px or self.shake_deg or any(self.pan_px_per_s) or self.homographies is not None)

    def record(self) -> dict:
        """The sidecar's ``sequence`` parameters."""
        return {"frames": self.frames, "frame_interval_s": self.frame_interval_s, "shake_px": self.shake_px,
                "shake_deg": self.shake_deg, "pan_px_per_s": list(self.pan_px_per_s),
                "homographies": None if self.homographies is None else [list(map(list, h)) for h in self.homographies],
                "blur_subsamples": self.blur_subsamples,
                "motion_model": "H(t) = pan(t) · shake(t) · H_i: reference pixel q seen at H(t) q; shake a Gaussian "
                                "random walk per frame interval, linear in between, from the scene's seed"}


def _number(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CamsimError(f"[sequence]: {what} must be a finite number, got {value!r}")
    return float(value)


def parse_sequence(table) -> SequenceParams:
    """A :class:`SequenceParams` from a scene file's ``[sequence]`` table.

    Raises
    ------
    CamsimError
        Unknown keys, values of the wrong type or range, a pan that is not two numbers, homographies that are not
        one invertible 3 × 3 matrix of finite numbers per frame.
    """
    if not isinstance(table, dict):
        raise CamsimError("[sequence] must be a table")
    unknown = set(table) - SEQUENCE_KEYS
    if unknown:
        raise CamsimError(f"[sequence]: unknown key(s): {', '.join(sorted(unknown))}")
    if "frames" not in table:
        raise CamsimError("[sequence]: frames is required")
    values = {k: v for k, v in table.items() if k not in ("pan_px_per_s", "homographies")}
    if values.get("blur_subsamples") == "none":
        values["blur_subsamples"] = None
    pan = table.get("pan_px_per_s", [0.0, 0.0])
    if not isinstance(pan, list) or len(pan) != 2:
        raise CamsimError(f"[sequence]: pan_px_per_s must be two numbers [vx, vy] (px/s), got {pan!r}")
    values["pan_px_per_s"] = tuple(_number(v, "pan_px_per_s") for v in pan)
    if "homographies" in table:
        values["homographies"] = _homographies(table["homographies"], table.get("frames"))
    return SequenceParams(**values)


def _homographies(value, frames) -> tuple:
    if not isinstance(value, list) or (isinstance(frames, int) and len(value) != frames):
        count = len(value) if isinstance(value, list) else "not a list"
        raise CamsimError(f"[sequence]: homographies must be a list of one 3x3 matrix per frame ({frames}), got "
                          f"{count}")
    out = []
    for i, h in enumerate(value):
        if not (isinstance(h, list) and len(h) == 3 and all(isinstance(r, list) and len(r) == 3 for r in h)):
            raise CamsimError(f"[sequence]: homographies[{i}] must be a 3x3 matrix (3 rows of 3 numbers)")
        m = np.array([[_number(v, f"homographies[{i}]") for v in r] for r in h])
        if not (abs(np.linalg.det(m)) > 1e-12 and np.all(np.isfinite(np.linalg.inv(m)))):
            raise CamsimError(f"[sequence]: homographies[{i}] is not invertible")
        out.append(tuple(tuple(r) for r in m.tolist()))
    return tuple(out)


def check_timing(seq: SequenceParams, exposure_s: float) -> None:
    """Refuse an exposure longer than the frame interval (frames would overlap)."""
    if exposure_s > seq.frame_interval_s * (1 + 1e-12):
        raise CamsimError(f"[sequence]: the exposure {exposure_s:g} s is longer than frame_interval_s "
                          f"{seq.frame_interval_s:g} s")


def shake_generator(seed: int) -> np.random.Generator:
    """The shake's stream: a function of the scene's seed alone."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(SHAKE_KEY,)))


@dataclass(frozen=True)
class Motion:
    """The camera's path: :meth:`homography` at any time of the sequence.

    Attributes
    ----------
    params : SequenceParams
    width, height : int
        The frame's size (the shake's rotation is about its centre). Unit: px.
    poses : numpy.ndarray, shape (frames + 1, 3)
        The shake's (tx px, ty px, θ deg) at t = j · frame_interval_s, j = 0 … frames (pose 0 is zero).
    """

    params: SequenceParams
    width: int
    height: int
    poses: np.ndarray

    @classmethod
    def of(cls, params: SequenceParams, width: int, height: int, seed: int) -> Motion:
        """The motion of ``params`` for a frame of ``width`` × ``height``, its shake drawn from ``seed``."""
        poses = np.zeros((params.frames + 1, 3))
        if params.shake_px or params.shake_deg:
            steps = shake_generator(seed).standard_normal((params.frames, 3))
            steps *= np.array([params.shake_px, params.shake_px, params.shake_deg])
            poses[1:] = np.cumsum(steps, axis=0)
        return cls(params, int(width), int(height), poses)

    def homography(self, t: float, frame: int) -> np.ndarray:
        """H(t) (3, 3) float64 of frame ``frame`` at time ``t`` (s, from the first frame's start)."""
        p = self.params
        u = min(max(t / p.frame_interval_s, 0.0), float(p.frames))
        j = min(int(math.floor(u)), p.frames - 1)
        tx, ty, theta = self.poses[j] + (u - j) * (self.poses[j + 1] - self.poses[j])
        vx, vy = p.pan_px_per_s
        cx, cy = (self.width - 1) / 2, (self.height - 1) / 2
        c, s = math.cos(math.radians(theta)), math.sin(math.radians(theta))
        shake = np.array([[c, -s, cx - c * cx + s * cy + tx], [s, c, cy - s * cx - c * cy + ty], [0, 0, 1.0]])
        h = shake
        h[0, 2] += vx * t
        h[1, 2] += vy * t
        if p.homographies is not None:
            h = h @ np.array(p.homographies[frame])
        return h

    def start_s(self, frame: int) -> float:
        """tᵢ: frame ``frame``'s exposure start. Unit: s."""
        return frame * self.params.frame_interval_s

    def subsample_times(self, frame: int, exposure_s: float) -> np.ndarray:
        """The midpoints of the exposure's equal parts (s): ``blur_subsamples`` of them, or as many as keep every
        pixel's motion between two at most :data:`MAX_SUBSAMPLE_STEP_PX` (the corners' largest displacement over
        the exposure, measured on 64 steps, divided by it; at least 1, at most :data:`MAX_SUBSAMPLES`)."""
        t0 = self.start_s(frame)
        n = self.params.blur_subsamples
        if n is None:
            corners = np.array([[0, 0, 1], [self.width - 1, 0, 1], [0, self.height - 1, 1],
                                [self.width - 1, self.height - 1, 1.0]]).T
            points = []
            for t in np.linspace(t0, t0 + exposure_s, 65):
                q = self.homography(t, frame) @ corners
                points.append(q[:2] / q[2])
            points = np.array(points)
            path = np.abs(np.diff(points, axis=0)).max(axis=(1, 2)).sum()
            n = int(min(MAX_SUBSAMPLES, max(1, math.ceil(path / MAX_SUBSAMPLE_STEP_PX - 1e-9))))
        return t0 + (np.arange(n) + 0.5) * (exposure_s / n)

    def mid_homography(self, frame: int, exposure_s: float) -> np.ndarray:
        """H at the middle of frame ``frame``'s exposure, tᵢ + T / 2: the sidecar's ``homography``."""
        return self.homography(self.start_s(frame) + exposure_s / 2, frame)

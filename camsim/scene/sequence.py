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

**Rolling shutter** (``rolling_shutter_row_s`` = Δ > 0): row r of frame i is exposed over [tᵢ + r·Δ, tᵢ + r·Δ + T],
so each row sees the path at its own times (a pan skews the frame by atan(v·Δ)). The frame's readout, H rows of Δ,
must fit in the frame interval (H · Δ ≤ ``frame_interval_s``: a row is read once per frame); a frame's later rows
may still be exposing when the next frame's row 0 starts, as on a video sensor. **Flicker** (``flicker_hz`` f,
``flicker_depth`` m, ``flicker_phase_deg`` φ): the light is L(t) = 1 + m cos(2π f t + φ), t from the first frame's
start (:mod:`camsim.light.flicker`), so

    S̄ᵢ(x, r) = (1/T) ∫ L(t) · S̄(H(t)⁻¹ (x, r)) dt   over row r's exposure,

evaluated at the midpoints of n equal parts of each row's exposure, sub-sample s weighted by the exact integral of L
over its part / T (:meth:`Motion.exposure_samples`): without motion each row's mean is exactly its closed-form share
of the light (:meth:`Motion.light_factor`). Flicker modulates the light only, never the dark current.
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
#: With both motion and flicker, the automatic sub-sampling also keeps below this the displacement that placing each
#: sub-sample at its part's middle leaves, while the light weights the part unevenly (:meth:`Motion.subsample_count`).
#: Unit: px.
MAX_FLICKER_DISPLACEMENT_PX = 0.01
#: The highest flicker frequency (a PWM-dimmed LED flickers at kHz). Unit: Hz.
MAX_FLICKER_HZ = 1e6
#: First spawn-key word of the shake's stream ("SHAKE").
SHAKE_KEY = 0x54A4E

SEQUENCE_KEYS = {"frames", "frame_interval_s", "shake_px", "shake_deg", "pan_px_per_s", "homographies",
                 "blur_subsamples", "rolling_shutter_row_s", "flicker_hz", "flicker_depth", "flicker_phase_deg"}
#: The keys added with the rolling shutter and flicker: in the sidecar's ``sequence`` record only where set.
_LATER_KEYS = ("rolling_shutter_row_s", "flicker_hz", "flicker_depth", "flicker_phase_deg")


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
    rolling_shutter_row_s : float
        Δ, the line time of a rolling shutter (row r starts r · Δ after row 0); 0: a global shutter. Unit: s.
    flicker_hz, flicker_depth, flicker_phase_deg : float
        The light's modulation L(t) = 1 + m cos(2π f t + φ): f (Hz; 0: steady), m (0 … 1), φ (degrees).
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
    rolling_shutter_row_s: float = param(0.0, "float", "rolling shutter: the line time Δ, row r exposed from r · Δ "
                                         "after row 0 (the rows' readout, height · Δ, within frame_interval_s); 0 = "
                                         "a global shutter", "s", low=0, omit_default=True)
    flicker_hz: float = param(0.0, "float", "flicker: frequency f of the light's modulation L(t) = 1 + m cos(2π f t "
                              "+ φ), e.g. 100 or 120 for 50 or 60 Hz mains; 0 = a steady light", "Hz", low=0,
                              omit_default=True)
    flicker_depth: float = param(0.0, "float", "flicker: depth m of the modulation, 0 … 1 (the light's mean stays "
                                 "the static scene's)", low=0, omit_default=True)
    flicker_phase_deg: float = param(0.0, "float", "flicker: phase φ of the modulation at t = 0, the first frame's "
                                     "start", "deg", omit_default=True)

    def __post_init__(self):
        validate(self, "[sequence]")
        if self.flicker_depth > 1:
            raise CamsimError(f"[sequence]: flicker_depth must be at most 1, got {self.flicker_depth:g}")
        if self.flicker_hz > MAX_FLICKER_HZ:
            raise CamsimError(f"[sequence]: flicker_hz must be at most {MAX_FLICKER_HZ:g}, got {self.flicker_hz:g}")
        if abs(self.flicker_phase_deg) > 1e9:
            raise CamsimError(f"[sequence]: flicker_phase_deg must be within ±1e9, got {self.flicker_phase_deg:g}")
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

    @property
    def rolling(self) -> bool:
        """Whether the shutter is a rolling one (Δ > 0)."""
        return self.rolling_shutter_row_s > 0

    @property
    def flickers(self) -> bool:
        """Whether the light is modulated (f > 0 and m > 0)."""
        return bool(self.flicker_hz and self.flicker_depth)

    def record(self) -> dict:
        """The sidecar's ``sequence`` parameters."""
        return {"frames": self.frames, "frame_interval_s": self.frame_interval_s, "shake_px": self.shake_px,
                "shake_deg": self.shake_deg, "pan_px_per_s": list(self.pan_px_per_s),
                "homographies": None if self.homographies is None else [list(map(list, h)) for h in self.homographies],
                "blur_subsamples": self.blur_subsamples,
                "motion_model": "H(t) = pan(t) · shake(t) · H_i: reference pixel q seen at H(t) q; shake a Gaussian "
                                "random walk per frame interval, linear in between, from the scene's seed",
                **{k: getattr(self, k) for k in _LATER_KEYS if getattr(self, k)},
                **({"rolling_shutter_model": "row r of frame i exposed over [t_i + r·Δ, t_i + r·Δ + T], Δ = "
                                             "rolling_shutter_row_s"} if self.rolling else {}),
                **({"flicker_model": "light L(t) = 1 + m·cos(2π f t + φ), f = flicker_hz, m = flicker_depth, φ = "
                                     "flicker_phase_deg, t from the first frame's start; the signal only, not the "
                                     "dark current"} if self.flickers else {})}


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


def check_timing(seq: SequenceParams, exposure_s: float, height: int | None = None) -> None:
    """Refuse an exposure longer than the frame interval (a row's exposures would overlap) and, for a rolling
    shutter of a frame ``height`` rows high, a readout (height · Δ) longer than the frame interval (a row would be
    read again before the frame's last row is read)."""
    if exposure_s > seq.frame_interval_s * (1 + 1e-12):
        raise CamsimError(f"[sequence]: the exposure {exposure_s:g} s is longer than frame_interval_s "
                          f"{seq.frame_interval_s:g} s")
    if height is not None and seq.rolling and height * seq.rolling_shutter_row_s > seq.frame_interval_s * (1 + 1e-12):
        raise CamsimError(f"[sequence]: the rolling shutter's readout, {height} rows × rolling_shutter_row_s "
                          f"{seq.rolling_shutter_row_s:g} s = {height * seq.rolling_shutter_row_s:g} s, is longer "
                          f"than frame_interval_s {seq.frame_interval_s:g} s")


def shake_generator(seed: int) -> np.random.Generator:
    """The shake's stream: a function of the scene's seed alone."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(SHAKE_KEY,)))


@dataclass(frozen=True)
class Motion:
    """The camera's path and the light's modulation: :meth:`homographies` at any times of the sequence, and the
    sub-samples and weights of each row's exposure (:meth:`exposure_samples`).

    Attributes
    ----------
    params : SequenceParams
    width, height : int
        The frame's size (the shake's rotation is about its centre; a rolling shutter has ``height`` rows). Unit: px.
    poses : numpy.ndarray, shape (knots, 3)
        The shake's (tx px, ty px, θ deg) at t = j · frame_interval_s, j = 0 … knots − 1 (pose 0 is zero): frames + 1
        knots, one more for a rolling shutter (whose last frame's rows run past the last frame interval).
    """

    params: SequenceParams
    width: int
    height: int
    poses: np.ndarray

    @classmethod
    def of(cls, params: SequenceParams, width: int, height: int, seed: int) -> Motion:
        """The motion of ``params`` for a frame of ``width`` × ``height``, its shake drawn from ``seed`` (the walk's
        first ``frames`` steps are the same with or without a rolling shutter's extra one)."""
        steps_count = params.frames + (1 if params.rolling else 0)
        poses = np.zeros((steps_count + 1, 3))
        if params.shake_px or params.shake_deg:
            steps = shake_generator(seed).standard_normal((steps_count, 3))
            steps *= np.array([params.shake_px, params.shake_px, params.shake_deg])
            poses[1:] = np.cumsum(steps, axis=0)
        return cls(params, int(width), int(height), poses)

    def homographies(self, times, frame: int) -> np.ndarray:
        """H(t) for every time of ``times`` (s, from the first frame's start; any shape, N values), of frame
        ``frame`` (its ``homographies`` matrix). Returns (N, 3, 3) float64, vectorised over the times."""
        p = self.params
        t = np.asarray(times, dtype=np.float64).reshape(-1)
        knots = len(self.poses) - 1
        u = np.clip(t / p.frame_interval_s, 0.0, float(knots))
        j = np.minimum(np.floor(u).astype(np.int64), knots - 1)
        pose = self.poses[j] + (u - j)[:, None] * (self.poses[j + 1] - self.poses[j])
        tx, ty, theta = pose[:, 0], pose[:, 1], pose[:, 2]
        vx, vy = p.pan_px_per_s
        cx, cy = (self.width - 1) / 2, (self.height - 1) / 2
        rad = np.radians(theta)
        c, s = np.cos(rad), np.sin(rad)
        h = np.zeros((len(t), 3, 3))
        h[:, 0, 0], h[:, 0, 1], h[:, 0, 2] = c, -s, cx - c * cx + s * cy + tx + vx * t
        h[:, 1, 0], h[:, 1, 1], h[:, 1, 2] = s, c, cy - s * cx - c * cy + ty + vy * t
        h[:, 2, 2] = 1.0
        if p.homographies is not None:
            h = h @ np.array(p.homographies[frame])
        return h

    def homography(self, t: float, frame: int) -> np.ndarray:
        """H(t) (3, 3) float64 of frame ``frame`` at time ``t`` (s, from the first frame's start)."""
        return self.homographies([t], frame)[0]

    def start_s(self, frame: int) -> float:
        """tᵢ: frame ``frame``'s exposure start (row 0's). Unit: s."""
        return frame * self.params.frame_interval_s

    def row_starts(self, frame: int) -> np.ndarray:
        """Each row's exposure start, tᵢ + r · Δ: (height,) float64, or (1,) for a global shutter. Unit: s."""
        if not self.params.rolling:
            return np.array([self.start_s(frame)])
        return self.start_s(frame) + np.arange(self.height) * self.params.rolling_shutter_row_s

    def subsample_count(self, frame: int, exposure_s: float) -> int:
        """n, the sub-samples of each row's exposure: ``blur_subsamples``, or as many as keep every pixel's motion
        between two at most :data:`MAX_SUBSAMPLE_STEP_PX` — the frame corners' largest displacement over any row's
        exposure, measured on 64 steps per exposure (the path from row 0's start to the last row's end, its largest
        sum over 64 consecutive steps), divided by it — and, with flicker too, enough that the sub-samples' placement
        at their parts' middles displaces the image by at most ε = :data:`MAX_FLICKER_DISPLACEMENT_PX`; at least 1,
        at most :data:`MAX_SUBSAMPLES`. 1 without motion.

        The flicker's bound: part s, [t_s − δ/2, t_s + δ/2] (δ = T/n), is weighted by ∫ L over it but sampled at
        t_s; to first order in the motion (image speed u, gradient g) its error is (g·u/T) ∫ (t − t_s) L dt =
        (g·u/T) L'(t_s) δ³/12. Summed over the parts, |error| ≤ |g| (|u| δ) δ/(12 T) ∫ |L'| dt ≤ |g| · step · m ω δ/12
        (|L'| ≤ m ω, ω = 2π f), i.e. a displacement of step · m ω δ / (12 F) of an image of the light F collected;
        with step = path / n: path · m · ω T / (12 F n²) ≤ ε for n ≥ √(path · m · ω T / (12 ε F)), F the least
        row's share of the light."""
        n = self.params.blur_subsamples
        if n is None:
            if not self.params.moves:
                return 1
            t0 = self.start_s(frame)
            readout = (self.height - 1) * self.params.rolling_shutter_row_s
            whole = math.ceil(readout / exposure_s - 1e-9) + 1  # exposures that cover row 0's start … the last's end
            per_exposure = 64 if whole * 64 <= 4096 else max(1, 4096 // whole)  # (a short T on a long readout)
            steps = per_exposure * whole
            span = exposure_s * whole
            corners = np.array([[0, 0, 1], [self.width - 1, 0, 1], [0, self.height - 1, 1],
                                [self.width - 1, self.height - 1, 1.0]]).T
            q = self.homographies(np.linspace(t0, t0 + span, steps + 1), frame) @ corners
            points = q[:, :2] / q[:, 2:]
            step = np.abs(np.diff(points, axis=0)).max(axis=(1, 2))
            window = np.concatenate([[0.0], np.cumsum(step)])
            path = float(np.max(window[per_exposure:] - window[:-per_exposure])) if steps > per_exposure \
                else float(step.sum())
            n = math.ceil(path / MAX_SUBSAMPLE_STEP_PX - 1e-9)
            if self.params.flickers:
                p = self.params
                least = max(float(np.min(self.light_factor(frame, exposure_s))), 1e-3)
                bound = path * p.flicker_depth * 2 * math.pi * p.flicker_hz * exposure_s
                n = max(n, math.ceil(math.sqrt(bound / (12 * MAX_FLICKER_DISPLACEMENT_PX * least)) - 1e-9))
            n = int(min(MAX_SUBSAMPLES, max(1, n)))
        return n

    def subsample_times(self, frame: int, exposure_s: float) -> np.ndarray:
        """Row 0's sub-sample times (s): the midpoints of :meth:`subsample_count` equal parts of its exposure (a
        rolling shutter's row r has them r · Δ later)."""
        n = self.subsample_count(frame, exposure_s)
        return self.start_s(frame) + (np.arange(n) + 0.5) * (exposure_s / n)

    def exposure_samples(self, frame: int, exposure_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The sub-sample times and weights of frame ``frame``'s rows.

        Returns
        -------
        times : numpy.ndarray, shape (n, R), float64
            Sub-sample s of row r at the middle of the s-th of n equal parts of the row's exposure,
            tᵢ + r · Δ + (s + ½) T / n (R = height for a rolling shutter, 1 for a global one). Unit: s.
        weights : numpy.ndarray, shape (n, R), float64
            (1/T) ∫ L(t) dt over that part (:func:`camsim.light.flicker.flicker_integral`): 1/n for a steady
            light; each row's weights sum to its share of the light, :meth:`light_factor`.
        """
        from camsim.light.flicker import flicker_integral

        p = self.params
        n = self.subsample_count(frame, exposure_s)
        starts = self.row_starts(frame)[None, :]
        part = exposure_s / n
        edges = np.arange(n)[:, None] * part
        times = starts + (edges + part / 2)
        if p.flickers:
            weights = flicker_integral(starts + edges, starts + edges + part, exposure_s, p.flicker_hz,
                                       p.flicker_depth, p.flicker_phase_deg)
        else:
            weights = np.full((n, 1), 1 / n)
        return times, weights

    def light_factor(self, frame: int, exposure_s: float) -> np.ndarray | None:
        """Each row's share of the light over its exposure, (1/T) ∫ L(t) dt: (height,) for a rolling shutter,
        (1,) for a global one; None for a steady light."""
        from camsim.light.flicker import flicker_integral

        p = self.params
        if not p.flickers:
            return None
        starts = self.row_starts(frame)
        return flicker_integral(starts, starts + exposure_s, exposure_s, p.flicker_hz, p.flicker_depth,
                                p.flicker_phase_deg)

    def mid_homography(self, frame: int, exposure_s: float) -> np.ndarray:
        """H at the middle of frame ``frame``'s exposure (row 0's), tᵢ + T / 2: the sidecar's ``homography``."""
        return self.homography(self.start_s(frame) + exposure_s / 2, frame)

    def row_homographies(self, frame: int, exposure_s: float) -> np.ndarray:
        """H at the middle of each row's exposure, tᵢ + r · Δ + T / 2: (height, 3, 3) (a rolling shutter's sidecar
        ``row_homographies``; row 0's is :meth:`mid_homography`)."""
        return self.homographies(self.row_starts(frame) + exposure_s / 2, frame)

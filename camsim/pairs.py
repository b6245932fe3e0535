"""Noisy/clean training pairs on the fly: batches of crops of photographs through real cameras, on a GPU or the CPU.

A :class:`PairSource` holds what the pairs are drawn from — a scene file's light, luminance, wavelength grid,
camera curves and sensor overrides (as a dataset spec's ``scene``), photographs (reflectance images, Mallett 2019,
as an ``[images]`` spec's), a crop size, a range of intensity factors F, camera presets with an ISO range or
virtual cameras drawn from their noise fits — and a seed. ``source.batch(b)`` renders batch *b*: for each of its
pairs an image, a crop (and flips), an illuminant, F and a camera are drawn on the host from
:func:`camsim.core.seeding.pair_batch_seed_sequence` (seed, b), and the noise on the device from a child of the same
sequence, so a batch depends on the seed and its index only: whichever process draws it, whatever was drawn before.
:class:`PairBatches` iterates over batch indices (a worker of a data loader takes every n-th).

Per pair, each pixel's mean signal is its photograph's linear sRGB (Mallett 2019's three basis spectra) times one
3 × 3 matrix of the illuminant and camera — the scene's lit photograph (:func:`camsim.render.pipeline.light_scene` of an
:class:`~camsim.scene.sources.image.ImageSource`, computed once per image and illuminant) — times T · F. The noise is
the array path's exact per-pixel law (:func:`camsim.render.backends.array_path.draw_planes`); the clean target is each
pixel's exact expectation before quantisation, k · E[min(X + o, full well)]
(:func:`camsim.sensor.expected.clean_charge_e`), so that ``noisy − clean`` has mean zero at every pixel. Everything per
pixel stays on the device: with ``device="cuda"`` the arrays are CuPy's (a torch training loop takes them without a copy
through the host: :mod:`camsim.pairs_torch`), with ``device="cpu"`` numpy's.

The pairs of a batch are drawn together: signals, Poisson means, draws, full well, read noise, gain, ADC and clean
targets on (B, planes, H, W) arrays in one chain of array calls per batch (about 60 for any B, where a pair made about
60 of its own before: on a GPU each costs its launch whatever its size), each pair's sensor figures broadcast as
(B, 1, 1, 1) arrays (:class:`camsim.sensor.params.SensorBatch`). Pairs whose cameras differ in what cannot broadcast
(their Bayer pattern, stage switches or read-noise law: :data:`camsim.sensor.params.BATCH_SHARED`) are drawn in
separate groups; on the CPU the same code draws chunks of at most :data:`_CPU_CHUNK_PIXELS` pixels, whose arrays stay
in the caches. The noise stream is consumed batch-wise: the same seed gives the same batch, bit for bit.

The arrays of a batch are in one of :data:`PAIR_DOMAINS`, the source's ``domain``:

- ``"dn"`` (the default): the DN above, planes (1 for a Bayer mosaic, 3 for a three-chip sensor) at full
  resolution;
- ``"raw"``: what raw denoisers (SID, ELD, PMN, LED) take: the same DN with the black level before the ADC subtracted
  and divided by white − black (:func:`camsim.isp.normalise`: 0 = black, 1 = the value the ADC turns into the white
  level 2^nb − 1, :func:`adc_white_dn`), a Bayer
  mosaic packed into four half-resolution planes R, G1, G2, B (:func:`camsim.isp.pack_rggb`, G1 the green on red's
  row, whatever the camera's pattern); for a three-chip sensor the normalised (3, H, W) planes;
- ``"srgb"``: noisy and clean developed through one camera ISP (:func:`camsim.isp.develop_pair`: the same white
  balance gains, colour matrix, gain and tone curve for both; the clean mosaic demosaiced as the noisy one is), (3,
  H, W) in [0, 1]. The source's ``isp`` settings (:class:`camsim.isp.IspSettings`), by default :func:`pair_isp`:
  ``gain = "auto"`` (1 / F, the exposure ratio of SID and ELD, so that a pair at F = 10⁻³ is as bright as one at
  F = 1; 1 for a scene whose exposure is ``auto``) and bilinear demosaicing (:data:`PAIR_DEMOSAIC`: the
  cheapest; ``tools/bench_pair_domains.py`` measures what the ISP costs beside the raw domain).

Each batch says its ``domain`` and, per pair, how its arrays were made (``isp``: the ISP's record in ``srgb``, with
``path``: the ISP's compiled kernel or its numpy stages; the black and white levels and packing in ``raw``). The
conversion works on the host: on the CPU, ``srgb`` pairs with bilinear demosaicing (or three chips) are developed by
one compiled pass per image straight into the batch (:mod:`camsim.isp.fused`, numba; compiled once per process), the
others by the ISP's numpy stages; on a GPU, a pair's planes are copied to the host for the stages and back.

**Bursts** (``burst_frames = N``, issue 29): each item is N noisy frames of one crop seen by a moving camera and
the clean reference, the static crop's expectation (the target of a burst denoiser: HDR+-style merging, KPN). The
camera's motion is the sequence model of :class:`camsim.scene.sequence.Motion` (a Gaussian random walk of shake,
``shake_px`` and ``shake_deg`` per ``frame_interval_s``, linear in between, and a constant pan ``pan_px_per_s``, in
the crop's pixel coordinates, rotation about its centre), drawn from the item's own ``motion_seed`` (from the
batch's seed sequence); frame j exposes [j · interval, j · interval + T] and its expected signal is the static
crop's averaged along the path over the exposure (:func:`camsim.render.warp.average_warp`: bilinear, sub-sampled by
:meth:`~camsim.scene.sequence.Motion.subsample_times`). The crop is cut with a **margin** of the photograph around it,
as wide as the item's path reaches (its corners followed at every sub-sample; under a rolling shutter each row's ends
at its own), so that the moving frames see real scene; where the photograph is too small for that margin, the scene
beyond it is clamped to its edge (as the sequence renderer does at the frame's edge) and the item's ``burst`` record
says ``clamped``. Each frame is drawn with the
same fixed-pattern maps (the sensor's) and its own temporal noise (the batch's noise stream: every frame of every
item drawn together); the batch gives each frame's own expectation (``frames_clean``) and each frame's homography
from the reference crop to the frame at its exposure's middle (``homographies``, as a sequence sidecar's).

A burst may also have a **rolling shutter** and a **flickering light**, the settings of a scene's ``[sequence]``
with the same names and meaning (:class:`~camsim.scene.sequence.SequenceParams`, which checks them):
``rolling_shutter_row_s`` Δ (row r of frame j exposed over [tⱼ + r·Δ, tⱼ + r·Δ + T]; the crop's readout, height · Δ,
within the frame interval), ``flicker_hz``, ``flicker_depth``, ``flicker_phase_deg`` (L(t) = 1 + m cos(2π f t + φ),
t from the first frame's start, on the signal only, never the dark current). Each row is drawn by the sequence's
law: the sub-sample times and weights of its own exposure (:meth:`~camsim.scene.sequence.Motion.exposure_samples`:
each part weighted by the exact integral of L over it), the inverse homographies at those times, one weighted
average (``average_warp`` with per-row inverses and weights; the margin's rows take the nearest crop row's). What a
burst denoiser's trainer needs of them, and no more: the item's ``burst`` record holds the four settings (0 when
off); the batch's ``row_homographies`` (B, N, H, 3, 3) float32, each row's at its exposure's middle (a sidecar's
``row_homographies``; 36 bytes a row and frame), only with a rolling shutter; ``flicker_factor`` (B, N, H) float64,
each row's share of the light (1/T) ∫ L dt over its exposure (a sidecar's ``flicker_row_factor``; one value
repeated over the rows for a global shutter), only with flicker; both None otherwise. ``homographies`` stays row
0's, at its exposure's middle. Bursts render on the CPU only (the warp is numpy's; ``device="cuda"`` with
``burst_frames`` is refused).

:class:`WrittenPairs` reads the pairs of a dataset written by ``camsim dataset`` (files or a Zarr store) in the same
domains, one frame at a time as numpy arrays (:func:`camsim.pairs_torch.written_pairs` wraps it as a torch
``Dataset``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.seeding import pair_batch_seed_sequence
from camsim.core.xp import on_device, to_host
from camsim.render.backends import array_module, device_generator
from camsim.render.backends.array_path import device_maps, draw_planes, mosaic
from camsim.sensor.params import SENSOR_PARAMS, SensorBatch, with_checked_values

#: The most pixels a chunk of frames drawn together holds on the CPU (its arrays stay in the caches), and on a device
#: (all of a batch, however small its crops; 2²⁶ float64 pixels: 512 MiB an array).
_CPU_CHUNK_PIXELS, _DEVICE_CHUNK_PIXELS = 2**16, 2**26
#: The sensor parameters' schema entries by name.
_SENSOR_PARAMS = {p.name: p for p in SENSOR_PARAMS}

#: What ``cameras_mode`` may be: camera presets at an ISO drawn log-uniformly, or virtual cameras (LED's).
CAMERA_MODES = ("preset", "virtual")
#: The devices a source renders on: ``cpu`` (numpy) or ``cuda`` (CuPy).
PAIR_DEVICES = ("cpu", "cuda")
#: The domains of a batch's arrays (module docstring): DN as rendered, normalised (packed) raw, developed sRGB.
PAIR_DOMAINS = ("dn", "raw", "srgb")
#: The demosaicing of :func:`pair_isp` (the ISP's cheapest; its default, Malvar 2004, is an ``isp`` setting away).
PAIR_DEMOSAIC = "bilinear"
#: The children of a batch's seed sequence, by use.
_NOISE, _IMAGES, _LIGHT, _CAMERA, _ISO = 0, 1, 2, 3, 4
#: The child of a batch's seed sequence that draws its bursts' motion seeds (after the virtual cameras' 5 … 8).
_MOTION = 9
#: Slack added to a burst's reach before its margin is rounded up (float32 sampling coordinates). Unit: px.
_REACH_SLACK_PX = 0.01
#: A burst's rolling shutter and flickering light: the settings of :class:`camsim.scene.sequence.SequenceParams` of
#: the same names and meaning.
_LIGHT_AND_SHUTTER = ("rolling_shutter_row_s", "flicker_hz", "flicker_depth", "flicker_phase_deg")
_VIRTUAL_STREAMS = {"camera": 3, "k": 4, "shape": 5, "tukey_scale_dn": 6, "gaussian_sigma_dn": 7, "row_sigma_dn": 8}


def pair_isp(exposure: str = "fixed"):
    """The ISP settings of ``srgb`` pairs unless a source gives its own: :class:`camsim.isp.IspSettings` with
    ``gain="auto"`` (1 / F) and ``demosaic=PAIR_DEMOSAIC``; the rest the ISP's defaults (as-shot white balance, the
    camera's matrix, the sRGB curve). For a scene with ``exposure = "auto"`` (each pair's exposure time already
    brings the white to the scene's target whatever F) the gain is 1."""
    from camsim.isp import IspSettings

    return IspSettings(gain="auto" if exposure == "fixed" else 1.0, demosaic=PAIR_DEMOSAIC)


@dataclass(frozen=True)
class PairBatch:
    """One batch of pairs, its arrays on the source's device (numpy or CuPy).

    Attributes
    ----------
    index : int
        The batch's index (its seed: :func:`camsim.core.seeding.pair_batch_seed_sequence`).
    noisy : array, shape (B, planes, H, W), float32
        ``domain`` ``"dn"``: DN before quantisation (the EXR's values): k · (charge + read noise) + row noise.
        Unit: DN. ``"raw"``: the same normalised, (B, 4, H/2, W/2) packed R, G1, G2, B for a Bayer camera (B, 3, H,
        W for three chips). ``"srgb"``: developed, (B, 3, H, W) in [0, 1].
    clean : array, shape as ``noisy``, float32
        Each pixel's expectation of the DN, k · E[min(X + o, full well)] (in ``"dn"``, ``noisy − clean`` has mean 0),
        in the batch's domain.
    digital : array or None, shape (B, planes, H, W), uint16
        The raw numbers a camera writes, clip(⌊noisy + ½⌋ + pedestal, 0, 2^nb − 1) (⌊noisy⌋ without a pedestal);
        None without quantisation, and in the domains other than ``"dn"``. Unit: DN.
    params : list of dict
        Per pair: ``image``, ``crop_x``, ``crop_y``, ``flip_horizontal``, ``flip_vertical``, ``illuminant``,
        ``intensity_factor``, ``preset``, ``iso`` (None for a virtual camera), ``exposure_s``, ``dn_per_electron``,
        ``read_noise_e``, ``read_noise_model``, ``tukey_lambda``, ``row_noise_e``, ``full_well_e``, ``dark_e``
        (per channel), ``bits``, ``pedestal_dn``, ``white_level_dn``, ``cfa_pattern``.
    domain : str
        One of :data:`PAIR_DOMAINS`.
    isp : list of dict or None
        Per pair, how its arrays were made from the DN: in ``"srgb"`` the ISP's record
        (:attr:`camsim.isp.Developed.record`: each stage, the white-balance gains, the matrix, the gain); in
        ``"raw"`` ``black_dn``, ``white_dn`` and ``packed`` (the planes' names, or None for three chips); None in
        ``"dn"``.
    homographies : numpy.ndarray or None, shape (B, N, 3, 3), float64
        Bursts only (None for single pairs): per item and frame, H mapping a pixel of the reference crop (``clean``)
        to where the frame sees it, at the middle of the frame's exposure (pixel coordinates of the crop: x the
        column, y the row, a pixel's centre at integers; homogeneous). On the host.
    frames_clean : array or None, shape (B, N, planes, H, W), float32
        Bursts only: each frame's own expectation (the moving crop's, blurred by the motion within the exposure), in
        the batch's domain, as ``clean`` is the static crop's.
    row_homographies : numpy.ndarray or None, shape (B, N, H, 3, 3), float32
        Bursts with a rolling shutter only: each row's homography at the middle of its exposure,
        tⱼ + r · Δ + T / 2 (row 0's is ``homographies``'). On the host.
    flicker_factor : numpy.ndarray or None, shape (B, N, H), float64
        Bursts with flicker only: each row's share of the light over its exposure, (1/T) ∫ L(t) dt (the same for
        every row of a global shutter's frame). On the host.

    Notes
    -----
    A burst batch (``burst_frames = N``) has ``noisy`` and ``digital`` of shape (B, N, planes, H, W) (in ``"raw"``
    (B, N, 4, H/2, W/2) for a Bayer camera, in ``"srgb"`` (B, N, 3, H, W)), ``clean`` (B, planes, H, W) the static
    crop's expectation, and per item a ``burst`` record in ``params`` (``frames``, ``frame_interval_s``, ``time_s``,
    ``shake_px``, ``shake_deg``, ``pan_px_per_s``, ``rolling_shutter_row_s``, ``flicker_hz``, ``flicker_depth``,
    ``flicker_phase_deg``, ``motion_seed``, ``blur_subsamples_used``, ``margin_px``, ``reach_px``, ``clamped``).
    """

    index: int
    noisy: object
    clean: object
    digital: object
    params: list
    domain: str = "dn"
    isp: list | None = None
    homographies: np.ndarray | None = None
    frames_clean: object = None
    row_homographies: np.ndarray | None = None
    flicker_factor: np.ndarray | None = None


@dataclass(frozen=True)
class _Photo:
    """A photograph's file name and size (pixels)."""

    name: str
    width: int
    height: int


@dataclass(frozen=True)
class PairSource:
    """What batches of noisy/clean pairs are drawn from (module docstring).

    Attributes
    ----------
    scene : camsim.scene.scene_file.Scene
        The light (its ``illuminants``, drawn uniformly), luminance, wavelength grid, camera curves, exposure and
        sensor overrides (applied to every camera before a virtual camera's own parameters).
    images : tuple of str
        Photograph files (reflectance, sRGB, Mallett 2019 recovery), each at least the crop's size.
    crop : (int, int)
        (width, height) of a pair. Unit: pixels (even for Bayer cameras).
    batch_size : int
        Pairs per batch.
    intensity : (float, float)
        F drawn log-uniformly between these (F = 1: the perfect white at the scene's luminance, 8000 e⁻ in the
        strongest channel at T = 1 s).
    cameras : tuple of str
        Camera presets (:data:`camsim.sensor.presets.CAMERA_PRESETS`), drawn uniformly; all of one layout (Bayer or
        three planes).
    iso : (float, float) or None
        ``preset`` mode: ISO drawn log-uniformly in this range, clipped to each camera's; None: each camera's
        default ISO.
    cameras_mode : {'preset', 'virtual'}
        ``virtual``: each pair's camera drawn around the presets' noise fits
        (:func:`camsim.sensor.presets.virtual.draw_virtual_cameras`, ``k_range``).
    k_range : {'camera', 'union'}
    flips : bool
        Random left-right and upside-down flips of each crop, probability ½ each.
    seed : int
    device : {'cpu', 'cuda'}
    domain : {'dn', 'raw', 'srgb'}
        The batches' arrays: DN (default), normalised and packed raw, or developed sRGB (module docstring).
    isp : camsim.isp.IspSettings or None
        ``srgb``: the ISP's settings (None: :func:`pair_isp`).
    burst_frames : int or None
        None: single pairs. N ≥ 1: bursts of N noisy frames of one crop with camera motion and its clean reference
        (module docstring; :class:`PairBatch`'s shapes). The CPU only.
    shake_px, shake_deg : float
        Bursts: σ of the shake's random-walk steps per frame interval, translation per axis (px) and rotation about
        the crop's centre (degrees) (:class:`camsim.scene.sequence.SequenceParams`).
    pan_px_per_s : (float, float)
        Bursts: a constant pan (vx, vy). Unit: px / s.
    frame_interval_s : float or None
        Bursts: time from one frame's start to the next's, at least each pair's exposure; None: the pair's exposure
        (frames back to back). Unit: s.
    blur_subsamples : int or None
        Bursts: sub-samples of the motion per exposure; None: as many as keep every pixel's step ≤ 0.25 px.
    rolling_shutter_row_s : float
        Bursts: the line time Δ of a rolling shutter, row r of a frame exposed from r · Δ after row 0 (the crop's
        readout, height · Δ, within the frame interval); 0: a global shutter. Unit: s.
    flicker_hz, flicker_depth, flicker_phase_deg : float
        Bursts: the light's modulation L(t) = 1 + m cos(2π f t + φ), f (Hz; 0: steady), m (0 … 1), φ (degrees), t
        from the first frame's start; the signal only, never the dark current.
    """

    scene: object
    images: tuple
    crop: tuple = (512, 512)
    batch_size: int = 16
    intensity: tuple = (1e-3, 1.0)
    cameras: tuple = ("sony-a7s2",)
    iso: tuple | None = None
    cameras_mode: str = "preset"
    k_range: str = "camera"
    flips: bool = True
    seed: int = 0
    device: str = "cpu"
    domain: str = "dn"
    isp: object = None
    burst_frames: int | None = None
    shake_px: float = 0.0
    shake_deg: float = 0.0
    pan_px_per_s: tuple = (0.0, 0.0)
    frame_interval_s: float | None = None
    blur_subsamples: int | None = None
    rolling_shutter_row_s: float = 0.0
    flicker_hz: float = 0.0
    flicker_depth: float = 0.0
    flicker_phase_deg: float = 0.0
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        from camsim.scene.scene_file import Scene
        from camsim.sensor.presets import CAMERA_PRESETS

        if not isinstance(self.scene, Scene):
            raise CamsimError(f"a pair source needs a camsim Scene (camsim.load_scene), got {self.scene!r}")
        if self.device not in PAIR_DEVICES:
            raise CamsimError(f"unknown pair device {self.device!r}; devices: {', '.join(PAIR_DEVICES)}")
        if self.domain not in PAIR_DOMAINS:
            raise CamsimError(f"unknown pair domain {self.domain!r}; domains: {', '.join(PAIR_DOMAINS)}")
        if self.isp is not None:
            from camsim.isp import IspSettings

            if not isinstance(self.isp, IspSettings):
                raise CamsimError(f"isp must be a camsim.isp.IspSettings, got {self.isp!r}")
            if self.domain != "srgb":
                raise CamsimError(f"isp settings are for the srgb domain, not {self.domain!r}")
        if self.cameras_mode not in CAMERA_MODES:
            raise CamsimError(f"cameras_mode must be one of {CAMERA_MODES}, got {self.cameras_mode!r}")
        if not self.images:
            raise CamsimError("a pair source needs at least one image file")
        width, height = self.crop
        if not (isinstance(width, int) and isinstance(height, int) and width >= 2 and height >= 2):
            raise CamsimError(f"crop must be (width, height) in pixels, got {self.crop!r}")
        if not (isinstance(self.batch_size, int) and self.batch_size >= 1):
            raise CamsimError(f"batch_size must be a positive integer, got {self.batch_size!r}")
        lo, hi = self.intensity
        if not (0 < lo <= hi and math.isfinite(hi)):
            raise CamsimError(f"intensity must be (low, high) with 0 < low ≤ high, got {self.intensity!r}")
        unknown = [name for name in self.cameras if name not in CAMERA_PRESETS]
        if not self.cameras or unknown:
            raise CamsimError(f"unknown camera preset(s) {unknown or '(none given)'}; presets: "
                              f"{', '.join(CAMERA_PRESETS)}")
        if self.cameras_mode == "virtual":
            without = [name for name in self.cameras if not CAMERA_PRESETS[name].fits]
            if without:
                raise CamsimError(f"virtual cameras need noise fits; {', '.join(without)} have none")
        layouts = {self._sensor(name, None, {}).cfa is None for name in self.cameras}
        if len(layouts) > 1:
            raise CamsimError("the cameras of a pair source must share their layout (all Bayer or all three planes): "
                              f"{', '.join(self.cameras)}")
        if self._sensor(self.cameras[0], None, {}).cfa is not None and (width % 2 or height % 2):
            raise CamsimError(f"a Bayer camera needs an even crop, got {width}x{height}")
        for photo in self._photos:
            if photo.width < width or photo.height < height:
                raise CamsimError(f"image {photo.name} is {photo.width}x{photo.height} pixels, smaller than the crop "
                                  f"{width}x{height}")
        self._check_burst()

    def _check_burst(self) -> None:
        """Refuse burst settings that cannot be rendered (one line each), and motion settings without a burst."""
        from camsim.scene.sequence import MAX_SUBSAMPLES

        pan = self.pan_px_per_s
        still = isinstance(pan, (tuple, list)) and tuple(pan) == (0.0, 0.0)
        motion = {"shake_px": self.shake_px != 0.0, "shake_deg": self.shake_deg != 0.0, "pan_px_per_s": not still,
                  "frame_interval_s": self.frame_interval_s is not None,
                  "blur_subsamples": self.blur_subsamples is not None,
                  **{name: getattr(self, name) != 0.0 for name in _LIGHT_AND_SHUTTER}}
        frames = self.burst_frames
        if frames is None:
            given = [name for name, on in motion.items() if on]
            if given:
                raise CamsimError(f"{', '.join(given)} set without burst_frames: motion is for bursts")
            return
        if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
            raise CamsimError(f"burst_frames must be a positive integer (frames per burst), got {frames!r}")
        if self.device != "cpu":
            raise CamsimError("burst pairs render on the CPU only (device='cpu'): the motion's warp "
                              "(camsim.render.warp.average_warp) is numpy's")
        for name in ("shake_px", "shake_deg"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 <= value < math.inf):
                raise CamsimError(f"{name} must be a finite number ≥ 0, got {value!r}")
        if not (isinstance(pan, (tuple, list)) and len(pan) == 2 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in pan)):
            raise CamsimError(f"pan_px_per_s must be two finite numbers (vx, vy) in px/s, got {pan!r}")
        object.__setattr__(self, "pan_px_per_s", (float(pan[0]), float(pan[1])))
        interval = self.frame_interval_s
        if interval is not None and (isinstance(interval, bool) or not isinstance(interval, (int, float))
                                     or not (0 < interval < math.inf)):
            raise CamsimError(f"frame_interval_s must be a finite number > 0 (s) or None, got {interval!r}")
        n = self.blur_subsamples
        if n is not None and (isinstance(n, bool) or not isinstance(n, (int, np.integer))
                              or not 1 <= n <= MAX_SUBSAMPLES):
            raise CamsimError(f"blur_subsamples must be an integer from 1 to {MAX_SUBSAMPLES} or None, got {n!r}")
        self._sequence_params(None)  # the shutter's and the light's values, by the sequence's own rules
        if self.scene.exposure == "fixed":  # (auto: each pair's T is checked when it is known)
            for name in self.cameras:
                self._burst_sequence(self._sensor(name, None, {}).exposure_s)

    def _burst_sequence(self, exposure_s: float):
        """The bursts' :class:`~camsim.scene.sequence.SequenceParams` for a pair of exposure ``exposure_s`` (s).

        Raises
        ------
        CamsimError
            The exposure is longer than ``frame_interval_s``, a rolling shutter's readout (the crop's height × Δ)
            longer than it, or the motion leaves every scene (the sequence's bound).
        """
        from camsim.scene.sequence import check_timing

        key = ("sequence", exposure_s)
        if key not in self._cache:
            interval = exposure_s if self.frame_interval_s is None else float(self.frame_interval_s)
            seq = self._sequence_params(interval)
            try:
                check_timing(seq, exposure_s, self.crop[1])
            except CamsimError as exc:
                raise CamsimError(f"burst pairs: {str(exc).removeprefix('[sequence]: ')}") from None
            self._cache[key] = seq
        return self._cache[key]

    def _sequence_params(self, interval: float | None):
        """The bursts' :class:`~camsim.scene.sequence.SequenceParams` at frame interval ``interval`` (s), checked by
        its own rules (one line, ``burst pairs:`` for ``[sequence]:``); None: only the rolling shutter's and the
        light's values checked (one still frame, before the exposure is known), nothing returned."""
        from camsim.scene.sequence import SequenceParams

        light_and_shutter = {name: getattr(self, name) for name in _LIGHT_AND_SHUTTER}
        try:
            if interval is None:
                SequenceParams(frames=1, frame_interval_s=1.0, **light_and_shutter)
                return None
            return SequenceParams(
                frames=int(self.burst_frames), frame_interval_s=interval, shake_px=float(self.shake_px),
                shake_deg=float(self.shake_deg), pan_px_per_s=self.pan_px_per_s,
                blur_subsamples=None if self.blur_subsamples is None else int(self.blur_subsamples),
                **light_and_shutter)
        except CamsimError as exc:
            raise CamsimError(f"burst pairs: {str(exc).removeprefix('[sequence]: ')}") from None

    @classmethod
    def from_scene(cls, scene, images, **settings) -> PairSource:
        """A source from a scene file or built-in name (:func:`camsim.scene.scene_file.load_scene`) and ``images``: a
        folder (every .png, .jpg, .jpeg, .tif, .tiff, .exr file in it, in name order) or a list of files."""
        from camsim.dataset.spec import IMAGE_SUFFIXES
        from camsim.scene.scene_file import Scene, load_scene

        scene = scene if isinstance(scene, Scene) else load_scene(scene)
        if isinstance(images, (str, Path)) and Path(images).is_dir():
            files = sorted(p for p in Path(images).iterdir()
                           if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".") and p.is_file())
            if not files:
                raise CamsimError(f"folder {images} holds no image files ({', '.join(IMAGE_SUFFIXES)})")
        elif isinstance(images, (str, Path)):
            files = [Path(images)]
        else:
            files = [Path(p) for p in images]
        return cls(scene, tuple(str(p.resolve()) for p in files), **settings)

    # ------------------------------------------------------------------------------------------------ set-up
    @property
    def xp(self):
        """The array namespace of :attr:`device` (CuPy imported, and checked to see a GPU, on first use)."""
        return array_module("numpy" if self.device == "cpu" else "cuda")

    @cached_property
    def _camera(self):
        from camsim.sensor.camera import load_camera

        scene = self.scene
        return load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)

    def _lit(self, path: str, illuminant: str):
        """The photograph ``path`` lit by ``illuminant`` through the scene's camera (cached)."""
        from camsim.light.rates import FactoredSpectra
        from camsim.render.pipeline import light_scene
        from camsim.scene.sources.image import ImageSource

        key = ("lit", path, illuminant)
        if key not in self._cache:
            source = ImageSource(path=Path(path))
            lit = light_scene(self.scene.replace(source=source, regions=()), illuminant, self._camera)
            if not isinstance(lit.photon_rate, FactoredSpectra):
                raise CamsimError(f"image {path}: pairs need a photograph recovered with Mallett 2019")
            self._cache[key] = lit
        return self._cache[key]

    @cached_property
    def _photos(self) -> tuple:
        from camsim.scene.sources.image import ImageSource

        photos = []
        for path in self.images:
            width, height = ImageSource(path=Path(path)).own_size()
            photos.append(_Photo(Path(path).name, width, height))
        return tuple(photos)

    def _rgb(self, i: int):
        """Photograph ``i``'s linear sRGB per pixel, (H, W, 3) float32 on the device (cached)."""
        key = ("rgb", i)
        if key not in self._cache:
            lit = self._lit(self.images[i], self.scene.illuminants[0])
            rgb = np.asarray(lit.photon_rate.coefficients, dtype=np.float32)[lit.labels]
            self._cache[key] = self.xp.asarray(rgb)
        return self._cache[key]

    def _electrons_per_rgb(self, illuminant: str) -> np.ndarray:
        """(3, 3): signal electrons per second at F = 1 of each channel (columns) per unit linear sRGB (rows) under
        ``illuminant``: Mallett's basis spectra lit, in photons, through the camera's Qe. Unit: e⁻/s."""
        key = ("matrix", illuminant)
        if key not in self._cache:
            lit = self._lit(self.images[0], illuminant)
            self._cache[key] = lit.photon_rate.basis @ lit.qe.T
        return self._cache[key]

    def _sensor(self, preset: str, iso, overrides: dict):
        """The sensor of camera ``preset`` at ``iso`` with the scene's sensor overrides, then ``overrides`` (a virtual
        camera's figures, :data:`camsim.sensor.presets.virtual.VIRTUAL_KEYS`).

        The preset with the scene's overrides (user input) is validated in full once per (preset, iso) and kept; a
        virtual camera's figures are each checked by their schema entry and set on it with the checks across fields
        (:func:`camsim.sensor.params.with_checked_values`): the sensor :func:`camsim.sensor.presets.sensor_preset`
        gives for the same settings, without validating every field of it per pair."""
        from camsim.sensor.presets import sensor_preset

        key = ("sensor", preset, iso)
        if key not in self._cache:
            self._cache[key] = sensor_preset(preset, iso, self.scene.base_dir, **dict(self.scene.sensor_overrides))
        sensor = self._cache[key]
        if not overrides:
            return sensor
        return with_checked_values(sensor, **{name: _SENSOR_PARAMS[name].coerce(value, "virtual camera")
                                              for name, value in overrides.items()})

    # ------------------------------------------------------------------------------------------------ draws
    def _draw_params(self, children: list) -> list:
        """The parameters of a batch's pairs, drawn on the host from the children of its seed sequence."""
        from camsim.sensor.presets import CAMERA_PRESETS
        from camsim.sensor.presets.virtual import draw_virtual_cameras

        n, (width, height) = self.batch_size, self.crop
        images = np.random.default_rng(children[_IMAGES])
        which = images.integers(len(self.images), size=n)
        u_x, u_y, flips = images.random(n), images.random(n), images.random((n, 2)) < 0.5
        light = np.random.default_rng(children[_LIGHT])
        lights = light.integers(len(self.scene.illuminants), size=n)
        lo, hi = self.intensity
        factors = np.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * light.random(n))
        if self.cameras_mode == "virtual":
            streams = {name: np.random.default_rng(children[i]) for name, i in _VIRTUAL_STREAMS.items()}
            drawn = draw_virtual_cameras([CAMERA_PRESETS[c] for c in self.cameras], n, streams, self.k_range,
                                         dict(self.scene.sensor_overrides).get("read_noise_model"))
            cameras = [(d["preset"], None, {k: v for k, v in d.items() if k != "preset"}) for d in drawn]
        else:
            pick = np.random.default_rng(children[_CAMERA]).integers(len(self.cameras), size=n)
            u_iso = np.random.default_rng(children[_ISO]).random(n)
            cameras = []
            for i in range(n):
                preset = CAMERA_PRESETS[self.cameras[pick[i]]]
                iso = None
                if self.iso is not None:
                    c_lo, c_hi = preset.iso_range
                    a, b = max(self.iso[0], c_lo), min(self.iso[1], c_hi)
                    a, b = (a, b) if a <= b else ((c_lo, c_lo) if self.iso[1] < c_lo else (c_hi, c_hi))
                    iso = float(np.clip(math.exp(math.log(a) + (math.log(b) - math.log(a)) * u_iso[i]), c_lo, c_hi))
                cameras.append((preset.name, iso, {}))
        params = []
        for i in range(n):
            photo = self._photos[which[i]]
            x = min(int(u_x[i] * (photo.width - width + 1)), photo.width - width)
            y = min(int(u_y[i] * (photo.height - height + 1)), photo.height - height)
            preset, iso, overrides = cameras[i]
            params.append({"image_index": int(which[i]), "image": photo.name, "crop_x": x, "crop_y": y,
                           "flip_horizontal": bool(self.flips and flips[i, 0]),
                           "flip_vertical": bool(self.flips and flips[i, 1]),
                           "illuminant": self.scene.illuminants[lights[i]], "intensity_factor": float(factors[i]),
                           "preset": preset, "iso": iso, "_overrides": overrides, "_u": (u_x[i], u_y[i])})
        return params

    def _exposure_s(self, sensor, illuminant: str, factor: float) -> float:
        """The pair's T: the sensor's, or with the scene's ``exposure = "auto"`` the frame's auto exposure."""
        if self.scene.exposure == "fixed":
            return sensor.exposure_s
        from camsim.render.pipeline import auto_exposure_s

        return auto_exposure_s(self._lit(self.images[0], illuminant), factor, self.scene.exposure_target_e,
                               self.scene.exposure_max_s)

    # ------------------------------------------------------------------------------------------------ batches
    def batch(self, index: int) -> PairBatch:
        """Render batch ``index`` (≥ 0): a function of the source and the index only.

        The batch's pairs are drawn together (module docstring): their signals, noise and clean targets computed on
        (B, planes, H, W) arrays in one chain of array calls per batch, each pair's sensor figures broadcast from
        a :class:`~camsim.sensor.params.SensorBatch`."""
        if not (isinstance(index, (int, np.integer)) and index >= 0):
            raise CamsimError(f"a batch index is an integer ≥ 0, got {index!r}")
        xp = self.xp
        children = pair_batch_seed_sequence(self.seed, int(index)).spawn(10)  # (spawn(9)'s nine, and _MOTION)
        params = self._draw_params(children)
        rng = device_generator(xp, children[_NOISE])
        sensors = [self._pair_sensor(p) for p in params]
        quantised = sensors[0].quantisation and self.domain == "dn"
        homographies = frames_clean = row_homographies = flicker_factor = None
        if self.burst_frames is None:
            noisy, clean, digital = self._draw_frames(xp, rng, self._crops(params), params, sensors)
            noisy, clean, records = self._in_domain(xp, noisy, clean, params, sensors)
        else:
            noisy, clean, digital, frames_clean, homographies, row_homographies, flicker_factor, records = \
                self._bursts(xp, rng, children, params, sensors)
        if digital is not None:
            digital = digital.astype(xp.uint16, copy=False) if quantised else None
        for p, sensor in zip(params, sensors):
            del p["_overrides"], p["_u"]
            p.update(_sensor_record(sensor))
        return PairBatch(int(index), noisy, clean, digital, params, self.domain, records, homographies, frames_clean,
                         row_homographies, flicker_factor)

    def _pair_sensor(self, p: dict):
        """A pair's sensor: its camera's (:meth:`_sensor`) at the pair's exposure (:meth:`_exposure_s`)."""
        sensor = self._sensor(p["preset"], p["iso"], p["_overrides"])
        exposure = self._exposure_s(sensor, p["illuminant"], p["intensity_factor"])
        if exposure != sensor.exposure_s:
            sensor = with_checked_values(sensor, exposure_s=_SENSOR_PARAMS["exposure_s"].coerce(exposure, "pair"))
        return sensor

    def _tail(self, sensor) -> tuple:
        """The shape of one pair's arrays in the source's domain."""
        width, height = self.crop
        if self.domain == "raw" and sensor.cfa is not None:
            return (4, height // 2, width // 2)
        if self.domain == "srgb" or sensor.cfa is None:
            return (3, height, width)
        return (1, height, width)

    # ------------------------------------------------------------------------------------------------ domains
    def _in_domain(self, xp, noisy, clean, params: list, sensors: list):
        """Frames' (M, planes, H, W) DN (``xp``'s) in the source's domain: ``(noisy, clean, records)`` (records
        None in ``dn``). The conversion is the ISP's, on the host, frame by frame: on the CPU into the batch's
        arrays (``srgb`` by the compiled pass where it applies), on a device after one copy of the batch to the host
        and before one copy back."""
        if self.domain == "dn":
            return noisy, clean, None
        host = xp is np
        noisy_h, clean_h = (noisy, clean) if host else (to_host(noisy), to_host(clean))
        shape = (len(params),) + self._tail(sensors[0])
        out_noisy, out_clean = np.empty(shape, dtype=np.float32), np.empty(shape, dtype=np.float32)
        records = [self._store(host, noisy_h[i], clean_h[i], p, sensor, out_noisy[i], out_clean[i])
                   for i, (p, sensor) in enumerate(zip(params, sensors))]
        if host:
            return out_noisy, out_clean, records
        return xp.asarray(out_noisy), xp.asarray(out_clean), records

    def _store(self, fused: bool, noisy: np.ndarray, clean: np.ndarray, p: dict, sensor, out_noisy, out_clean):
        """A pair's (planes, H, W) DN on the host written into the batch's host slots ``out_noisy``, ``out_clean``
        in the source's domain (``srgb`` by the compiled pass where ``fused`` and it applies); returns its record
        (None in ``dn``)."""
        if self.domain == "dn":
            out_noisy[...], out_clean[...] = noisy, clean
            return None
        if self.domain == "srgb" and fused:  # developed straight into the batch
            return self._develop(noisy, clean, self._facts(p, sensor), out_noisy, out_clean)
        pair_noisy, pair_clean, record = self._to_domain(noisy, clean, self._facts(p, sensor))
        out_noisy[...], out_clean[...] = pair_noisy, pair_clean
        return record

    def _facts(self, p: dict, sensor):
        """What the ISP knows of a pair (:class:`camsim.isp.IspFacts`): its DN's black level before the ADC, the
        white level in the same units (:func:`adc_white_dn`), the camera's Qe and neutral under the pair's
        illuminant, and F."""
        from camsim.isp import IspFacts

        lit = self._lit(self.images[0], p["illuminant"])
        key = ("neutral", p["illuminant"])
        if key not in self._cache:
            self._cache[key] = np.asarray(lit.as_shot_neutral, dtype=np.float64)
        return IspFacts(cfa_pattern=sensor.cfa, black_dn=sensor.dark_level_dn, white_dn=adc_white_dn(sensor),
                        as_shot_neutral=self._cache[key], intensity_factor=p["intensity_factor"],
                        illuminant=p["illuminant"], wavelengths_nm=lit.grid.wavelengths_nm, qe=lit.qe)

    def _to_domain(self, noisy: np.ndarray, clean: np.ndarray, facts):
        """A pair's (planes, H, W) DN on the host in the source's domain, and its record."""
        from camsim.isp import develop_pair, normalise, pack_rggb

        cfa = facts.cfa_pattern
        if cfa is not None:
            noisy, clean = noisy[0], clean[0]
        if self.domain == "raw":
            noisy, clean = normalise(noisy, facts), normalise(clean, facts)
            if cfa is not None:
                noisy, clean = pack_rggb(noisy, cfa), pack_rggb(clean, cfa)
            return noisy, clean, {"domain": "raw", "black_dn": facts.black_dn.tolist(), "white_dn": facts.white_dn,
                                  "packed": None if cfa is None else ["R", "G1", "G2", "B"]}
        from camsim.isp.fused import STAGES_PATH

        settings = self.isp or pair_isp(self.scene.exposure)
        developed_noisy, developed_clean = develop_pair(noisy, clean, facts, settings)
        return (developed_noisy.image, developed_clean.image,
                {"domain": "srgb", "path": STAGES_PATH, **developed_noisy.record})

    def _develop(self, noisy: np.ndarray, clean: np.ndarray, facts, out_noisy, out_clean) -> dict:
        """``srgb`` on the CPU: a pair's (planes, H, W) DN developed into ``out_noisy`` and ``out_clean`` (the
        batch's (3, H, W) slots) as :meth:`_to_domain` develops it, by the ISP's compiled kernel where it applies
        (bilinear demosaicing or three chips, numba present: :mod:`camsim.isp.fused`), else by the numpy stages;
        returns the record, with ``path`` saying which made the pair."""
        from camsim.isp.fused import develop_pair_into

        if facts.cfa_pattern is not None:
            noisy, clean = noisy[0], clean[0]
        record, path = develop_pair_into(noisy, clean, facts, self.isp or pair_isp(self.scene.exposure), out_noisy,
                                         out_clean)
        return {"domain": "srgb", "path": path, **record}

    # ------------------------------------------------------------------------------------------------ drawing
    def _crops(self, params: list) -> list:
        """The pairs' crops of their photographs (with their flips), linear sRGB (H, W, 3) float32 views on the
        source's device."""
        width, height = self.crop
        views = []
        for p in params:
            x, y = p["crop_x"], p["crop_y"]
            rgb = self._rgb(p["image_index"])[y : y + height, x : x + width]
            if p["flip_vertical"]:
                rgb = rgb[::-1]
            if p["flip_horizontal"]:
                rgb = rgb[:, ::-1]
            views.append(rgb)
        return views

    def _signals(self, xp, rgb, params: list, sensors: list):
        """S̄ (M, 3, H, W) float64 of M crops' linear sRGB ``rgb`` (M, H, W, 3) float32: each pixel's rgb times its
        frame's 3 × 3 matrix of the illuminant and camera times T · F, one batched product. Unit: e⁻."""
        scale = np.stack([sensor.exposure_s * p["intensity_factor"] * self._electrons_per_rgb(p["illuminant"])
                          for p, sensor in zip(params, sensors)])[:, None]  # (M, 1, 3, 3): rgb × channels
        return xp.ascontiguousarray(xp.moveaxis(rgb.astype(xp.float64) @ xp.asarray(scale), 3, 1))  # (M, 3, H, W)

    def _draw_frames(self, xp, rng, rgb: list, params: list, sensors: list, noise: bool = True):
        """``(noisy, clean, digital)`` (M, planes, H, W) of M frames of linear sRGB ``rgb`` (M arrays (H, W, 3) on
        ``xp``'s device), each frame's signal (:meth:`_signals`) with its sensor's dark charge and fixed pattern (the
        sensor's maps for the crop's size: the same for every frame of a burst); without ``noise``, (None, clean,
        None) and nothing drawn from ``rng``.

        The frames are drawn together (:meth:`_draw_group`): all of them in one chain of array calls on a device;
        on the CPU in chunks of at most :data:`_CPU_CHUNK_PIXELS` pixels (a chunk's arrays stay in the caches:
        32 × 32 crops are drawn 64 at a time, 512 × 512 ones one by one). Frames whose sensors differ in what cannot
        broadcast (:data:`camsim.sensor.params.BATCH_SHARED`: the Bayer pattern, the stage switches, the read-noise
        law) are drawn in separate chunks, in the order of their first frame, and put back in place."""
        height, width = rgb[0].shape[:2]
        limit = max(1, (_CPU_CHUNK_PIXELS if xp is np else _DEVICE_CHUNK_PIXELS) // (height * width))
        groups: dict = {}
        for i, sensor in enumerate(sensors):
            groups.setdefault(SensorBatch.key(sensor), []).append(i)
        chunks = [items[start : start + limit] for items in groups.values() for start in range(0, len(items), limit)]
        out = [None, None, None]
        for items in chunks:
            if len(chunks) == 1:
                return self._draw_group(xp, rng, self._signals(xp, xp.stack(rgb), params, sensors), sensors, noise)
            chunk_params, chunk_sensors = [params[i] for i in items], [sensors[i] for i in items]
            signal = self._signals(xp, xp.stack([rgb[i] for i in items]), chunk_params, chunk_sensors)
            arrays = self._draw_group(xp, rng, signal, chunk_sensors, noise)
            together = items == list(range(items[0], items[-1] + 1))
            where = slice(items[0], items[-1] + 1) if together else xp.asarray(np.array(items, dtype=np.intp))
            for k, (array, dtype) in enumerate(zip(arrays, (xp.float32, xp.float32, xp.uint16))):
                if array is not None:
                    if out[k] is None:
                        out[k] = xp.zeros((len(sensors),) + array.shape[1:], dtype=dtype)
                    out[k][where] = array
        return tuple(out)

    def _draw_group(self, xp, rng, signal, sensors: list, noise: bool = True):
        """:meth:`_draw_frames` for frames whose sensors share :data:`~camsim.sensor.params.BATCH_SHARED`: one chain
        of array calls, the sensors' figures broadcast per frame (:class:`~camsim.sensor.params.SensorBatch`)."""
        m, _, height, width = signal.shape
        batch = SensorBatch.of(sensors)
        dark = np.array([sensor.dark_mean_e for sensor in sensors], dtype=np.float64)  # (M, 3)
        maps = [device_maps(xp, sensor, (height, width)) for sensor in sensors]
        offset, gain, dark_gain = _stacked_maps(xp, maps)
        dark_planes = None
        if dark_gain is not None or np.any(dark != 0):
            dark_planes = xp.broadcast_to(xp.asarray(dark.reshape(m, 3, 1, 1)), signal.shape)
        if batch.cfa is not None:  # each site its own channel
            signal = mosaic(xp, batch.cfa, signal)
            dark_planes = None if dark_planes is None else mosaic(xp, batch.cfa, dark_planes)
            offset, gain, dark_gain = (None if v is None else mosaic(xp, batch.cfa, v)
                                       for v in (offset, gain, dark_gain))
        # the Poisson mean of each pixel (g S̄ + d D̄; d D̄ alone without photon noise) and what it holds besides
        signal_mean = signal if gain is None else signal * gain
        dark_mean = dark_planes if dark_planes is None or dark_gain is None else dark_planes * dark_gain
        if batch.photon_noise:
            poisson_mean = signal_mean if dark_mean is None else signal_mean + dark_mean
            base = 0.0
        else:
            poisson_mean = xp.zeros_like(signal_mean) if dark_mean is None else dark_mean
            base = signal_mean
        if offset is not None:
            base = base + offset
        noisy = digital = None
        if noise:
            # issue 28's black-level error: one offset per channel and frame, from the noise stream (only when on)
            error = None
            if np.any(batch.black_level_error_dn > 0):
                error = rng.standard_normal((m, 3)) * on_device(xp, batch.black_level_error_dn.reshape(m, 1))
            noisy, digital = draw_planes(rng, signal, batch, dark_e=0.0 if dark_planes is None else dark_planes,
                                         gain=gain, dark_gain=dark_gain, offset_e=offset, black_level_error_dn=error)
        from camsim.sensor.expected import clean_charge_e

        clean = (clean_charge_e(poisson_mean, batch, base) * on_device(xp, batch.dn_per_electron)).astype(xp.float32)
        for i, (frame_maps, sensor) in enumerate(zip(maps, sensors)):  # a crop's stuck pixels, target and input alike
            if frame_maps is not None and frame_maps.stuck_index is not None:
                from camsim.render.frame import write_stuck

                if noise:
                    write_stuck(frame_maps, sensor, noisy[i], None if digital is None else digital[i])
                write_stuck(frame_maps, sensor, clean[i], None)
        return noisy, clean, digital

    # ------------------------------------------------------------------------------------------------ bursts
    def _bursts(self, xp, rng, children: list, params: list, sensors: list) -> tuple:
        """A burst batch (module docstring): ``(noisy, clean, digital, frames_clean, homographies, row_homographies,
        flicker_factor, records)``. Each
        item's motion and moved crops on the host (:meth:`_burst_crops`), then every frame of every item drawn
        together (:meth:`_draw_frames`), and the references' expectations together."""
        n, b = int(self.burst_frames), len(params)
        seeds = np.random.default_rng(children[_MOTION]).integers(2**63, size=b)
        moved, static, homographies, rows, light = zip(*(self._burst_crops(p, sensor, int(seed))
                                                         for p, sensor, seed in zip(params, sensors, seeds)))
        frame_params = [p for p in params for _ in range(n)]
        frame_sensors = [sensor for sensor in sensors for _ in range(n)]
        noisy, frames_clean, digital = self._draw_frames(xp, rng, [frame for item in moved for frame in item],
                                                         frame_params, frame_sensors)
        _, reference, _ = self._draw_frames(xp, rng, list(static), params, sensors, noise=False)
        noisy, frames_clean, records = self._in_domain(xp, noisy, frames_clean, frame_params, frame_sensors)
        clean, _, _ = self._in_domain(xp, reference, reference, params, sensors)
        if records is not None:
            records = records[n - 1 :: n]  # each item's (its frames' are alike)
        split = (b, n)
        noisy = noisy.reshape(split + noisy.shape[1:])
        frames_clean = frames_clean.reshape(split + frames_clean.shape[1:])
        if digital is not None:
            digital = digital.reshape(split + digital.shape[1:])
        rows = None if rows[0] is None else np.stack(rows)
        light = None if light[0] is None else np.stack(light)
        return noisy, clean, digital, frames_clean, np.stack(homographies), rows, light, records

    def _burst_crops(self, p: dict, sensor, motion_seed: int) -> tuple:
        """One burst item's motion and light (module docstring): its frames' moved crops (N, H, W, 3), the static
        crop (H, W, 3) (linear sRGB, float32, on the host), each frame's homography (N, 3, 3) at its exposure's
        middle, its rows' (N, H, 3, 3) float32 with a rolling shutter (else None) and its rows' shares of the light
        (N, H) with flicker (else None); sets the item's ``crop_x``, ``crop_y`` and ``burst`` record.

        Each frame is the sequence's law (:func:`camsim.render.sequence.moving_expectation`'s): the sub-sample times
        and weights of each row's exposure (:meth:`camsim.scene.sequence.Motion.exposure_samples`: its own times
        under a rolling shutter, each part weighted by the light's exact integral over it), the inverse homographies
        at those times, one weighted bilinear average (:func:`camsim.render.warp.average_warp`) of the crop with its
        margin (the margin's rows take the nearest crop row's times; they are cut away)."""
        from camsim.render.warp import average_warp
        from camsim.scene.sequence import Motion

        width, height = self.crop
        exposure = sensor.exposure_s
        seq = self._burst_sequence(exposure)
        motion = Motion.of(seq, width, height, motion_seed)
        # each frame's inverse homographies (crop pixel -> reference crop pixel) at its rows' sub-sample times, and
        # how far beyond the crop they reach: the ends of each row (of the first and last row for a global shutter,
        # whose rows share their times: the corners), a straight row staying straight under a homography
        rows = np.arange(height) if seq.rolling else np.array([0, height - 1])
        ends = np.stack([np.concatenate([np.zeros(len(rows)), np.full(len(rows), width - 1.0)]),
                         np.concatenate([rows, rows]).astype(np.float64), np.ones(2 * len(rows))])  # (3, 2R)
        columns = np.tile(np.arange(len(rows)), 2) if seq.rolling else np.zeros(2 * len(rows), np.intp)
        samples, reach_xy = [], np.zeros(2)  # how far beyond the crop's columns and rows
        for j in range(seq.frames):
            times, weights = motion.exposure_samples(j, exposure)  # (n, R): R = height, or 1 for a global shutter
            inv = np.linalg.inv(motion.homographies(times, j)).reshape(times.shape + (3, 3))
            q = np.einsum("srij,jr->sri", inv[:, columns], ends)  # (n, 2R, 3): each end at its row's times
            q = q[..., :2] / q[..., 2:]
            beyond = np.maximum(np.max(-q, axis=(0, 1)), np.max(q - [width - 1, height - 1], axis=(0, 1)))
            reach_xy = np.maximum(reach_xy, beyond)
            samples.append((inv, weights))
        reach = float(reach_xy.max())
        need = max(0, math.ceil(reach + _REACH_SLACK_PX)) if reach > 0 else 0
        need_x, need_y = (max(0, math.ceil(r + _REACH_SLACK_PX)) if r > 0 else 0 for r in reach_xy)
        # the crop with a margin of the photograph (as wide as the path reaches, the photograph permitting)
        photo = self._photos[p["image_index"]]
        u_x, u_y = p["_u"]
        mx, my = min(need, (photo.width - width) // 2), min(need, (photo.height - height) // 2)
        span_x, span_y = photo.width - width - 2 * mx, photo.height - height - 2 * my
        x = mx + min(int(u_x * (span_x + 1)), span_x)
        y = my + min(int(u_y * (span_y + 1)), span_y)
        p["crop_x"], p["crop_y"] = x, y
        rgb = self._rgb(p["image_index"])[y - my : y + height + my, x - mx : x + width + mx]
        if p["flip_vertical"]:
            rgb = rgb[::-1]
        if p["flip_horizontal"]:
            rgb = rgb[:, ::-1]
        rgb = np.ascontiguousarray(rgb)
        inside = (slice(my, my + height), slice(mx, mx + width))
        shift, unshift = np.eye(3), np.eye(3)
        shift[:2, 2], unshift[:2, 2] = (mx, my), (-mx, -my)
        # a rolling shutter's rows of the crop with its margin: the margin's rows repeat the crop's first and last
        padded = np.concatenate([np.zeros(my, np.intp), np.arange(height), np.full(my, height - 1)]) \
            if seq.rolling else slice(None)
        moved = np.stack([average_warp(rgb, (shift @ inv @ unshift)[:, padded],
                                       weights if weights.shape[1] == 1 else weights[:, padded], workers=1)[inside]
                          for inv, weights in samples])
        homographies = np.stack([motion.mid_homography(j, exposure) for j in range(seq.frames)])
        row_homographies = light = None
        if seq.rolling:
            row_homographies = np.stack([motion.row_homographies(j, exposure) for j in range(seq.frames)])
            row_homographies = row_homographies.astype(np.float32)
        if seq.flickers:
            light = np.stack([np.broadcast_to(motion.light_factor(j, exposure), (height,))
                              for j in range(seq.frames)])
        p["burst"] = {"frames": seq.frames, "frame_interval_s": seq.frame_interval_s,
                      "time_s": [motion.start_s(j) for j in range(seq.frames)], "shake_px": seq.shake_px,
                      "shake_deg": seq.shake_deg, "pan_px_per_s": list(seq.pan_px_per_s),
                      **{name: getattr(seq, name) for name in _LIGHT_AND_SHUTTER}, "motion_seed": motion_seed,
                      "blur_subsamples_used": [len(inv) for inv, _ in samples], "margin_px": [mx, my],
                      "reach_px": reach, "clamped": bool(mx < need_x or my < need_y)}
        return moved, np.ascontiguousarray(rgb[inside]), homographies, row_homographies, light


def _stacked_maps(xp, maps: list) -> tuple:
    """The frames' fixed-pattern maps stacked (offset, PRNU gain, dark-current factor, each (M, 3, H, W) or None
    where no frame has it): a frame without a map takes the neutral one (offset 0, factor 1)."""
    if all(frame_maps is None for frame_maps in maps):
        return None, None, None
    out = []
    for name, neutral in (("offset_e", 0.0), ("gain", 1.0), ("dark_gain", 1.0)):
        planes = [None if frame_maps is None else getattr(frame_maps, name) for frame_maps in maps]
        like = next((v for v in planes if v is not None), None)
        if like is None:
            out.append(None)
            continue
        fill = xp.full(like.shape, neutral, dtype=like.dtype)
        out.append(xp.stack([fill if v is None else v for v in planes]))
    return tuple(out)


def adc_white_dn(sensor) -> float:
    """The white level of the DN before quantisation: the value the ADC turns into 2^nb − 1, 2^nb − 1 − P with a
    pedestal P (the ADC rounds and adds P), 2^nb − ½ without (the ADC's floor); 2^nb − 1 without quantisation.
    Unit: DN.

    What :func:`camsim.isp.float_white_dn` (the white of :func:`camsim.isp.facts_from_info`) computes as 2^nb − 1
    less the offset between the two black levels (``black_level_dn − dark_level_dn``), without the exact black
    level's integration (milliseconds per camera: a pair may have a camera of its own): the two differ where the
    clipping of an unlit pixel's noise at 0 moves the quantised black level, by a fraction of a DN (0.6 DN of 4095
    for ``sony-imx174``, none for ``sony-a7s2`` with its pedestal of 512 DN)."""
    if not sensor.quantisation:
        return float(sensor.max_dn)
    return float(sensor.max_dn - sensor.pedestal_dn) if sensor.pedestal_dn else sensor.max_dn + 0.5


def _sensor_record(sensor) -> dict:
    """A pair's sensor figures for its ``params``."""
    return {"exposure_s": sensor.exposure_s, "dn_per_electron": sensor.dn_per_electron,
            "read_noise_e": sensor.read_noise_e if sensor.read_noise else 0.0,
            "read_noise_model": sensor.read_noise_model, "tukey_lambda": sensor.tukey_lambda,
            "row_noise_e": sensor.row_noise_e, "full_well_e": sensor.full_well_e,
            "dark_e": [float(v) for v in sensor.dark_mean_e], "bits": sensor.bits, "pedestal_dn": sensor.pedestal_dn,
            "white_level_dn": sensor.max_dn, "cfa_pattern": sensor.cfa}


class PairBatches:
    """The batches ``start``, ``start + step``, … (before ``stop``; None: without end) of a :class:`PairSource`.

    Iterating twice gives the same batches; a data loader's worker *w* of *n* takes ``start = w, step = n``
    (:mod:`camsim.pairs_torch`), so the batches of a run do not depend on the number of workers.
    """

    def __init__(self, source: PairSource, start: int = 0, stop: int | None = None, step: int = 1):
        if start < 0 or step < 1 or (stop is not None and stop < start):
            raise CamsimError(f"batches need 0 ≤ start ≤ stop and step ≥ 1, got {start}, {stop}, {step}")
        self.source, self.start, self.stop, self.step = source, start, stop, step

    def __iter__(self):
        index = self.start
        while self.stop is None or index < self.stop:
            yield self.source.batch(index)
            index += self.step

    def __len__(self) -> int:
        if self.stop is None:
            raise TypeError("an endless PairBatches has no length")
        return max(0, -(-(self.stop - self.start) // self.step))


# ---------------------------------------------------------------------------------------------------- written pairs
class WrittenPairs:
    """The pairs of a dataset written by ``camsim dataset`` (the file layout or a Zarr store), one per complete
    frame (in the manifest's order: frame order after a finished run), read one at a time as numpy arrays.

    ``pairs[i]`` (:meth:`read`) is ``(noisy, clean, meta)`` in ``domain``:

    - ``"dn"``: the EXR's noisy layer (the store's ``noisy``) and its clean layer, float32 DN before quantisation:
      (3, H, W), or (1, H, W) for a Bayer mosaic, whose clean layer is taken at the mosaic's sites (each pixel its
      own channel), as :class:`PairSource` gives it;
    - ``"raw"``: the same normalised with the frame's black level before the ADC and white level
      (:func:`camsim.isp.normalise` with :func:`camsim.isp.facts_from_meta`), a mosaic packed into (4, H/2, W/2)
      planes R, G1, G2, B (:func:`camsim.isp.pack_rggb`);
    - ``"srgb"``: the developed PNGs ``ID_srgb_noisy.png``, ``ID_srgb_clean.png`` (decoded by OpenImageIO; the
      store's ``srgb_noisy``, ``srgb_clean``) as (3, H, W) float32 in [0, 1] (code / (2^bits − 1)); the dataset
      must have been written with ``--srgb png`` or ``png16``.

    ``crop`` (width, height) cuts every pair to that size at an offset drawn from
    ``numpy.random.default_rng([seed, i])`` (the same crop of frame ``i`` on every read and in every domain; even
    offsets for a Bayer frame, whose crop must then be even). ``meta`` holds ``id``, ``index`` (the frame's),
    ``domain``, ``crop`` ((x, y, width, height) or None), ``record`` (the frame's manifest line: its parameters and
    seed) and how the arrays were made (``isp``: the ISP's record for ``srgb``; ``black_dn``, ``white_dn`` and
    ``packed`` for ``raw``).

    **Bursts** (a dataset written with ``burst_frames``: :mod:`camsim.dataset.spec`), ``burst=True``: item ``i``
    is its ``i``-th burst, ``(noisy, clean, meta)`` with ``noisy`` the N frames stacked, (N, P, H, W) (P = 3, or 1
    for a Bayer mosaic; (N, 4, H/2, W/2) packed in ``raw``), and ``clean`` the burst's **reference** (P, H, W):
    the clean static scene (``ID_ref.exr``'s clean layer: no motion, no noise, the fixed pattern in), aligned to no
    frame but to the camera's path at its start (t = 0, the shake's pose 0). ``meta["homography"]`` (N, 3, 3)
    float64 gives each frame's homography, reference pixel → frame pixel (the sidecar's, at the exposure's middle;
    with a crop, of the crop's pixels: T(−x, −y) · H · T(x, y), one crop window for the reference and every frame),
    so that frame n's pixel p shows the reference at H[n]⁻¹ p; ``meta["time_s"]`` (N,) the exposures' starts,
    ``meta["frames"]`` the frames' ids. Domains ``dn`` and ``raw``, from files or a Zarr store (its ``noisy`` (frame,
    burst_frame, …) and ``reference`` arrays); ``srgb`` from a dataset written with ``--srgb``: ``noisy`` (N, 3, H,
    W) each frame's ``ID_fNNN_srgb_noisy.png`` (the store's ``srgb_noisy``), ``clean`` (3, H, W)
    ``ID_ref_srgb_clean.png`` (the store's ``srgb_reference``), all developed with the burst's one development (its
    reference's; ``meta["isp"]``). A burst dataset read without ``burst=True`` (or a
    single-frame one with it) is refused.

    Raises
    ------
    CamsimError
        No dataset at ``path`` (neither ``manifest.jsonl`` nor ``dataset.zarr``), an unknown domain, an ``srgb``
        domain without sRGB outputs, a crop larger than the frames, bursts read as frames or frames as bursts.
    """

    def __init__(self, path, domain: str = "dn", crop: tuple | None = None, seed: int = 0, burst: bool = False):
        from camsim.dataset.manifest import MANIFEST_NAME, read_manifest
        from camsim.dataset.zarr_store import STORE_NAME

        if domain not in PAIR_DOMAINS:
            raise CamsimError(f"unknown pair domain {domain!r}; domains: {', '.join(PAIR_DOMAINS)}")
        path = Path(path)
        if path.name == STORE_NAME:
            path = path.parent
        if not (path / MANIFEST_NAME).is_file():
            raise CamsimError(f"{path} holds no camsim dataset ({MANIFEST_NAME} not found)")
        self.path, self.domain, self.seed = path, domain, int(seed)
        self.store = path / STORE_NAME if (path / STORE_NAME).is_dir() else None
        self.records = [r for r in read_manifest(path) if ("arrays" if self.store else "files") in r]
        self.burst = bool(burst)
        bursts = sum(1 for r in self.records if r.get("burst_frames") is not None)
        if not burst and bursts:
            raise CamsimError(f"{path} holds bursts (burst_frames): read them with burst=True")
        if burst and (bursts < len(self.records) or not self.records):
            raise CamsimError(f"{path} holds {len(self.records) - bursts} single frame(s) and {bursts} burst(s): "
                              "burst=True reads a dataset of bursts (burst_frames)")
        if crop is not None:
            width, height = crop
            if not (isinstance(width, int) and isinstance(height, int) and width >= 1 and height >= 1):
                raise CamsimError(f"crop must be (width, height) in pixels, got {crop!r}")
        self.crop = None if crop is None else (int(crop[0]), int(crop[1]))
        if domain == "srgb":
            without = [r["id"] for r in self.records if not isinstance(r.get("srgb"), dict)]
            if without:
                raise CamsimError(f"{path}: {len(without)} frame(s) have no sRGB outputs (e.g. {without[0]}): write "
                                  "the dataset with camsim dataset --srgb png (or png16)")
        self._group = None
        self._pid = None

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, i: int):
        return self.read(i)

    def __getstate__(self) -> dict:
        """Pickled without the open store (a data loader's spawned workers open their own)."""
        return self.__dict__ | {"_group": None, "_pid": None}

    # --- reading ------------------------------------------------------------------------------------------------
    def _zarr(self):
        """The store's group, opened once per process (a data loader's workers each open their own)."""
        import os

        if self._group is None or self._pid != os.getpid():
            import zarr

            self._group = zarr.open_group(self.store, mode="r", zarr_format=3, use_consolidated=False)
            self._pid = os.getpid()
        return self._group

    def _layers(self, record: dict, names: tuple) -> tuple:
        """The frame's arrays ``names`` (``noisy``, ``clean``, ``srgb_noisy``, ``srgb_clean``) as stored, and its
        sidecar (None where not needed)."""
        import json

        if self.store is not None:
            group = self._zarr()
            index = record["index"]
            arrays = tuple(np.asarray(group[name][index]) for name in names)
            meta = json.loads(str(group["sidecar"][index])) if "noisy" in names else None
            return arrays, meta
        files = record["files"]
        if "noisy" in names:
            from camsim.io.exr import read_exr
            from camsim.render.frame_files import read_frame_meta

            exr = self.path / files["exr"]["name"]
            noisy, clean, _ = read_exr(exr)
            return (noisy, clean), read_frame_meta(exr)
        return tuple(_read_png_planes(self.path / files[name]["name"]) for name in names), None

    def _offset(self, i: int, width: int, height: int, bayer: bool) -> tuple | None:
        """Crop ``i``'s (x, y) in a frame of width × height (None without a crop)."""
        if self.crop is None:
            return None
        cw, ch = self.crop
        if cw > width or ch > height:
            raise CamsimError(f"crop {cw}x{ch} is larger than the frames ({width}x{height})")
        if bayer and (cw % 2 or ch % 2):
            raise CamsimError(f"a Bayer frame needs an even crop, got {cw}x{ch}")
        rng = np.random.default_rng([self.seed, int(i)])
        step = 2 if bayer else 1
        x = int(rng.integers((width - cw) // step + 1)) * step
        y = int(rng.integers((height - ch) // step + 1)) * step
        return x, y

    def read(self, i: int) -> tuple:
        """Pair ``i``: ``(noisy, clean, meta)`` (class docstring)."""
        if not (isinstance(i, (int, np.integer)) and -len(self) <= i < len(self)):
            raise IndexError(f"pair {i!r} of a dataset of {len(self)}")
        i = int(i) % len(self)
        record = self.records[i]
        if self.burst:
            return self._read_burst(i, record)
        cfa = record.get("cfa")
        bayer = cfa is not None
        meta = {"id": record["id"], "index": record["index"], "domain": self.domain, "crop": None,
                "record": {k: v for k, v in record.items() if k not in ("files", "arrays")}}
        if self.domain == "srgb":
            (noisy, clean), _ = self._layers(record, ("srgb_noisy", "srgb_clean"))
            bits = record["srgb"]["bits"]
            noisy = noisy.astype(np.float32) / np.float32(2**bits - 1)
            clean = clean.astype(np.float32) / np.float32(2**bits - 1)
            meta["isp"] = record["srgb"]["isp"]
        else:
            (noisy, clean), sidecar = self._layers(record, ("noisy", "clean"))
            cfa = sidecar.get("cfa_pattern") or None
            bayer = cfa is not None
            if bayer:
                from camsim.dataset.srgb import mosaic_clean

                clean = mosaic_clean(clean, cfa)[None]
        height, width = noisy.shape[1:]
        offset = self._offset(i, width, height, bayer)
        if offset is not None:
            (x, y), (cw, ch) = offset, self.crop
            noisy, clean = noisy[:, y:y + ch, x:x + cw], clean[:, y:y + ch, x:x + cw]
            meta["crop"] = (x, y, cw, ch)
        if self.domain == "raw":
            from camsim.isp import facts_from_meta, normalise, pack_rggb

            facts = facts_from_meta(sidecar, quantised=False)
            noisy = normalise(noisy[0] if bayer else noisy, facts)
            clean = normalise(clean[0] if bayer else clean, facts)
            if bayer:
                noisy, clean = pack_rggb(noisy, cfa), pack_rggb(clean, cfa)  # even offsets keep the pattern
            meta.update(black_dn=facts.black_dn.tolist(), white_dn=facts.white_dn,
                        packed=["R", "G1", "G2", "B"] if bayer else None)
        return (np.ascontiguousarray(noisy, dtype=np.float32), np.ascontiguousarray(clean, dtype=np.float32), meta)

    def _read_burst(self, i: int, record: dict) -> tuple:
        """Burst ``i``: its frames and reference (class docstring)."""
        from camsim.io.exr import read_exr, read_exr_clean
        from camsim.render.frame_files import read_frame_meta

        if self.store is not None:  # the store's (frame, burst_frame, …) arrays and the item's sidecars
            import json

            group, index = self._zarr(), record["index"]
            if self.domain == "srgb":  # every frame's noisy and the reference's clean, developed one way
                from camsim.dataset.zarr_store import SRGB_REFERENCE

                scale = np.float32(2 ** record["srgb"]["bits"] - 1)
                noisy = np.asarray(group["srgb_noisy"][index]).astype(np.float32) / scale
                clean = np.asarray(group[SRGB_REFERENCE][index]).astype(np.float32) / scale
            else:
                noisy, clean = np.asarray(group["noisy"][index]), np.asarray(group["reference"][index])
            sidecars = json.loads(str(group["sidecar"][index]))["frames"]
            from camsim.render.sequence import frame_digits

            digits = frame_digits(len(sidecars))
            suffixes = [f"f{meta['frame_index']:0{digits}d}" for meta in sidecars]
        elif self.domain == "srgb":  # the developed PNGs: every frame's noisy, the reference's clean
            files, burst = record["files"], record["burst"]
            suffixes = burst["frames"]
            sidecars = [read_frame_meta(self.path / files[f"{suffix}.exr"]["name"]) for suffix in suffixes]
            scale = np.float32(2 ** record["srgb"]["bits"] - 1)
            noisy = np.stack([_read_png_planes(self.path / files[f"{suffix}.srgb_noisy"]["name"])
                              for suffix in suffixes]).astype(np.float32) / scale
            clean = _read_png_planes(self.path / files[f"{burst['reference']}.srgb_clean"]["name"]).astype(
                np.float32) / scale
        else:
            files, burst = record["files"], record["burst"]
            noisy, sidecars, suffixes = [], [], burst["frames"]
            for suffix in suffixes:
                path = self.path / files[f"{suffix}.exr"]["name"]
                noisy.append(read_exr(path, clean=False)[0])
                sidecars.append(read_frame_meta(path))
            clean = read_exr_clean(self.path / files[f"{burst['reference']}.exr"]["name"])[0]
            noisy = np.stack(noisy)
        cfa = sidecars[0].get("cfa_pattern") or None
        bayer = cfa is not None  # (even crop offsets in every domain: the same crop of item i in each)
        if bayer and self.domain != "srgb":  # (sRGB: demosaiced)
            from camsim.dataset.srgb import mosaic_clean

            clean = mosaic_clean(clean, cfa)[None]
        homography = np.array([meta["homography"] for meta in sidecars], dtype=np.float64)
        meta = {"id": record["id"], "index": record["index"], "domain": self.domain, "crop": None,
                "record": {k: v for k, v in record.items() if k not in ("files", "arrays")},
                "frames": [f"{record['id']}_{suffix}" for suffix in suffixes],
                "time_s": [float(meta["time_s"]) for meta in sidecars]}
        height, width = noisy.shape[2:]
        offset = self._offset(i, width, height, bayer)
        if offset is not None:
            (x, y), (cw, ch) = offset, self.crop
            noisy, clean = noisy[:, :, y:y + ch, x:x + cw], clean[:, y:y + ch, x:x + cw]
            meta["crop"] = (x, y, cw, ch)
            into, out_of = np.eye(3), np.eye(3)
            into[:2, 2], out_of[:2, 2] = (x, y), (-x, -y)
            homography = out_of @ homography @ into  # crop pixels: T(−x, −y) · H · T(x, y)
        meta["homography"] = homography
        if self.domain == "srgb":
            meta["isp"] = record["srgb"]["isp"]  # the burst's one development, its reference's
        if self.domain == "raw":
            from camsim.isp import facts_from_meta, normalise, pack_rggb

            facts = facts_from_meta(sidecars[0], quantised=False)  # one sensor: every frame's levels are these
            noisy = np.stack([normalise(frame[0] if bayer else frame, facts) for frame in noisy])
            clean = normalise(clean[0] if bayer else clean, facts)
            if bayer:
                noisy, clean = np.stack([pack_rggb(frame, cfa) for frame in noisy]), pack_rggb(clean, cfa)
            meta.update(black_dn=facts.black_dn.tolist(), white_dn=facts.white_dn,
                        packed=["R", "G1", "G2", "B"] if bayer else None)
        return (np.ascontiguousarray(noisy, dtype=np.float32), np.ascontiguousarray(clean, dtype=np.float32), meta)


def _read_png_planes(path: Path) -> np.ndarray:
    """A PNG's RGB codes as stored, (3, H, W) uint8 or uint16 (OpenImageIO:
    :func:`camsim.scene.sources.image.read_image_codes`)."""
    from camsim.scene.sources.image import read_image_codes

    pixels, integer, _ = read_image_codes(str(path))
    if not integer:
        raise CamsimError(f"{path}: not an 8- or 16-bit image")
    return np.ascontiguousarray(pixels.transpose(2, 0, 1))

__all__ = ["CAMERA_MODES", "PAIR_DEMOSAIC", "PAIR_DEVICES", "PAIR_DOMAINS", "PairBatch", "PairBatches", "PairSource",
           "WrittenPairs", "adc_white_dn", "pair_isp"]

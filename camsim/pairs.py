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
:class:`~camsim.scene.sources.image.ImageSource`, computed once per image and illuminant) — times T · F. The noise is the
array path's exact per-pixel law (:func:`camsim.render.backends.array_path.draw_planes`); the clean target is each pixel's
exact expectation before quantisation, k · E[min(X + o, full well)] (:func:`camsim.sensor.expected.clean_charge_e`), so that
``noisy − clean`` has mean zero at every pixel. Everything per pixel stays on the device: with ``device="cuda"`` the
arrays are CuPy's (a torch training loop takes them without a copy through the host: :mod:`camsim.pairs_torch`),
with ``device="cpu"`` numpy's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from camsim.render.backends import array_module, device_generator
from camsim.render.backends.array_path import device_maps, draw_planes, mosaic
from camsim.core.errors import CamsimError
from camsim.core.seeding import pair_batch_seed_sequence

#: What ``cameras_mode`` may be: camera presets at an ISO drawn log-uniformly, or virtual cameras (LED's).
CAMERA_MODES = ("preset", "virtual")
#: The devices a source renders on: ``cpu`` (numpy) or ``cuda`` (CuPy).
PAIR_DEVICES = ("cpu", "cuda")
#: The children of a batch's seed sequence, by use.
_NOISE, _IMAGES, _LIGHT, _CAMERA, _ISO = 0, 1, 2, 3, 4
_VIRTUAL_STREAMS = {"camera": 3, "k": 4, "shape": 5, "tukey_scale_dn": 6, "gaussian_sigma_dn": 7, "row_sigma_dn": 8}


@dataclass(frozen=True)
class PairBatch:
    """One batch of pairs, its arrays on the source's device (numpy or CuPy).

    Attributes
    ----------
    index : int
        The batch's index (its seed: :func:`camsim.core.seeding.pair_batch_seed_sequence`).
    noisy : array, shape (B, planes, H, W), float32
        DN before quantisation (the EXR's values): k · (charge + read noise) + row noise. Unit: DN.
    clean : array, shape (B, planes, H, W), float32
        Each pixel's expectation of ``noisy``, k · E[min(X + o, full well)]: ``noisy − clean`` has mean 0. Unit: DN.
    digital : array or None, shape (B, planes, H, W), uint16
        The raw numbers a camera writes, clip(⌊noisy + ½⌋ + pedestal, 0, 2^nb − 1) (⌊noisy⌋ without a pedestal); None without quantisation. Unit: DN.
    params : list of dict
        Per pair: ``image``, ``crop_x``, ``crop_y``, ``flip_horizontal``, ``flip_vertical``, ``illuminant``,
        ``intensity_factor``, ``preset``, ``iso`` (None for a virtual camera), ``exposure_s``, ``dn_per_electron``,
        ``read_noise_e``, ``read_noise_model``, ``tukey_lambda``, ``row_noise_e``, ``full_well_e``, ``dark_e``
        (per channel), ``bits``, ``pedestal_dn``, ``white_level_dn``, ``cfa_pattern``.
    """

    index: int
    noisy: object
    clean: object
    digital: object
    params: list


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
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        from camsim.sensor.presets import CAMERA_PRESETS
        from camsim.scene.scene_file import Scene

        if not isinstance(self.scene, Scene):
            raise CamsimError(f"a pair source needs a camsim Scene (camsim.load_scene), got {self.scene!r}")
        if self.device not in PAIR_DEVICES:
            raise CamsimError(f"unknown pair device {self.device!r}; devices: {', '.join(PAIR_DEVICES)}")
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

    @classmethod
    def from_scene(cls, scene, images, **settings) -> PairSource:
        """A source from a scene file or built-in name (:func:`camsim.scene.scene_file.load_scene`) and ``images``: a folder
        (every .png, .jpg, .jpeg, .tif, .tiff, .exr file in it, in name order) or a list of files."""
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
        from camsim.render.pipeline import light_scene
        from camsim.light.rates import FactoredSpectra
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
        from camsim.sensor.presets import sensor_preset

        return sensor_preset(preset, iso, self.scene.base_dir, **(dict(self.scene.sensor_overrides) | overrides))

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
                           "preset": preset, "iso": iso, "_overrides": overrides})
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
        """Render batch ``index`` (≥ 0): a function of the source and the index only."""
        if not (isinstance(index, (int, np.integer)) and index >= 0):
            raise CamsimError(f"a batch index is an integer ≥ 0, got {index!r}")
        xp = self.xp
        children = pair_batch_seed_sequence(self.seed, int(index)).spawn(9)
        params = self._draw_params(children)
        rng = device_generator(xp, children[_NOISE])
        width, height = self.crop
        first = self._sensor(params[0]["preset"], params[0]["iso"], params[0]["_overrides"])
        planes = 3 if first.cfa is None else 1
        shape = (self.batch_size, planes, height, width)
        noisy = xp.empty(shape, dtype=xp.float32)
        clean = xp.empty(shape, dtype=xp.float32)
        digital = xp.empty(shape, dtype=xp.uint16) if first.quantisation else None
        for i, p in enumerate(params):
            sensor = self._sensor(p["preset"], p["iso"], p["_overrides"])
            exposure = self._exposure_s(sensor, p["illuminant"], p["intensity_factor"])
            if exposure != sensor.exposure_s:
                sensor = dataclasses.replace(sensor, exposure_s=exposure)
            pair = self._render_pair(xp, rng, p, sensor)
            noisy[i], clean[i] = pair[0], pair[1]
            if digital is not None:
                digital[i] = pair[2]
            del p["_overrides"]
            p.update(_sensor_record(sensor))
        return PairBatch(int(index), noisy, clean, digital, params)

    def _render_pair(self, xp, rng, p: dict, sensor):
        """One pair's (noisy, clean, digital) planes."""
        width, height = self.crop
        x, y = p["crop_x"], p["crop_y"]
        rgb = self._rgb(p["image_index"])[y : y + height, x : x + width]
        if p["flip_vertical"]:
            rgb = rgb[::-1]
        if p["flip_horizontal"]:
            rgb = rgb[:, ::-1]
        scale = sensor.exposure_s * p["intensity_factor"] * self._electrons_per_rgb(p["illuminant"])
        signal = xp.ascontiguousarray(xp.moveaxis(rgb.astype(xp.float64) @ xp.asarray(scale), 2, 0))  # (3, H, W)
        dark = np.asarray(sensor.dark_mean_e, dtype=np.float64)
        maps = device_maps(xp, sensor, (height, width))
        offset = gain = dark_gain = None
        if maps is not None:
            offset, gain, dark_gain = maps.offset_e, maps.gain, maps.dark_gain
        dark_planes = xp.broadcast_to(xp.asarray(dark.reshape(3, 1, 1)), signal.shape)
        if sensor.cfa is not None:  # each site its own channel
            signal = mosaic(xp, sensor.cfa, signal)
            dark_planes = mosaic(xp, sensor.cfa, dark_planes)
            offset, gain, dark_gain = (None if m is None else mosaic(xp, sensor.cfa, m)
                                       for m in (offset, gain, dark_gain))
        # the Poisson mean of each pixel (g S̄ + d D̄; d D̄ alone without photon noise) and what it holds besides
        signal_mean = signal if gain is None else signal * gain
        dark_mean = dark_planes if dark_gain is None else dark_planes * dark_gain
        if sensor.photon_noise:
            poisson_mean, base = signal_mean + dark_mean, 0.0
        else:
            poisson_mean, base = dark_mean, signal_mean
        if offset is not None:
            base = base + offset
        if gain is None and dark_gain is None:
            noisy, digital = draw_planes(rng, signal + dark_planes, sensor, offset_e=offset)
        else:
            noisy, digital = draw_planes(rng, signal, sensor, dark_e=dark_planes, gain=gain, dark_gain=dark_gain,
                                         offset_e=offset)
        from camsim.sensor.expected import clean_charge_e

        clean = clean_charge_e(poisson_mean, sensor, base) * sensor.dn_per_electron
        return noisy, clean.astype(xp.float32), digital


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


__all__ = ["CAMERA_MODES", "PAIR_DEVICES", "PairBatch", "PairBatches", "PairSource"]

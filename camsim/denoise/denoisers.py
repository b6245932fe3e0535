"""Denoisers for ``camsim denoise-eval``: the built-in scikit-image baselines and the user's own.

Every denoiser has one interface: ``f(image, sigma_dn) -> denoised``, the result of the same shape and unit as
``image``, which is, for

* a three-chip frame: a (H, W, 3) float32 array of noisy digital numbers (R, G, B as the last axis, black level
  included: the EXR's values before quantisation), ``sigma_dn`` (3,) per channel in DN;
* a Bayer frame (:mod:`camsim.denoise.bayer`): the mosaic with its black level subtracted and divided by white −
  black (0 = black, 1 = the white level; noise makes values below 0), either packed — a (H/2, W/2, 4) float32
  array, planes R, G1, G2, B as the last axis — or, for a user's denoiser with ``--bayer-input mosaic``, the (H, W)
  float32 mosaic in the frame's own pattern; ``sigma_dn`` (4,) per plane R, G1, G2, B in that normalised unit
  (the parameter keeps its name).

``sigma_dn`` is the estimated noise standard deviation, or None.

The noise level a blind denoiser may use is *estimated from the noisy image itself*
(:func:`estimate_noise_sigma`, scikit-image's wavelet-domain median absolute deviation); the sidecar's noise model
(signal variance + dark + read noise) is never given to a denoiser, since a real denoiser does not know it.

A target names a denoiser:

* a built-in name (:data:`DENOISERS`): ``identity`` (the control: returns its input), ``nl-means``, ``wavelet``,
  ``tv``, ``bm3d`` (PyPI ``bm3d``, the classic baseline; the one built-in given the *model's* noise level,
  :func:`model_noise_sigma`, since BM3D's result depends on σ and it has no blind mode);
* ``MODULE:FUNCTION`` — e.g. ``mypkg.filters:denoise`` (imported with the current directory on ``sys.path``) or
  ``path/to/file.py:denoise``; called as ``FUNCTION(image)`` with the array above, or as
  ``FUNCTION(image, sigma_dn=...)`` if it has a parameter named ``sigma_dn``; it must return an array of the same
  shape;
* ``cmd:COMMAND ARGS...`` — a program run once per frame, with ``{input}`` and ``{output}`` in its arguments
  replaced by the paths of a temporary EXR holding the noisy frame (float32; header ``camsim:denoise_sigma_dn`` =
  the estimated σ per channel as JSON) and of the EXR it must write, with the same channels: ``R``, ``G``, ``B``
  in DN for a three-chip frame; for a Bayer frame ``R``, ``G1``, ``G2``, ``B`` at half resolution (packed) or one
  channel ``CFA`` (the mosaic), normalised. The command line is split like a POSIX shell would (``shlex``) but
  run without a shell.

The built-ins work on a Bayer frame's packed planes (given the packed planes whatever ``--bayer-input`` says):
``identity``, ``wavelet`` and ``tv`` each plane on its own, ``nl-means`` the four planes as the channels of one
image (patch distances over all four), ``bm3d`` each plane on its own (:func:`bm3d.bm3d`, grey).
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.input_files import check_input, open_input
from camsim.core.pixel_limit import check_pixel_count

__all__ = ["DENOISERS", "Denoiser", "estimate_noise_sigma", "model_noise_sigma", "resolve_denoiser", "COMMAND_PREFIX",
           "SIGMA_BLIND", "SIGMA_MODEL"]

COMMAND_PREFIX = "cmd:"
INPUT_PLACEHOLDER = "{input}"
OUTPUT_PLACEHOLDER = "{output}"
STDERR_TAIL_CHARS = 2000

#: Constants of the built-in baselines (in units of the estimated noise σ, so that they do not depend on the
#: image's scale). ``nl-means``: h = 0.8 σ with σ passed to scikit-image (its documented choice for fast mode),
#: 5 × 5 patches searched within ±6 pixels; ``tv``: Chambolle's weight = 1 σ (of the normalised image).
NLM_H_PER_SIGMA = 0.8
NLM_PATCH_SIZE = 5
NLM_PATCH_DISTANCE = 6
TV_WEIGHT_PER_SIGMA = 1.0


SIGMA_ESTIMATOR = ("skimage.restoration.estimate_sigma(channel_axis=-1) (MAD of the finest db2 diagonal "
                   "coefficients)")
"""How :func:`estimate_noise_sigma` estimates the noise (for the report)."""
WAVELET_IMPLEMENTATION = ("skimage.restoration.denoise_wavelet(wavelet='db1', method='BayesShrink', mode='soft', "
                          "channel_axis=-1)")
"""What the ``wavelet`` denoiser runs (for the report)."""


def estimate_noise_sigma(image: np.ndarray) -> np.ndarray:
    """The noise standard deviation per channel of a (H, W, 3) image, estimated blindly. Unit: that of the image.

    Donoho's estimator, the median absolute deviation of the finest diagonal wavelet coefficients / 0.6745, which
    assumes additive white Gaussian noise and sees only the noisy pixels, never the sidecar's noise model:
    :func:`skimage.restoration.estimate_sigma` with ``channel_axis=-1`` (Daubechies-2 wavelet). On a ColorChecker
    it sees only noise: flat patches and axis-aligned edges have no diagonal detail. Undefined estimates are 0.
    """
    from skimage.restoration import estimate_sigma

    image = np.asarray(image, dtype=np.float64)
    sigma = np.asarray(estimate_sigma(image, channel_axis=-1, average_sigmas=False), dtype=np.float64)
    return np.where(np.isfinite(sigma), sigma, 0.0)


MODEL_SIGMA_TEXT = (
    "the sensor model's noise per channel from the sidecar: σ² = K·max(mean(noisy) − black, 0) (signal shot noise, "
    "Poisson, if photon_noise) + K²·(dark_e (if dark_current) + read_noise_e² + row_noise_e² (if read_noise)), "
    "K = dn_per_electron, dark_e = dark_current_e_per_s · "
    "exposure_s: the RMS over the frame of each pixel's expected σ (the variance is linear in the signal, so its "
    "frame mean needs only the noisy frame's mean; the clean layer is not used)")
"""How :func:`model_noise_sigma` computes the noise level (for the report)."""

SIGMA_BLIND = "blind"
"""A denoiser given :func:`estimate_noise_sigma` (the noisy image alone)."""
SIGMA_MODEL = "model"
"""A denoiser given :func:`model_noise_sigma` (the sidecar's sensor figures)."""


def model_noise_sigma(meta: dict, image: np.ndarray, black_dn, channel_of=(0, 1, 2)) -> np.ndarray:
    """The frame's noise level per channel from the sensor model in its sidecar. Unit: DN.

    Each pixel's variance about its expectation (the clean layer, which holds the fixed pattern — DSNU, PRNU — so
    that they are no noise to remove) is linear in its expected signal s (e⁻): K²·(s + d + r² + ρ²) with K the
    gain (DN/e⁻), d the dark electrons (``dark_current_e_per_s`` × ``exposure_s``), r and ρ the read and row noise
    (e⁻); each term only where its stage is on (``stages``). The result is the square root of its mean over the
    frame, with the mean signal taken from the noisy image itself (mean(image) − black, unbiased) — the clean layer
    is never used. Under ``photon_statistics = "paper"`` the shot-noise term is the Poisson one all the same.

    Parameters
    ----------
    meta : dict
        The frame's sidecar (``dn_per_electron``, ``read_noise_e``, ``dark_current_e_per_s``, ``exposure_s``,
        ``stages``; ``row_noise_e`` if present).
    image : numpy.ndarray, shape (H, W, C)
        The noisy frame, black level included (C = 3: R, G, B; a Bayer frame's packed planes: C = 4). Unit: DN.
    black_dn : array_like, shape (C,)
        The mean DN of an unlit pixel. Unit: DN.
    channel_of : sequence of int, length C
        The colour (0 = R, 1 = G, 2 = B) of each plane, for the per-colour dark current (packed planes R, G1, G2,
        B: ``(0, 1, 1, 2)``).

    Returns
    -------
    numpy.ndarray, shape (C,)
        σ per channel. Unit: DN.
    """
    k = float(meta["dn_per_electron"])
    stages = meta.get("stages") or {}
    mean_dn = np.asarray(image, dtype=np.float64).mean(axis=(0, 1)) - np.asarray(black_dn, dtype=np.float64)
    signal_e = np.maximum(mean_dn, 0.0) / k
    var_e = np.zeros(signal_e.shape)
    if stages.get("photon_noise", True):
        var_e += signal_e
    if stages.get("dark_current", True):
        rate = meta.get("dark_current_effective_e_per_s", meta.get("dark_current_e_per_s", 0.0))  # at temperature_c
        dark = np.broadcast_to(np.asarray(rate, dtype=np.float64), (3,))
        var_e += dark[list(channel_of)] * float(meta["exposure_s"])
    if stages.get("read_noise", True):
        var_e += float(meta.get("read_noise_e") or 0.0) ** 2 + float(meta.get("row_noise_e") or 0.0) ** 2
    return k * np.sqrt(var_e)


def _normalise(image: np.ndarray):
    """Divide a DN image by its largest absolute value, so that it lies in [−1, 1]; returns (scaled, scale)."""
    scale = float(np.max(np.abs(image))) if image.size else 0.0
    if not (np.isfinite(scale) and scale > 0):
        scale = 1.0
    return np.asarray(image, dtype=np.float64) / scale, scale


def _sigma(image: np.ndarray, sigma_dn) -> np.ndarray:
    return estimate_noise_sigma(image) if sigma_dn is None else np.asarray(sigma_dn, dtype=np.float64)


def _rms_sigma(image: np.ndarray, sigma_dn) -> float:
    """One σ for all channels (for scikit-image's functions that take one): the root mean square of the
    per-channel σ. Unit: that of the image."""
    return float(np.sqrt(np.mean(np.square(_sigma(image, sigma_dn)))))


def identity(image: np.ndarray, sigma_dn=None) -> np.ndarray:
    """The control: the noisy image itself (a copy). Its scores are the noisy baseline's, exactly."""
    return np.array(image, dtype=np.float32, copy=True)


def nl_means(image: np.ndarray, sigma_dn=None) -> np.ndarray:
    """Non-local means (:func:`skimage.restoration.denoise_nl_means`, fast mode, ``channel_axis=-1``).

    The image is divided by its maximum; h = 0.8 σ and ``sigma`` = σ, with σ the root mean square of the
    per-channel estimates (scikit-image takes one σ for all channels).
    """
    from skimage.restoration import denoise_nl_means

    scaled, scale = _normalise(image)
    sigma = _rms_sigma(image, sigma_dn) / scale
    if not sigma > 0:
        return identity(image)
    out = denoise_nl_means(scaled, patch_size=NLM_PATCH_SIZE, patch_distance=NLM_PATCH_DISTANCE,
                           h=NLM_H_PER_SIGMA * sigma, sigma=sigma, fast_mode=True, preserve_range=True,
                           channel_axis=-1)
    return (out * scale).astype(np.float32)


def wavelet(image: np.ndarray, sigma_dn=None) -> np.ndarray:
    """Wavelet shrinkage: BayesShrink, soft thresholds, Haar (db1), per channel, with the per-channel σ.

    :func:`skimage.restoration.denoise_wavelet` (``channel_axis=-1``, no YCbCr conversion). The image is divided
    by its maximum first; the output is not clipped (scikit-image does not clip float images).
    """
    from skimage.restoration import denoise_wavelet

    scaled, scale = _normalise(image)
    sigma = _sigma(image, sigma_dn) / scale
    if not np.all(sigma > 0):
        return identity(image)
    out = denoise_wavelet(scaled, sigma=list(sigma), wavelet="db1", mode="soft", method="BayesShrink",
                          rescale_sigma=True, channel_axis=-1)
    return (out * scale).astype(np.float32)


def total_variation(image: np.ndarray, sigma_dn=None) -> np.ndarray:
    """Total-variation denoising (:func:`skimage.restoration.denoise_tv_chambolle`, per channel).

    The image is divided by its maximum; the weight (1/λ of the ROF problem) is 1 × the RMS σ of the normalised
    image, so the smoothing follows the noise level and not the image's scale.
    """
    from skimage.restoration import denoise_tv_chambolle

    scaled, scale = _normalise(image)
    sigma = _rms_sigma(image, sigma_dn) / scale
    if not sigma > 0:
        return identity(image)
    out = denoise_tv_chambolle(scaled, weight=TV_WEIGHT_PER_SIGMA * sigma, channel_axis=-1)
    return (out * scale).astype(np.float32)


BM3D_PROFILE = "np"
"""The ``bm3d`` package's parameter profile whose settings are used (its default, "normal profile"), but for
:data:`BM3D_STEP_PX`."""
BM3D_STEP_PX = 5
"""Reference blocks of both BM3D stages are taken every 5 pixels instead of the profile's 3: on 256 × 192 frames of
``scenes/denoise_small.toml`` (2 idle cores) 3.3 s a frame instead of 5.9, for an RMSE against the clean layer
larger by 0.1–0.9 %."""
BM3D_MISSING = ("the bm3d denoiser needs the Python package 'bm3d' (PyPI; free for non-commercial use), which is not "
                "installed: pip install bm3d")


def bm3d(image: np.ndarray, sigma_dn=None) -> np.ndarray:
    """BM3D (Dabov et al. 2007), the PyPI ``bm3d`` package's :func:`bm3d.bm3d_rgb`: block matching on the
    luminance of the opponent colour transform, collaborative hard thresholding then Wiener filtering.

    A (H, W, 3) image is denoised as colour; any other number of planes (a Bayer frame's packed R, G1, G2, B) plane
    by plane with the grey :func:`bm3d.bm3d`, each with its own σ.

    ``sigma_dn`` (3,) is the noise σ per R, G, B channel in DN — in ``denoise-eval`` the sensor model's
    (:func:`model_noise_sigma`), else estimated blindly. The image is shifted and scaled to [0, 1] per channel by
    ``bm3d_rgb`` itself, which scales the σ with it and carries the per-channel σ through the colour transform
    (noise independent between channels, as on a three-chip sensor). One σ per channel for the whole frame: the
    signal-dependent shot noise enters as its frame RMS.

    Raises
    ------
    CamsimError
        The ``bm3d`` package is not installed.
    """
    try:
        import bm3d as bm3d_package
    except ImportError:
        raise CamsimError(BM3D_MISSING) from None
    sigma = _sigma(image, sigma_dn)
    if not np.all(sigma > 0):
        return identity(image)
    image64 = np.asarray(image, dtype=np.float64)
    if not float(np.ptp(image64)) > 0:
        return identity(image)
    profile = bm3d_package.BM3DProfile()  # the "np" profile's settings
    profile.step_ht = profile.step_wiener = BM3D_STEP_PX
    if image64.ndim == 3 and image64.shape[-1] == 3:
        out = bm3d_package.bm3d_rgb(image64, [float(s) for s in sigma], profile=profile)
        return np.asarray(out, dtype=np.float32)
    # Any other number of planes (a Bayer frame's packed R, G1, G2, B): each plane on its own, grey BM3D.
    planes = image64[..., None] if image64.ndim == 2 else image64
    sigma = np.broadcast_to(sigma, (planes.shape[-1],))
    out = np.empty(planes.shape, dtype=np.float32)
    for i in range(planes.shape[-1]):
        out[..., i] = np.asarray(bm3d_package.bm3d(planes[..., i], float(sigma[i]), profile=profile)).reshape(
            planes.shape[:2])
    return out.reshape(image64.shape)


def bm3d_available() -> bool:
    """Whether the ``bm3d`` package can be imported."""
    return importlib.util.find_spec("bm3d") is not None


DENOISERS: dict[str, Callable] = {
    "identity": identity,
    "nl-means": nl_means,
    "wavelet": wavelet,
    "tv": total_variation,
    "bm3d": bm3d,
}
"""The built-in denoisers: ``f(image (H, W, 3) float32 DN, sigma_dn (3,) or None) -> (H, W, 3)``."""

BUILTIN_DESCRIPTIONS = {
    "identity": "the control: returns the noisy frame unchanged",
    "nl-means": f"scikit-image non-local means, fast mode, {NLM_PATCH_SIZE}×{NLM_PATCH_SIZE} patches within "
                f"±{NLM_PATCH_DISTANCE} px, h = {NLM_H_PER_SIGMA:g} σ",
    "wavelet": "wavelet shrinkage (scikit-image's denoise_wavelet algorithm), BayesShrink, soft thresholds, Haar, "
               "per channel",
    "tv": f"scikit-image total variation (Chambolle), weight = {TV_WEIGHT_PER_SIGMA:g} σ, per channel",
    "bm3d": f"BM3D (PyPI bm3d, bm3d_rgb, profile '{BM3D_PROFILE}' with reference blocks every {BM3D_STEP_PX} px, "
            "opponent colour space), given the sensor model's noise σ per channel",
}

#: Which noise level each built-in is given (:data:`SIGMA_BLIND` unless listed).
BUILTIN_SIGMA = {"bm3d": SIGMA_MODEL}


@dataclass(frozen=True)
class Denoiser:
    """A resolved denoiser target.

    Attributes
    ----------
    target : str
        As given (``nl-means``, ``pkg.mod:fn``, ``cmd:...``).
    name : str
        Short name for tables, plots and file names.
    kind : {'builtin', 'function', 'command'}
    description : str
    function : callable
        ``function(image, sigma_dn) -> array``; use :meth:`__call__`, which checks the result.
    sigma_source : {'blind', 'model'}
        The noise level it is given: estimated from the noisy image (:func:`estimate_noise_sigma`) or the sensor
        model's (:func:`model_noise_sigma`).
    """

    target: str
    name: str
    kind: str
    description: str
    function: Callable
    sigma_source: str = SIGMA_BLIND

    def __call__(self, image: np.ndarray, sigma_dn=None) -> np.ndarray:
        """Denoise an image (see the module docstring: (H, W, 3) DN, or a Bayer frame's normalised (H/2, W/2, 4)
        planes or (H, W) mosaic); the result is checked: same shape, finite, float32.

        Raises
        ------
        CamsimError
            The denoiser raised, or returned an array of another shape, a non-numeric or a non-finite array.
        """
        try:
            out = self.function(np.array(image, dtype=np.float32, copy=True), sigma_dn)
        except CamsimError:
            raise
        except Exception as exc:  # the user's code failing is reported as one line, like any bad input
            raise CamsimError(f"denoiser {self.target!r} failed: {type(exc).__name__}: {exc}") from exc
        except SystemExit as exc:  # sys.exit() in the user's code is no result (Ctrl-C, KeyboardInterrupt, stays)
            raise CamsimError(f"denoiser {self.target!r} failed: it called sys.exit({exc.code!r}) instead of "
                              "returning an array") from None
        try:
            out = np.asarray(out)
        except Exception as exc:
            raise CamsimError(f"denoiser {self.target!r} returned {type(out).__name__}, not an array") from exc
        if out.shape != image.shape:
            raise CamsimError(f"denoiser {self.target!r} returned an array of shape {out.shape} for an input of "
                              f"shape {image.shape}; it must return the same shape {_layout(image.shape)}")
        if out.dtype.kind not in "biuf":
            raise CamsimError(f"denoiser {self.target!r} returned a {out.dtype} array; expected numbers")
        out = out.astype(np.float32)
        if not np.all(np.isfinite(out)):
            raise CamsimError(f"denoiser {self.target!r} returned {np.count_nonzero(~np.isfinite(out))} non-finite "
                              "values (NaN or inf)")
        return out


def _layout(shape) -> str:
    """How an input of ``shape`` is laid out, for messages."""
    if len(shape) == 2:
        return "(H, W): a Bayer mosaic"
    if len(shape) == 3 and shape[-1] == 4:
        return "(H/2, W/2, 4): packed planes R, G1, G2, B"
    return "(H, W, 3)"


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]+", "_", text).strip("_.") or "denoiser"


def _load_module(spec_text: str, target: str):
    """Import ``spec_text``: a dotted module name (current directory first on sys.path) or a ``.py`` file."""
    if spec_text.endswith(".py") or os.sep in spec_text or "/" in spec_text:
        path = Path(spec_text).expanduser().resolve()
        if not path.is_file():
            raise CamsimError(f"denoiser {target!r}: no such Python file {path}")
        name = f"camsim_user_denoiser_{_slug(path.stem)}"
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            raise CamsimError(f"denoiser {target!r}: cannot load {path} as a Python module")
        module = importlib.util.module_from_spec(spec)
        try:
            spec.loader.exec_module(module)
        except Exception as exc:
            raise CamsimError(f"denoiser {target!r}: importing {path} failed: {type(exc).__name__}: {exc}") from exc
        except SystemExit as exc:
            raise CamsimError(f"denoiser {target!r}: importing {path} called sys.exit({exc.code!r})") from None
        return module
    cwd = os.getcwd()
    added = cwd not in sys.path and "" not in sys.path
    if added:
        sys.path.insert(0, cwd)
    try:
        return importlib.import_module(spec_text)
    except ModuleNotFoundError as exc:
        raise CamsimError(f"denoiser {target!r}: no module named {exc.name or spec_text!r} (looked in the current "
                          "directory and on sys.path)") from exc
    except Exception as exc:
        raise CamsimError(f"denoiser {target!r}: importing {spec_text!r} failed: {type(exc).__name__}: {exc}") from exc
    except SystemExit as exc:
        raise CamsimError(f"denoiser {target!r}: importing {spec_text!r} called sys.exit({exc.code!r})") from None
    finally:
        if added:
            sys.path.remove(cwd)


def _function_denoiser(target: str) -> Denoiser:
    module_text, _, attr = target.rpartition(":")
    if not module_text or not attr:
        raise CamsimError(f"denoiser {target!r}: expected MODULE:FUNCTION, e.g. mypkg.filters:denoise")
    module = _load_module(module_text, target)
    obj = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise CamsimError(f"denoiser {target!r}: module {module_text!r} has no attribute {attr!r}") from None
    if not callable(obj):
        raise CamsimError(f"denoiser {target!r}: {attr!r} is a {type(obj).__name__}, not a function")
    try:
        params = inspect.signature(obj).parameters
        takes_sigma = "sigma_dn" in params
    except (TypeError, ValueError):  # builtins without a signature
        takes_sigma = False

    def call(image, sigma_dn):
        return obj(image, sigma_dn=sigma_dn) if takes_sigma else obj(image)

    name = _slug(f"{Path(module_text).stem if module_text.endswith('.py') else module_text}.{attr}")
    how = "image, sigma_dn=σ" if takes_sigma else "image"
    return Denoiser(target, name, "function", f"user function {module_text}:{attr}({how})", call)


def _tail(text: str) -> str:
    text = (text or "").strip()
    if len(text) > STDERR_TAIL_CHARS:
        text = "…" + text[-STDERR_TAIL_CHARS:]
    return text or "(no output on stderr)"


def _kill_group(process: subprocess.Popen) -> None:
    """SIGKILL the process group that ``process`` leads (it and every child it started), then reap it."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):  # the group is gone already
        pass
    process.wait()


def _run_in_own_group(args: list[str], timeout_s: float | None, folder: Path) -> subprocess.CompletedProcess:
    """Run ``args`` in a new session (its own process group), like :func:`subprocess.run`, with its standard output
    and error captured in files of ``folder`` (not pipes: a child left running in the background would hold a pipe
    open, and reading it to its end would wait for that child).

    Whatever happens — a normal exit, a non-zero status, ``timeout_s`` (seconds) running out, Ctrl-C, SIGTERM — the
    whole group is killed as soon as the command itself ends or is given up, so that no child it started (e.g. a
    shell script's ``sleep``) outlives it as an orphan.

    Raises
    ------
    subprocess.TimeoutExpired
        The command ran longer than ``timeout_s``; its ``stderr`` holds what the command had written there.
    OSError
        The command could not be started.
    """
    out_path, err_path = folder / "command.stdout", folder / "command.stderr"

    def captured(path):  # the end of what the command wrote (a chatty command may write megabytes)
        with open_input(path, "denoiser command's output") as file:  # the command may have put a FIFO there
            file.seek(max(0, file.seek(0, os.SEEK_END) - 4 * STDERR_TAIL_CHARS))
            return file.read().decode("utf-8", errors="replace")

    with open(out_path, "wb") as out, open(err_path, "wb") as err:
        process = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=out, stderr=err, start_new_session=True)
    try:
        process.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        _kill_group(process)
        raise subprocess.TimeoutExpired(args, timeout_s, captured(out_path), captured(err_path)) from None
    except BaseException:  # Ctrl-C, SIGTERM, anything: no orphan
        _kill_group(process)
        raise
    _kill_group(process)  # the command exited; children it left behind go with it
    return subprocess.CompletedProcess(args, process.returncode, captured(out_path), captured(err_path))


#: The EXR channels of a Bayer frame's packed planes given to (and read back from) a ``cmd:`` denoiser.
PACKED_CHANNELS = ("R", "G1", "G2", "B")


#: The EXR channel of a Bayer mosaic given to (and read back from) a ``cmd:`` denoiser.
MOSAIC_CHANNEL = "CFA"


def _write_input_exr(path: Path, planes: dict, header: dict) -> None:
    """The noisy frame a ``cmd:`` denoiser reads: an uncompressed float32 EXR with ``planes`` (name → 2-D array) as
    its channels and ``header``'s string attributes.

    Written with the OpenEXR bindings straight into the private temporary folder, not with
    :func:`camsim.io.exr.write_exr`: that one writes atomically and only inside the output folder a run holds
    (:func:`camsim.io.atomic.confined_to`), which this temporary file, no output of the run, lies outside of.
    """
    import OpenEXR

    channels = {c: np.ascontiguousarray(v, dtype=np.float32) for c, v in planes.items()}
    try:
        with OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage, **header},
                          channels) as exr:
            exr.write(str(path))
    except RuntimeError as exc:  # OpenEXR reports a failed write (no space, I/O error) as RuntimeError
        raise CamsimError(f"cannot write the denoiser's input {path}: {exc}") from None


def _read_planes_exr(path: Path, template: str) -> np.ndarray:
    """The (h, w, 4) planes of channels R, G1, G2, B of an EXR a ``cmd:`` denoiser wrote."""
    import OpenEXR

    check_input(path, f"EXR the denoiser command {template!r} wrote")  # a FIFO there would block OpenEXR
    try:
        with OpenEXR.File(str(path), header_only=True) as exr:  # the size, before the pixels are decoded
            (x0, y0), (x1, y1) = ((int(v) for v in corner) for corner in exr.header()["dataWindow"])
        check_pixel_count(x1 - x0 + 1, y1 - y0 + 1, f"EXR the denoiser command {template!r} wrote")
        with OpenEXR.File(str(path), separate_channels=True) as exr:
            found = {k: np.array(v.pixels) for k, v in exr.channels().items()}
    except CamsimError:
        raise
    except Exception as exc:
        raise CamsimError(f"denoiser command {template!r} wrote an unreadable EXR: {type(exc).__name__}: "
                          f"{exc}") from None
    missing = [c for c in PACKED_CHANNELS if c not in found]
    if missing:
        raise CamsimError(f"denoiser command {template!r} wrote an EXR without channel(s) {', '.join(missing)} "
                          f"(a Bayer frame's packed planes are channels {', '.join(PACKED_CHANNELS)})")
    shapes = {found[c].shape for c in PACKED_CHANNELS}
    if len(shapes) != 1:
        raise CamsimError(f"denoiser command {template!r} wrote channels of different sizes")
    return np.stack([found[c] for c in PACKED_CHANNELS], axis=-1)


def _command_denoiser(target: str, timeout_s: float | None) -> Denoiser:
    template = target[len(COMMAND_PREFIX):].strip()
    try:
        argv = shlex.split(template)
    except ValueError as exc:
        raise CamsimError(f"denoiser {target!r}: cannot split the command line: {exc}") from None
    if not argv:
        raise CamsimError(f"denoiser {target!r}: empty command; expected 'cmd:PROGRAM ARGS... {{input}} {{output}}'")
    for placeholder in (INPUT_PLACEHOLDER, OUTPUT_PLACEHOLDER):
        if not any(placeholder in arg for arg in argv):
            raise CamsimError(f"denoiser {target!r}: the command must contain {placeholder} (replaced by the path "
                              "of the "
                              f"{'noisy EXR it reads' if placeholder == INPUT_PLACEHOLDER else 'EXR it writes'})")
    program = argv[0]
    if shutil.which(program) is None and not Path(program).is_file():
        raise CamsimError(f"denoiser {target!r}: program {program!r} not found")

    def run(image, sigma_dn):
        from camsim.io.exr import read_exr

        with tempfile.TemporaryDirectory(prefix="camsim-denoise-") as tmp:
            source, result = Path(tmp) / "noisy.exr", Path(tmp) / "denoised.exr"
            header = {"camsim:units": "DN" if image.ndim == 3 and image.shape[-1] == 3 else
                      "normalised: 0 = black, 1 = the white level"}
            if sigma_dn is not None:
                header["camsim:denoise_sigma_dn"] = json.dumps([float(s) for s in np.ravel(sigma_dn)])
            if image.ndim == 2:  # a Bayer mosaic: one channel CFA
                _write_input_exr(source, {MOSAIC_CHANNEL: image}, header)
            elif image.shape[-1] == 3:
                _write_input_exr(source, {c: image[..., i] for i, c in enumerate("RGB")}, header)
            else:  # packed planes R, G1, G2, B
                _write_input_exr(source, {c: image[..., i] for i, c in enumerate(PACKED_CHANNELS)}, header)
            args = [a.replace(INPUT_PLACEHOLDER, str(source)).replace(OUTPUT_PLACEHOLDER, str(result)) for a in argv]
            try:
                done = _run_in_own_group(args, timeout_s, Path(tmp))
            except subprocess.TimeoutExpired as exc:
                raise CamsimError(f"denoiser command {template!r} did not finish within {timeout_s:g} s; stderr: "
                                  f"{_tail(exc.stderr if isinstance(exc.stderr, str) else '')}") from None
            except OSError as exc:
                raise CamsimError(f"denoiser command {template!r} could not start: {exc}") from None
            if done.returncode != 0:
                raise CamsimError(f"denoiser command {template!r} failed with exit status {done.returncode}; "
                                  f"stderr: {_tail(done.stderr)}")
            if not result.is_file():
                raise CamsimError(f"denoiser command {template!r} exited with status 0 but wrote no {{output}} EXR; "
                                  f"stderr: {_tail(done.stderr)}")
            if image.ndim == 3 and image.shape[-1] == 4:
                return _read_planes_exr(result, template)
            pixels, _, _ = read_exr(result)
        if image.ndim == 2:
            if pixels.shape[0] != 1:
                raise CamsimError(f"denoiser command {template!r} wrote an EXR without the channel CFA")
            return pixels[0]
        if pixels.shape[0] != 3:
            raise CamsimError(f"denoiser command {template!r} wrote an EXR without channels R, G, B")
        return np.moveaxis(pixels, 0, -1)

    name = _slug(f"cmd-{Path(program).stem}")
    return Denoiser(target, name, "command", f"command `{template}`", run)


def resolve_denoiser(target: str, timeout_s: float | None = None) -> Denoiser:
    """The denoiser a target names: a built-in name, ``MODULE:FUNCTION`` or ``cmd:COMMAND {input} {output}``.

    Modules are imported and commands checked (placeholders present, program found) here, before any frame is
    processed.

    Raises
    ------
    CamsimError
        Unknown name, a module or function that cannot be imported, a command without ``{input}`` / ``{output}``
        or whose program does not exist.
    """
    if not isinstance(target, str) or not target.strip():
        raise CamsimError("empty denoiser name")
    target = target.strip()
    if target in DENOISERS:
        if target == "bm3d" and not bm3d_available():
            raise CamsimError(BM3D_MISSING)
        return Denoiser(target, target, "builtin", BUILTIN_DESCRIPTIONS[target],
                        lambda image, sigma_dn, f=DENOISERS[target]: f(image, sigma_dn),
                        BUILTIN_SIGMA.get(target, SIGMA_BLIND))
    if target.startswith(COMMAND_PREFIX):
        return _command_denoiser(target, timeout_s)
    if ":" in target:
        return _function_denoiser(target)
    raise CamsimError(f"unknown denoiser {target!r}: built-ins are {', '.join(DENOISERS)}; a function is "
                      "MODULE:FUNCTION, a command 'cmd:PROGRAM ARGS... {input} {output}'")

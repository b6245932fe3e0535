"""The ISP's pipeline: settings, the whole development of a frame, each stage's image, and noisy/clean pairs
through the same ISP."""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.isp.stages import (
    CHROMATIC_ADAPTATION,
    DEMOSAIC_METHODS,
    DEMOSAIC_PAD,
    DEMOSAIC_SOURCES,
    MATRICES,
    PER_CHANNEL_LINEAR,
    TONE_CURVES,
    WHITE_BALANCE_MODES,
    _bilinear,
    _bilinear_padded,
    _normalise_into,
    _srgb,
    _srgb_matrix,
    _workspace,
    apply_gain,
    apply_matrix,
    apply_white_balance,
    demosaic,
    normalise,
    tone_curve,
    white_balance_gains,
)

__all__ = ["IspSettings", "Developed", "develop", "develop_stages", "develop_pair", "STAGE_NAMES", "GAIN_MODES"]

#: The named gains: ``"auto"`` = 1 / F; ``"white"`` = the perfect white at the frame's F maps to 1.
GAIN_MODES = ("auto", "white")
#: The keys of :func:`develop_stages`, in the order of the pipeline.
STAGE_NAMES = ("raw", "normalised", "white_balanced", "demosaiced", "srgb_linear", "gained", "toned")


@dataclass(frozen=True)
class IspSettings:
    """The ISP's settings: every stage switchable by name.

    Attributes
    ----------
    black : bool
        Subtract the black level (else only divide by the white level: 0 = zero DN).
    white_balance : str
        ``"as-shot"`` (the frame's AsShotNeutral: the perfect white under the frame's illuminant becomes neutral),
        ``"none"``, or a colour-science illuminant name (e.g. ``"D65"``, ``"A"``): the white under that light.
    demosaic : str
        A key of :data:`camsim.isp.stages.DEMOSAIC_METHODS` (``"bilinear"``, ``"malvar2004"``, ``"menon2007"``);
        ignored for three-chip frames.
    matrix : str
        ``"camera"`` (camera → linear sRGB from the camera's spectral sensitivities and the white-balance
        illuminant, :func:`camsim.isp.stages.srgb_matrix`), ``"paper"`` (from the paper's Eq. 15 projection of
        the sensitivities), ``"dng"`` (from the DNG's ColorMatrix1, as raw converters do) or ``"none"``.
    gain : float or "auto" or "white"
        A digital gain on the linear values (1 = the white level stays 1), ``"auto"`` = 1 / F, F the frame's
        intensity factor (the SID/ELD exposure ratio), or ``"white"``: the perfect white under the frame's light
        at its F maps to 1 (1 / its green level, from the sidecar's ``white_signal_e``).
    tone : str
        A key of :data:`camsim.isp.stages.TONE_CURVES`: ``"srgb"``, ``"filmic"``, ``"linear"``.
    """

    black: bool = True
    white_balance: str = "as-shot"
    demosaic: str = "malvar2004"
    matrix: str = "camera"
    gain: float | str = 1.0
    tone: str = "srgb"

    def __post_init__(self):
        if not isinstance(self.black, bool):
            raise CamsimError(f"black must be True or False, got {self.black!r}")
        if not isinstance(self.white_balance, str) or not self.white_balance:
            raise CamsimError(f"white balance must be {', '.join(WHITE_BALANCE_MODES)} or an illuminant name, got "
                              f"{self.white_balance!r}")
        if self.demosaic not in DEMOSAIC_METHODS:
            raise CamsimError(f"unknown demosaicing method {self.demosaic!r}; methods: {', '.join(DEMOSAIC_METHODS)}")
        if self.matrix not in MATRICES:
            raise CamsimError(f"unknown colour matrix {self.matrix!r}; matrices: {', '.join(MATRICES)}")
        if self.tone not in TONE_CURVES:
            raise CamsimError(f"unknown tone curve {self.tone!r}; curves: {', '.join(TONE_CURVES)}")
        gain = self.gain
        if isinstance(gain, str):
            if gain not in GAIN_MODES:
                raise CamsimError(f"gain must be a positive number, 'auto' or 'white', got {gain!r}")
        elif isinstance(gain, bool) or not isinstance(gain, (int, float)) or not (np.isfinite(gain) and gain > 0):
            raise CamsimError(f"gain must be a positive number, 'auto' or 'white', got {gain!r}")
        else:
            object.__setattr__(self, "gain", float(gain))

    def record(self) -> dict:
        """The settings as a JSON-ready dict (for metadata)."""
        return dataclasses.asdict(self)


@dataclass(frozen=True, eq=False)
class Developed:
    """A developed image.

    Attributes
    ----------
    image : numpy.ndarray, shape (3, H, W), float32
        sRGB R, G, B after the tone curve, in [0, 1].
    record : dict
        Every stage's name and parameters, the colour matrix, the white-balance gains, the gain, the facts used
        and camsim's version (JSON-ready).
    """

    image: np.ndarray
    record: dict


@dataclass(frozen=True, eq=False)
class _Plan:
    """What the ISP applies to every frame with the same facts and settings."""

    gains: np.ndarray  # (3,)
    matrix: np.ndarray | None  # (3, 3) or None
    gain: float
    record: dict


_GAIN_RECORD = {"auto": "auto (1 / F)", "white": "white (the perfect white at this F -> 1)"}
_SRGB = "IEC 61966-2-1: 12.92 x for x <= 0.0031308, else 1.055 x^(1/2.4) - 0.055, on x clipped to [0, 1]"
_TONE_RECORD = {
    "srgb": _SRGB,
    "filmic": "Narkowicz 2015 ACES fit f(x) = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), clipped to [0, 1], "
              "then " + _SRGB,
    "linear": "x clipped to [0, 1]",
}


@functools.lru_cache(maxsize=None)
def _version(distribution: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(distribution)
    except PackageNotFoundError:
        return "(version unknown)"


def _bytes(a) -> bytes | None:
    return None if a is None else np.ascontiguousarray(a, dtype=np.float64).tobytes()


#: The white-balance gains and colour matrices computed, by settings and the facts' colour (:func:`_colour`).
_COLOUR_CACHE: dict = {}
_COLOUR_CACHE_SIZE = 64


def _colour(facts, settings: IspSettings) -> tuple:
    """(white-balance gains (3,), colour matrix (3, 3) or None, what the matrix's camera → XYZ is): the numbers of
    :func:`white_balance_gains` and :func:`camsim.isp.stages.srgb_matrix`, kept (read-only) per settings and the
    facts' colour — the neutral, the illuminant, the QE and its grid, ColorMatrix1 — since a pair batch reuses a
    few cameras and illuminants."""
    key = (settings.white_balance, settings.matrix, facts.illuminant, _bytes(facts.as_shot_neutral),
           _bytes(facts.qe), _bytes(facts.wavelengths_nm), _bytes(facts.color_matrix1))
    found = _COLOUR_CACHE.get(key)
    if found is None:
        gains = np.asarray(white_balance_gains(facts, settings.white_balance), dtype=np.float64)
        m, to_xyz = (_srgb_matrix(facts, settings.white_balance, settings.matrix) if settings.matrix != "none"
                     else (None, None))
        for a in (gains, m):
            if a is not None:
                a.setflags(write=False)
        if len(_COLOUR_CACHE) >= _COLOUR_CACHE_SIZE:
            _COLOUR_CACHE.clear()
        found = _COLOUR_CACHE[key] = (gains, m, to_xyz)
    return found


def _plan(facts, settings: IspSettings) -> _Plan:
    import camsim

    gains, matrix, to_xyz = _colour(facts, settings)
    if settings.gain == "auto":
        if facts.intensity_factor is None:
            raise CamsimError("gain 'auto' (1 / F) needs the frame's intensity factor F, which only its sidecar "
                              "gives; give a number")
        gain = 1.0 / facts.intensity_factor
    elif settings.gain == "white":
        if facts.white_signal_dn is None:
            raise CamsimError("gain 'white' needs the perfect white's signal (the sidecar's white_signal_e), which "
                              "this frame's metadata lacks; give a number")
        span = facts.white_dn - (facts.black_dn[1] if settings.black else 0.0)  # what normalise divides by
        gain = span / facts.white_signal_dn[1]
    else:
        gain = float(settings.gain)
    record = {
        "camsim_version": camsim.__version__,
        "settings": settings.record(),
        "stages": {
            "black": {"on": settings.black, "black_dn": facts.black_dn.tolist() if settings.black else [0.0] * 3,
                      "white_dn": facts.white_dn,
                      "formula": "(raw - black_c) / (white - black_c)"},
            "white_balance": {"mode": settings.white_balance, "gains": gains.tolist(),
                              "formula": "gain_c = neutral_G / neutral_c (neutral: the camera's response to the "
                                         "perfect white under the white-balance illuminant)"},
            "demosaic": ({"method": settings.demosaic,
                          "library": (DEMOSAIC_SOURCES[settings.demosaic] if settings.demosaic in PER_CHANNEL_LINEAR
                                      else f"colour-demosaicing {_version('colour-demosaicing')}")}
                         if facts.cfa_pattern is not None else None),
            "matrix": {"name": settings.matrix,
                       "matrix": None if matrix is None else matrix.tolist(),
                       "camera_to_xyz": to_xyz,
                       "adaptation": (None if settings.white_balance == "none"
                                      else f"von Kries ({CHROMATIC_ADAPTATION}) from the white-balance white to D65"),
                       "output": "linear sRGB (IEC 61966-2-1 primaries, D65 white)"},
            "gain": {"mode": _GAIN_RECORD.get(settings.gain, "fixed") if isinstance(settings.gain, str) else "fixed",
                     "value": gain},
            "tone": {"name": settings.tone, "formula": _TONE_RECORD[settings.tone]},
        },
        "facts": facts.record(),
    }
    return _Plan(gains, matrix, gain, record)


def _run(raw, facts, settings: IspSettings, plan: _Plan, keep: dict | None) -> np.ndarray:
    def stage(name, value):
        if keep is not None:
            keep[name] = value
        return value

    cfa = facts.cfa_pattern
    raw = np.asarray(raw)
    if cfa is not None and raw.ndim == 3 and raw.shape[0] == 1:
        raw = raw[0]
    stage("raw", raw)
    use = facts if settings.black else dataclasses.replace(facts, black_dn=np.zeros(3))
    x = stage("normalised", normalise(raw, use))
    x = stage("white_balanced", apply_white_balance(x, plan.gains, cfa) if settings.white_balance != "none" else x)
    x = stage("demosaiced", demosaic(x, cfa, settings.demosaic) if cfa is not None else x)
    x = stage("srgb_linear", apply_matrix(x, plan.matrix) if plan.matrix is not None else x)
    x = stage("gained", apply_gain(x, plan.gain) if plan.gain != 1.0 else x)
    return stage("toned", tone_curve(x, settings.tone))


def _linear_after_demosaic(facts, settings: IspSettings) -> bool:
    """Whether the white balance, the colour matrix and the gain can be one 3 × 3 matrix after demosaicing: a
    three-chip frame, or a demosaicing that is linear per channel (:data:`camsim.isp.stages.PER_CHANNEL_LINEAR`)."""
    return facts.cfa_pattern is None or settings.demosaic in PER_CHANNEL_LINEAR


def _fused_matrix(plan: _Plan) -> np.ndarray:
    """gain · M · diag(white-balance gains), float64 (3, 3): the three linear stages in one."""
    m = np.eye(3) if plan.matrix is None else np.asarray(plan.matrix, dtype=np.float64)
    return plan.gain * (m * np.asarray(plan.gains, dtype=np.float64)[None, :])


def _run_fused(raw, facts, settings: IspSettings, plan: _Plan, out: np.ndarray | None = None) -> np.ndarray:
    """:func:`_run` where :func:`_linear_after_demosaic`: normalise → demosaic (without the white balance) → one
    3 × 3 matrix (:func:`_fused_matrix`) → tone curve, in float32; the result in ``out`` ((3, H, W) float32,
    C-contiguous) if given. Exact in exact arithmetic (per-channel gains before a per-channel linear demosaicing
    equal the same gains after it; the gain and the matrix commute with both); in float32 it differs from the
    stage-by-stage result by rounding alone."""
    cfa = facts.cfa_pattern
    raw = np.asarray(raw)
    if cfa is not None and raw.ndim == 3 and raw.shape[0] == 1:
        raw = raw[0]
    black = facts.black_dn if settings.black else np.zeros(3)
    if cfa is None:
        x = _normalise_into(raw, facts, black, _workspace("develop.normalised", raw.shape))
    elif raw.ndim == 2 and min(raw.shape) > DEMOSAIC_PAD:
        height, width = raw.shape
        padded = _workspace("bilinear.padded", (height + 2, width + 2))
        _normalise_into(raw, facts, black, padded[1:-1, 1:-1])
        x = _bilinear_padded(padded, cfa, _workspace("develop.demosaiced", (3, height, width)))
    else:  # a small mosaic (colour-demosaicing's border rules), or a wrong shape (normalise says so)
        x = _bilinear(normalise(raw, dataclasses.replace(facts, black_dn=black)), cfa)
    if out is None:
        out = np.empty(x.shape, dtype=np.float32)
    elif not (out.shape == x.shape and out.dtype == np.float32 and out.flags.c_contiguous):
        raise CamsimError(f"the ISP's output must be a C-contiguous float32 array of shape {x.shape}")
    a = _fused_matrix(plan)
    if np.array_equal(a, np.eye(3)):
        np.copyto(out, x)
    else:
        np.matmul(a.astype(np.float32), x.reshape(3, -1), out=out.reshape(3, -1))
    if settings.tone == "srgb":
        return _srgb(out, out=out, scratch=x)
    np.copyto(out, tone_curve(out, settings.tone))
    return out


def _develop(raw, facts, settings: IspSettings, plan: _Plan, out: np.ndarray | None = None) -> np.ndarray:
    if _linear_after_demosaic(facts, settings):
        return _run_fused(raw, facts, settings, plan, out)
    image = _run(raw, facts, settings, plan, None)
    if out is None:
        return image
    np.copyto(out, image)
    return out


def _develop_pair_into(noisy, clean, facts, settings: IspSettings, out_noisy, out_clean) -> dict:
    """:func:`develop_pair` with the images written into ``out_noisy`` and ``out_clean`` ((3, H, W) float32,
    C-contiguous: e.g. a batch's slots); returns the record."""
    noisy, clean = np.asarray(noisy), np.asarray(clean)
    if noisy.shape != clean.shape:
        raise CamsimError(f"noisy and clean frames differ in shape: {noisy.shape} and {clean.shape}")
    plan = _plan(facts, settings)
    _develop(noisy, facts, settings, plan, out_noisy)
    _develop(clean, facts, settings, plan, out_clean)
    return plan.record


def develop(raw, facts, settings: IspSettings = IspSettings()) -> Developed:
    """Develop a frame's numbers into an sRGB image.

    Parameters
    ----------
    raw : array_like, shape (3, H, W), or (H, W) / (1, H, W) for a Bayer mosaic
        The frame's numbers. Unit: DN (those of ``facts``).
    facts : IspFacts
        What the ISP knows about the frame (:func:`camsim.isp.facts_of`, :func:`camsim.isp.facts_from_info`, …).
    settings : IspSettings

    Returns
    -------
    Developed
        ``image`` (3, H, W) float32 in [0, 1] and its ``record``.

    Stages: :func:`camsim.isp.normalise` → :func:`camsim.isp.apply_white_balance` (gains of
    :func:`camsim.isp.white_balance_gains`) → :func:`camsim.isp.demosaic` (Bayer frames) →
    :func:`camsim.isp.apply_matrix` (:func:`camsim.isp.srgb_matrix`) → :func:`camsim.isp.apply_gain` →
    :func:`camsim.isp.tone_curve` (which clips to [0, 1]). With a demosaicing that is linear per channel
    (bilinear; :data:`camsim.isp.stages.PER_CHANNEL_LINEAR`) or a three-chip frame, the white balance, the matrix
    and the gain are one 3 × 3 matrix, gain · M · diag(gains), applied after demosaicing: the same in exact
    arithmetic (per-channel gains commute with such a demosaicing), the same but for float32 rounding here.
    """
    plan = _plan(facts, settings)
    return Developed(_develop(raw, facts, settings, plan), plan.record)


def develop_stages(raw, facts, settings: IspSettings = IspSettings()) -> dict[str, np.ndarray]:
    """The image after each stage of :func:`develop`, keyed :data:`STAGE_NAMES`: ``"raw"`` (the input),
    ``"normalised"``, ``"white_balanced"`` (a mosaic stays (H, W) until ``"demosaiced"``), ``"demosaiced"``
    (3, H, W), ``"srgb_linear"``, ``"gained"``, ``"toned"`` (``develop(...).image``: the same numbers with Malvar
    2004 or Menon 2007; with bilinear demosaicing or a three-chip frame, where :func:`develop` applies the white
    balance, the matrix and the gain as one matrix, the same but for float32 rounding). A stage switched off gives
    its input. For the noise analysis."""
    keep: dict[str, np.ndarray] = {}
    _run(raw, facts, settings, _plan(facts, settings), keep)
    return keep


def develop_pair(noisy, clean, facts, settings: IspSettings = IspSettings()) -> tuple[Developed, Developed]:
    """Develop a noisy frame and its clean target through the same ISP: the same white-balance gains, colour matrix
    and gain (both from ``facts``), the same demosaicing and tone curve. ``noisy`` and ``clean`` have the same
    shape and units."""
    noisy, clean = np.asarray(noisy), np.asarray(clean)
    if noisy.shape != clean.shape:
        raise CamsimError(f"noisy and clean frames differ in shape: {noisy.shape} and {clean.shape}")
    plan = _plan(facts, settings)
    return (Developed(_develop(noisy, facts, settings, plan), plan.record),
            Developed(_develop(clean, facts, settings, plan), plan.record))

"""What the ISP needs to know about a frame: :class:`IspFacts`, from a sidecar, a loaded frame, an in-memory frame
or a DNG's own tags."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.schema import shown
from camsim.sensor.cfa import CFA_PATTERNS

__all__ = ["IspFacts", "facts_from_meta", "facts_of", "facts_from_info", "facts_from_dng_tags", "float_white_dn"]



@dataclass(frozen=True, eq=False)
class IspFacts:
    """What the ISP needs to know about a frame besides its numbers.

    Attributes
    ----------
    cfa_pattern : str or None
        The Bayer pattern of a mosaic (``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"``), None for a three-chip frame.
    black_dn : numpy.ndarray, shape (3,)
        The level subtracted per channel R, G, B, in the units of the numbers developed: a DNG's quantised numbers
        take the sidecar's ``black_level_dn`` (the mean digital number of an unlit pixel), an EXR's or an
        in-memory ``noisy_dn``'s the level before the ADC (``dark_level_dn``). Unit: DN.
    white_dn : float
        The white level 2^nb − 1 in the same units. Unit: DN. For the float values before the ADC it is moved by
        the offset between the two black levels (:func:`float_white_dn`): the ADC adds the pedestal P and rounds,
        so the quantised white 2^nb − 1 is the float value 2^nb − 1 − P (2^nb − ½ without a pedestal), and a
        frame's DNG and EXR normalise to the same values.
    as_shot_neutral : numpy.ndarray, shape (3,)
        The camera's response to the perfect white under the frame's illuminant (any scale; camsim writes it
        with its largest component 1).
    intensity_factor : float or None
        The frame's intensity factor F (the SID/ELD exposure ratio is 1 / F); None where unknown (a DNG without
        its sidecar).
    illuminant : str or None
        The name of the frame's illuminant (colour-science's), None where unknown.
    wavelengths_nm : numpy.ndarray, shape (N,), or None
        The wavelength grid of ``qe``. Unit: nm.
    qe : numpy.ndarray, shape (3, N), or None
        The camera's quantum efficiency per channel on ``wavelengths_nm`` (any common scale). Unit:
        e⁻·m²·sr/photon in a sidecar.
    color_matrix1 : numpy.ndarray, shape (3, 3), or None
        The DNG's ColorMatrix1 (XYZ → camera under D65), used for the colour matrix where ``qe`` is None (or where
        the settings ask for it: ``matrix="dng"``).
    white_signal_dn : numpy.ndarray, shape (3,), or None
        The perfect white's expected signal under the frame's light at its F, per channel, above the black level
        (the sidecar's ``white_signal_e`` × ``dn_per_electron``): what ``gain="white"`` maps to 1. None where
        unknown. Unit: DN.
    """

    cfa_pattern: str | None
    black_dn: np.ndarray
    white_dn: float
    as_shot_neutral: np.ndarray
    intensity_factor: float | None = None
    illuminant: str | None = None
    wavelengths_nm: np.ndarray | None = None
    qe: np.ndarray | None = None
    color_matrix1: np.ndarray | None = field(default=None)
    white_signal_dn: np.ndarray | None = None

    def __post_init__(self):
        if self.cfa_pattern is not None and self.cfa_pattern not in CFA_PATTERNS:
            raise CamsimError(f"unknown CFA pattern {self.cfa_pattern!r}; patterns: {', '.join(CFA_PATTERNS)}")
        black = np.asarray(self.black_dn, dtype=np.float64).reshape(-1)
        if black.size == 1:
            black = np.repeat(black, 3)
        neutral = np.asarray(self.as_shot_neutral, dtype=np.float64).reshape(-1)
        if black.shape != (3,) or not np.all(np.isfinite(black)):
            raise CamsimError(f"black level must be 3 finite numbers (R, G, B), got {shown(black)}")
        try:
            white = np.asarray(self.white_dn, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            white = None
        if white is None or not (white.size == 1 and np.isfinite(white[0]) and white[0] > np.max(black)):
            raise CamsimError(f"white level {shown(self.white_dn if white is None else white)} must be one finite "
                              "number above the black level "
                              f"{black.tolist()}")
        if neutral.shape != (3,) or not (np.all(np.isfinite(neutral)) and np.all(neutral > 0)):
            raise CamsimError(f"as-shot neutral must be 3 positive numbers, got {shown(neutral)}")
        if self.intensity_factor is not None and not (np.isfinite(self.intensity_factor)
                                                      and self.intensity_factor > 0):
            raise CamsimError(f"intensity factor must be positive, got {shown(self.intensity_factor)}")
        object.__setattr__(self, "black_dn", black)
        object.__setattr__(self, "white_dn", float(white[0]))
        object.__setattr__(self, "as_shot_neutral", neutral)
        if self.qe is not None:
            qe = np.asarray(self.qe, dtype=np.float64)
            wl = np.asarray(self.wavelengths_nm, dtype=np.float64)
            if wl.ndim != 1 or qe.shape != (3, wl.size) or wl.size < 3:
                raise CamsimError(f"qe must have shape (3, N) on N ≥ 3 wavelengths, got {qe.shape}, {wl.shape}")
            object.__setattr__(self, "qe", qe)
            object.__setattr__(self, "wavelengths_nm", wl)
        if self.color_matrix1 is not None:
            cm = np.asarray(self.color_matrix1, dtype=np.float64)
            if cm.size != 9 or not np.all(np.isfinite(cm)):
                raise CamsimError(f"ColorMatrix1 must be 9 finite numbers, got {shown(cm)}")
            cm = cm.reshape(3, 3)
            object.__setattr__(self, "color_matrix1", cm)
        if self.white_signal_dn is not None:
            signal = np.asarray(self.white_signal_dn, dtype=np.float64).reshape(-1)
            if signal.shape != (3,) or not (np.all(np.isfinite(signal)) and np.all(signal > 0)):
                raise CamsimError(f"the perfect white's signal must be 3 positive numbers, got {shown(signal)}")
            object.__setattr__(self, "white_signal_dn", signal)
        if self.qe is None and self.color_matrix1 is None:
            raise CamsimError("the ISP needs the camera's spectral sensitivities (a sidecar's qe) or a "
                              "ColorMatrix1 for its colour matrix")

    def record(self) -> dict:
        """The facts as JSON-ready values (for the developed image's record)."""
        return {"cfa_pattern": self.cfa_pattern, "black_dn": self.black_dn.tolist(), "white_dn": self.white_dn,
                "as_shot_neutral": self.as_shot_neutral.tolist(), "intensity_factor": self.intensity_factor,
                "illuminant": self.illuminant,
                "white_signal_dn": None if self.white_signal_dn is None else self.white_signal_dn.tolist(),
                "colour_source": "qe" if self.qe is not None else "color_matrix1"}


def float_white_dn(white_level_dn: float, black_level_dn, dark_level_dn) -> float:
    """The white level in the units of the float values before the ADC: ``white_level_dn`` less the mean offset
    between the quantised numbers' black level and the float values' (``black_level_dn − dark_level_dn``: the
    pedestal, or −½ from the ADC's floor without one). Unit: DN."""
    offset = np.mean(np.asarray(black_level_dn, dtype=np.float64) - np.asarray(dark_level_dn, dtype=np.float64))
    return float(white_level_dn) - float(offset)


def facts_from_meta(meta: dict, quantised: bool) -> IspFacts:
    """The facts of a frame from its sidecar (a dict as :func:`camsim.render.frame_files.read_frame_meta` gives).

    ``quantised``: the numbers to develop are the DNG's quantised digital numbers (black = ``black_level_dn``),
    else the float values before the ADC (an EXR's or ``noisy_dn``: black = ``dark_level_dn``), as
    :meth:`camsim.render.frame_files.LoadedFrame.expected_black_dn` says.
    """
    from camsim.render.frame_files import LoadedFrame

    try:
        black = LoadedFrame(Path(""), "dng" if quantised else "exr", None, meta).expected_black_dn()
        quantised_black = LoadedFrame(Path(""), "dng", None, meta).expected_black_dn()
        white = float(meta["white_level_dn"])
        return IspFacts(
            cfa_pattern=meta.get("cfa_pattern") or None,
            black_dn=black,
            white_dn=white if quantised else float_white_dn(white, quantised_black, black),
            as_shot_neutral=np.asarray(meta["as_shot_neutral"], dtype=np.float64),
            intensity_factor=float(meta["intensity_factor"]),
            illuminant=meta.get("illuminant"),
            # a raw scene's frame has no curves: its colour is its ColorMatrix1
            wavelengths_nm=(np.asarray(meta["wavelengths_nm"], dtype=np.float64)
                            if meta.get("wavelengths_nm") is not None else None),
            qe=(np.asarray(meta["qe_e_m2_sr_per_photon"], dtype=np.float64)
                if meta.get("qe_e_m2_sr_per_photon") is not None else None),
            color_matrix1=(np.asarray(meta["color_matrix1_xyz_to_camera"], dtype=np.float64)
                           if meta.get("color_matrix1_xyz_to_camera") is not None else None),
            white_signal_dn=(np.asarray(meta["white_signal_e"], dtype=np.float64) * float(meta["dn_per_electron"])
                             if meta.get("white_signal_e") is not None and min(meta["white_signal_e"]) > 0
                             else None),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise CamsimError(f"the frame's metadata lacks what the ISP needs ({type(exc).__name__}: {exc})") from None


def facts_of(loaded) -> IspFacts:
    """The facts of a :class:`camsim.render.frame_files.LoadedFrame` (its numbers: quantised for a DNG, float for
    an EXR)."""
    return facts_from_meta(loaded.meta, quantised=loaded.quantised)


def facts_from_info(frame, info, quantised: bool | None = None) -> IspFacts:
    """The facts of an in-memory frame: a :class:`camsim.render.frame.Frame` and its
    :class:`camsim.render.frame_files.FrameInfo`.

    ``quantised``: the numbers to develop are ``frame.digital_dn`` (True) or ``frame.noisy_dn`` /
    ``frame.clean_dn()`` (False); by default True when the frame is quantised (``digital_dn`` not None).
    """
    sensor = frame.sensor
    if quantised is None:
        quantised = frame.digital_dn is not None
    black = sensor.black_level_dn if quantised else sensor.dark_level_dn
    white = float(sensor.max_dn)
    return IspFacts(
        cfa_pattern=sensor.cfa,
        black_dn=np.asarray(black, dtype=np.float64),
        white_dn=white if quantised else float_white_dn(white, sensor.black_level_dn, sensor.dark_level_dn),
        as_shot_neutral=np.asarray(info.as_shot_neutral, dtype=np.float64),
        intensity_factor=float(info.intensity_factor),
        illuminant=info.illuminant,
        wavelengths_nm=np.asarray(info.wavelengths_nm, dtype=np.float64),
        qe=np.asarray(frame.expected.qe, dtype=np.float64),
        color_matrix1=np.asarray(info.color_matrix1, dtype=np.float64),
        white_signal_dn=(None if info.white_signal_e_per_s is None or np.min(info.white_signal_e_per_s) <= 0 else
                         np.asarray(info.white_signal_e_per_s, dtype=np.float64) * info.intensity_factor
                         * sensor.exposure_s * sensor.dn_per_electron),
    )


def facts_from_dng_tags(tags: dict) -> IspFacts:
    """The facts of a DNG from its own tags (the ``info`` :func:`camsim.io.dng.read_dng` returns): BlackLevel,
    WhiteLevel, CFAPattern, AsShotNeutral and ColorMatrix1. Without a sidecar the intensity factor and the
    illuminant's name are unknown (no ``gain="auto"``), and the colour matrix comes from ColorMatrix1."""
    missing = [k for k in ("as_shot_neutral", "color_matrix1", "white_level") if tags.get(k) is None]
    if missing:
        raise CamsimError(f"the DNG lacks the tags the ISP needs without a sidecar: {', '.join(missing)}")
    black = tags.get("black_level_exact") or tags.get("black_level") or [0.0, 0.0, 0.0]
    return IspFacts(cfa_pattern=tags.get("cfa_pattern"), black_dn=np.asarray(black, dtype=np.float64),
                    white_dn=tags["white_level"], as_shot_neutral=np.asarray(tags["as_shot_neutral"]),
                    color_matrix1=np.asarray(tags["color_matrix1"], dtype=np.float64))

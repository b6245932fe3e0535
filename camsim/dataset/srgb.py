"""A dataset's sRGB outputs (``srgb = "png"`` or ``"png16"`` in a spec, ``camsim dataset --srgb``): each frame's
noisy layer and its clean layer developed through one camera ISP (:func:`camsim.isp.develop_pair`: the same white
balance, the same camera → sRGB matrix, the same gain and tone curve for both), as 8- or 16-bit sRGB.

The file layout writes ``OUT/frames/ID_srgb_noisy.png`` and ``ID_srgb_clean.png`` (atomically, the ISP's record in
each PNG's text chunk); a Zarr store holds the same numbers as the arrays ``srgb_noisy`` and ``srgb_clean``
((frame, 3, y, x), uint8 or uint16). The frame's record (its ``.done`` file and manifest line) says what was
written under ``srgb``: the output, the bits and the ISP's record (every stage's name and parameters, the white
balance gains and the matrix).

The developed frame is the one in the EXR: ``noisy`` is the signal before quantisation (``Frame.noisy_dn``, the
EXR's noisy layer; for a Bayer sensor the mosaic, demosaiced by the ISP), ``clean`` its expectation per pixel (the
EXR's clean layer; for a Bayer sensor taken at the mosaic's sites, so that the target goes through the same
demosaicing as the input), both with the black level before the ADC (:func:`camsim.isp.facts_from_info` with
``quantised=False``). :func:`dataset_isp` gives the ISP's settings: the ISP's defaults (as-shot white balance, Malvar
2004, the camera's matrix, the sRGB curve) but for ``gain = "auto"`` (1 / F, the exposure ratio of SID and ELD), so
that a frame at F = 10⁻³ is as bright developed as one at F = 1 (a gain of 1 for a scene with ``exposure = "auto"``,
whose exposure times already make up for F).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError

__all__ = ["SRGB_LAYERS", "dataset_isp", "srgb_bits", "srgb_dtype", "develop_frame", "develop_raw_frame", "quantise",
           "mosaic_clean", "BurstDevelopment", "burst_development", "develop_burst_reference",
           "burst_srgb_record"]

#: The developed layers, as the file layout names its PNGs (``ID_<layer>.png``) and a Zarr store its arrays.
SRGB_LAYERS = ("srgb_noisy", "srgb_clean")
_BITS = {"png": 8, "png16": 16}


def dataset_isp(exposure: str = "fixed"):
    """The ISP settings of a dataset's sRGB outputs: :class:`camsim.isp.IspSettings` with ``gain="auto"`` (1 / F);
    a gain of 1 for frames whose ``exposure`` is ``auto`` (the exposure time already brings the white to the
    scene's target whatever F)."""
    from camsim.isp import IspSettings

    return IspSettings(gain="auto" if exposure == "fixed" else 1.0)


def srgb_bits(output: str) -> int | None:
    """Bits per value of an sRGB output (:data:`camsim.dataset.spec.SRGB_OUTPUTS`): 8, 16, or None for ``none``."""
    if output == "none":
        return None
    if output not in _BITS:
        raise CamsimError(f"unknown sRGB output {output!r}; outputs: none, {', '.join(_BITS)}")
    return _BITS[output]


def srgb_dtype(output: str) -> str | None:
    """NumPy dtype name of an sRGB output's values (``uint8``, ``uint16``), None for ``none``."""
    bits = srgb_bits(output)
    return None if bits is None else ("uint8" if bits == 8 else "uint16")


def quantise(image: np.ndarray, bits: int) -> np.ndarray:
    """A developed (3, H, W) image in [0, 1] as the integers a ``bits``-bit PNG of :func:`camsim.isp.write_png`
    holds (:func:`camsim.isp.writers.encode_image`: round half up of clip(x, 0, 1) · (2^bits − 1)), planes first:
    (3, H, W) uint8 or uint16."""
    from camsim.isp.writers import encode_image

    return np.ascontiguousarray(encode_image(image, bits).transpose(2, 0, 1))


def mosaic_clean(clean: np.ndarray, cfa_pattern: str) -> np.ndarray:
    """The clean layer (3, H, W) of a Bayer frame at its mosaic's sites: (H, W), each pixel its own channel's value
    (what the sensor's noisy mosaic is the noisy realisation of)."""
    from camsim.sensor.cfa import mosaic_of

    return mosaic_of(clean, cfa_pattern)


def develop_frame(rendered, info, output: str, settings=None, facts=None) -> tuple[dict, dict]:
    """Develop a rendered frame (:class:`camsim.render.frame.Frame` and its ``FrameInfo``) for the sRGB output
    ``output`` (``png`` or ``png16``): its noisy and clean layers through one ISP (``settings``, default
    :func:`dataset_isp`) with ``facts`` (:class:`camsim.isp.IspFacts`; default the frame's own: a burst frame takes
    its reference's, :func:`burst_development`).

    Returns
    -------
    images : dict
        ``srgb_noisy``, ``srgb_clean``: (3, H, W) float32 in [0, 1], the developed images before quantisation.
    record : dict
        ``output``, ``bits`` and ``isp``: the ISP's record of the noisy frame's development (the clean one's is the
        same: one set of gains, one matrix).
    """
    from camsim.isp import facts_from_info

    if settings is None:
        settings = dataset_isp((info.exposure or {}).get("exposure", "fixed"))
    if facts is None:
        facts = facts_from_info(rendered, info, quantised=False)  # noisy_dn and clean_dn: the level before the ADC
    noisy = rendered.noisy_dn
    clean = _clean_layer(rendered, facts)
    if facts.cfa_pattern is not None:
        noisy = noisy[0]
    return _develop(noisy, clean, facts, output, settings)


def _clean_layer(rendered, facts) -> np.ndarray:
    """A rendered frame's clean layer as it is developed: (3, H, W), or a Bayer frame's at its mosaic's sites."""
    clean = rendered.clean_dn()
    return clean if facts.cfa_pattern is None else mosaic_clean(clean, facts.cfa_pattern)


@dataclass(frozen=True, eq=False)
class BurstDevelopment:
    """The one development of a burst's sRGB outputs: the ISP's facts and settings of its reference frame,
    applied to every frame.

    Attributes
    ----------
    facts : camsim.isp.IspFacts
        The reference's facts (:func:`camsim.isp.facts_from_info`, the levels before the ADC): its white balance
        (as-shot neutral), colour matrix (the camera's curves), intensity factor F and white level.
    settings : camsim.isp.IspSettings
        :func:`dataset_isp` of the burst's exposure mode: the gain 1 / F (or 1), the tone curve and demosaicing.
    """

    facts: object
    settings: object


def burst_development(reference, info) -> BurstDevelopment:
    """The development of a burst (:class:`BurstDevelopment`) from its reference frame (``reference``: the
    :class:`camsim.render.raw_frame.ExpectationFrame` of ``ref``, and its ``FrameInfo``). Every decision of the ISP
    (the white-balance gains, the matrix, the gain) comes from these facts and settings, none from a frame's numbers:
    developing each frame with them develops the burst consistently, whatever its frames' noise, motion or flicker."""
    from camsim.isp import facts_from_info

    return BurstDevelopment(facts_from_info(reference, info, quantised=False),
                            dataset_isp((info.exposure or {}).get("exposure", "fixed")))


def develop_burst_reference(reference, output: str, development: BurstDevelopment) -> tuple[dict, dict]:
    """Develop a burst's reference (its clean layer, as :func:`develop_frame` develops a clean layer) with the
    burst's ``development``. Returns ``{"srgb_clean": (3, H, W) float32 in [0, 1]}`` and the output's record (as
    :func:`develop_frame`'s: the same ISP record as every frame of the burst)."""
    from camsim.isp import develop

    bits = srgb_bits(output)
    if bits is None:
        raise CamsimError("no sRGB output asked for (srgb = none)")
    developed = develop(_clean_layer(reference, development.facts), development.facts, development.settings)
    return {"srgb_clean": developed.image}, {"output": output, "bits": bits, "isp": developed.record}


def develop_raw_frame(draw, meta: dict, output: str) -> tuple[dict, dict]:
    """Develop a frame of a raw source (:class:`camsim.render.raw_frame.RawDraw` and its sidecar ``meta``, a
    ``[raws]`` dataset's) as :func:`develop_frame` does: the noisy mosaic and the clean one (each site's expectation)
    before the ADC, through one ISP whose colour is the source's (its ColorMatrix1 and as-shot neutral) and whose
    gain is 1 / (F · T / T_source), the exposure ratio, so that a frame is as bright developed as its source.
    Returns what :func:`develop_frame` returns."""
    from camsim.isp import IspSettings, facts_from_meta

    facts = facts_from_meta(meta, quantised=False)
    settings = IspSettings(gain=1.0 / float(meta["raw_source"]["fraction"]))
    return _develop(draw.noisy_dn[0], draw.clean_dn, facts, output, settings)


def _develop(noisy: np.ndarray, clean: np.ndarray, facts, output: str, settings) -> tuple[dict, dict]:
    """The noisy and clean images (a mosaic, or (3, H, W)) developed through one ISP, and the output's record."""
    from camsim.isp import develop_pair

    bits = srgb_bits(output)
    if bits is None:
        raise CamsimError("no sRGB output asked for (srgb = none)")
    developed_noisy, developed_clean = develop_pair(noisy, clean, facts, settings)
    images = {"srgb_noisy": developed_noisy.image, "srgb_clean": developed_clean.image}
    return images, {"output": output, "bits": bits, "isp": developed_noisy.record}


def burst_srgb_record(record: dict) -> dict:
    """A burst's ``srgb`` record: the output's (``output``, ``bits``, ``isp``: the one development's record, its
    reference's and every frame's), what the files or arrays hold (``layers``) and how the burst was developed
    (``development``)."""
    return {**record, "development": "one per burst, from its reference's ISP facts and settings (white balance, "
                                     "colour matrix, gain, tone curve), applied to every frame",
            "layers": {"frames": ["srgb_noisy", "srgb_clean"], "reference": ["srgb_clean"]}}

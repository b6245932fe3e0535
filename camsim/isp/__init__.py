"""The camera ISP: a camsim frame's numbers developed into an sRGB picture (``camsim develop``, ``camsim.isp``).

An application (layer 10). Stages, each a pure array function (:mod:`camsim.isp.stages`): black level and white
level (:func:`normalise`), white balance (:func:`white_balance_gains`, :func:`apply_white_balance`), demosaicing
(:func:`demosaic`, :data:`DEMOSAIC_METHODS`: bilinear in camsim's own float32 code, equal to colour-demosaicing's
within float32 rounding; Malvar 2004 and Menon 2007 colour-demosaicing's), camera → linear sRGB (:func:`srgb_matrix`,
:func:`apply_matrix`), a digital gain (:func:`apply_gain`) and a tone curve (:func:`tone_curve`,
:data:`TONE_CURVES`). :func:`develop` runs them with :class:`IspSettings` on the numbers of a frame described by
:class:`IspFacts` (:func:`facts_of`, :func:`facts_from_meta`, :func:`facts_from_info`);
:func:`develop_stages` keeps each stage's image; :func:`develop_pair` develops a noisy frame and its clean target
with the same gains and matrix. :func:`pack_rggb` / :func:`unpack_rggb` pack a mosaic for raw denoisers (SID/ELD).
:func:`write_png` and :func:`write_jpeg` write the result with its record.
"""

from camsim.isp.develop import GAIN_MODES, STAGE_NAMES, Developed, IspSettings, develop, develop_pair, develop_stages
from camsim.isp.facts import IspFacts, facts_from_dng_tags, facts_from_info, facts_from_meta, facts_of, float_white_dn
from camsim.isp.pack import PACKED_PLANES, pack_rggb, unpack_rggb
from camsim.isp.stages import (
    DEMOSAIC_METHODS,
    MATRICES,
    TONE_CURVES,
    WHITE_BALANCE_MODES,
    apply_gain,
    apply_matrix,
    apply_white_balance,
    camera_to_xyz,
    demosaic,
    normalise,
    srgb_matrix,
    tone_curve,
    white_balance_gains,
)
from camsim.isp.writers import read_png_record, write_jpeg, write_png

__all__ = [
    "IspSettings", "IspFacts", "Developed", "STAGE_NAMES", "GAIN_MODES", "DEMOSAIC_METHODS", "TONE_CURVES", "MATRICES",
    "WHITE_BALANCE_MODES", "PACKED_PLANES",
    "facts_from_meta", "facts_of", "facts_from_info", "facts_from_dng_tags", "float_white_dn",
    "normalise", "white_balance_gains", "apply_white_balance", "demosaic", "srgb_matrix", "camera_to_xyz",
    "apply_matrix",
    "apply_gain", "tone_curve", "develop", "develop_stages", "develop_pair",
    "pack_rggb", "unpack_rggb", "write_png", "write_jpeg", "read_png_record",
]

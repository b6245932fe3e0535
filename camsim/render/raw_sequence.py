"""A raw scene in motion: a real camera's raw file as a ``[sequence]`` of frames with camera motion (issue 29, point 1
for ``[raw]`` scenes).

::

    source electrons s (H, W) ──(law's count c(s), × f)──▶ mosaic f·c(s)                      (source_mosaic_e)
    f·c(s) ──(each site its own colour, the other two bilinear: clean_planes)──▶ planes (3, H, W) (source_planes_e)
    planes ──(average_warp along the camera's path: moving_expectation)──▶ moved planes s̃
    s̃ ──(the file's CFA: mosaic_of)──▶ (1, H, W) ──(photon law add, the sensor's stages)──▶ frame

The source's electrons per site s = (DN − black) / K_source (:func:`camsim.render.raw_render.source_electrons`) are
what a raw scene's frames draw from. In a sequence they are made into per-pixel planes, as every other scene's
expectation is (:func:`camsim.render.raw_render.clean_planes`: each site's own colour exact, the other two colours
the bilinear interpolation of their neighbours), moved along the camera's path exactly as any scene
(:func:`camsim.render.sequence.moving_expectation`, :func:`camsim.render.warp.average_warp`: bilinear, clamped at
the edges, averaged over the exposure's sub-samples), put back on the file's CFA (:func:`camsim.sensor.cfa.mosaic_of`)
and drawn by the photon law.

The photon laws (:mod:`camsim.sensor.raw_laws`) in a sequence:

``add``
    Poisson(s̃ · g + D̄ · d) at each site, s̃ the moved expectation of f · max(s, 0)
    (:func:`camsim.render.raw_frame.render_expectation_frame`: one implementation with the spectral sequences). A
    moving frame's EXR clean layer is its own expectation, every channel at every pixel
    (:func:`camsim.render.raw_frame.expectation_clean_dn`).
``thin``
    Binomial(round(max(s, 0)), f · g) needs an integer count of the source's own electrons at the site; a moved site
    has a bilinear mix of several sites' values, no count, so ``thin`` with motion is refused. A static sequence
    under ``thin`` draws each frame as a raw scene's frame is drawn (:func:`camsim.render.raw_frame.render_raw_frame`),
    each from its own seed.

Across the frames. Given the source, the frames are independent: each draws its own noise about the same clean layer
(the source's value, scaled and moved). The source's own noise (its photon and read noise, in s) is *common* to every
frame: about a scene's true expectation, a static site's frames covary by f² · g² · Var(s) (``add``; ``thin``: p² ·
Var(n)), a share f² Var(s) / (f E s + f² Var s) ≈ f / (1 + f) of a frame's shot-noise variance for a source limited
by its photon noise (``thin``: ≈ p). So the frames' temporal independence holds for the noise the frames add, not for
the source's: averaging N frames converges to the clean layer (the source made dark, its noise in), never to the
scene. :func:`raw_sequence_warnings` says so where that share is above :data:`COMMON_SHARE_WARNING`
(``tests/render/test_raw_sequence.py`` measures it).

Saturated (masked) source sites move with the scene: the mask's indicator goes down the same path as the electrons
(:func:`mask_planes`: clean_planes of the 0/1 mosaic, warped with the electrons; :func:`mask_share`: its sites' own
colour), giving each frame site the share of its interpolation weight that came from masked sites: 1 where it is
all masked, 0 where no masked site touched it, in between on a moving mask's border (and at a border site whose
other colours are interpolated from across it). ``STEM_mask.png`` writes round(255 · share): 255 masked, 0 clean,
any other value partly masked; the sidecar's ``raw_source.masked_px`` counts the sites with a share above 0 and
``masked_partial_px`` those between 0 and 1.

Files, per F with stem STEM (``SCENE_as-shot_F<F>``): ``STEM_fNNN.dng/.exr/.json`` (and ``_mask.png`` where a site
is masked), each sidecar a raw scene's (:func:`camsim.render.raw_render.raw_sidecar`) with the sequence's keys
(``frame_index``, ``time_s``, ``homography`` — in the mosaic's own pixels, the crop's, before the file's
Orientation —, ``homography_time``, ``blur_subsamples_used``, ``sequence``); and
``STEM_ref.exr/.json``: the reference frame, the source's expectation (no motion, no noise; the static planes'
:func:`camsim.render.raw_frame.expectation_clean_dn`, the fixed pattern in), its noisy layer the clean one's sites,
no DNG (under ``thin`` the planes are f · round(max(s, 0)): the law's mean, exact away from the full well, where
a ``thin`` frame's own clean layer is :func:`camsim.render.raw_frame.render_raw_frame`'s approximation). Frame i
draws from ``frame_seed_sequence(seed, "as-shot/f<i>", F)``. Each frame is written by
:func:`write_raw_sequence_frame`, which a dataset's bursts of ``[raws]`` crops share
(:func:`camsim.dataset.raws.render_raw_burst_files`: the stem the item's id, the seed the item's, the source the crop
after its flips).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.seeding import frame_seed_sequence
from camsim.render.raw_frame import RawDraw, expectation_clean_dn, render_expectation_frame, render_raw_frame
from camsim.render.raw_render import (
    RAW_ILLUMINANT,
    LoadedRaw,
    check_raw_scene,
    clean_planes,
    frame_fraction,
    raw_sidecar,
    read_source,
)
from camsim.scene.sequence import Motion, check_timing
from camsim.sensor.cfa import mosaic_of
from camsim.sensor.raw_laws import source_count_e

#: A raw sequence warns where the source's own noise, common to every frame, is more than this share of a frame's
#: shot-noise variance (f / (1 + f) for ``add``, p for ``thin``, f the largest fraction): 1 %.
COMMON_SHARE_WARNING = 0.01


#: The sidecar's ``units.raw_source``, added for a sequence's frame: what its mask counts are.
MASK_UNITS = ("; in a sequence, masked_px counts the frame's sites that took any share of their value from masked "
              "source sites (the mask moved with the scene) and masked_partial_px those that took part of it "
              "(1 to 254 in the mask file, 255 all)")


def check_raw_sequence(scene) -> None:
    """Refuse, before any work, a raw scene's ``[sequence]`` that cannot be drawn (one line): the raw scene's own
    checks, the timing, and ``thin`` with motion."""
    check_raw_scene(scene)
    seq = scene.sequence
    check_timing(seq, scene.sensor.exposure_s, scene.source.own_size()[1])
    if seq.moves and scene.source.photon_law == "thin":
        raise CamsimError("[raw] photon_law = 'thin' cannot move: thinning keeps each of a site's own source "
                          "electrons, and a moved site mixes several sites' values (no count to thin); use "
                          "photon_law = 'add', or a static [sequence]")
    if seq.flickers and scene.source.photon_law == "thin":
        raise CamsimError("[raw] photon_law = 'thin' cannot follow a flickering light (its fraction is one per "
                          "frame); use photon_law = 'add', or flicker_depth = 0")


def common_share(fraction: float, law: str) -> float:
    """The share of a frame's shot-noise variance that the source's own photon noise makes, common to every frame
    of a sequence (a source limited by its photon noise, Var s ≈ E s): f / (1 + f) for ``add``, p = f for
    ``thin``."""
    return fraction / (1 + fraction) if law == "add" else fraction


def raw_sequence_warnings(scene) -> list[str]:
    """A raw sequence's warning (one line, or none): the source's noise is common to every frame where its share
    (:func:`common_share`) at the largest fraction exceeds :data:`COMMON_SHARE_WARNING`."""
    src = scene.source
    f = max(scene.intensity_factors) * float(scene.sensor.exposure_s) / src.source_exposure_s
    return common_noise_warnings(f, src.photon_law, "[sequence] of a raw scene")


def common_noise_warnings(fraction: float, law: str, what: str) -> list[str]:
    """The warning (one line, or none) that ``what``'s frames (a raw sequence's, a dataset's bursts of raw crops)
    share the source's own noise: where its share (:func:`common_share`) at the largest ``fraction`` f under
    ``law`` exceeds :data:`COMMON_SHARE_WARNING`."""
    share = common_share(fraction, law)
    if share <= COMMON_SHARE_WARNING:
        return []
    return [f"{what}: the source's own noise is common to every frame (at f = {fraction:g}, about "
            f"{100 * share:.3g} % of a frame's shot-noise variance): its frames are independent about their clean "
            "layer, which carries it, not about the scene (darken more, or see the real-raws guide, 'In motion')"]


def source_mosaic_e(source: LoadedRaw, law: str, fraction: float) -> np.ndarray:
    """f · c(s) (H, W) float32: the source's expected signal electrons at the fraction f, c(s) = max(s, 0) for
    ``add``, round(max(s, 0)) (the count ``thin`` thins) for ``thin``. Unit: e⁻."""
    count = np.maximum(source.electrons_e, 0.0) if law == "add" else source_count_e(source.electrons_e)
    return (count * fraction).astype(np.float32)


def source_planes_e(mosaic_e: np.ndarray, pattern: str) -> np.ndarray:
    """The per-pixel planes (3, H, W) float32 of a site mosaic (H, W): each site's own colour exact, the other two
    bilinear (:func:`camsim.render.raw_render.clean_planes`). Unit: as the mosaic's."""
    return clean_planes(mosaic_e, pattern)


def mask_planes(masked: np.ndarray, pattern: str) -> np.ndarray:
    """The mask's planes (3, H, W) float32: the 0/1 mask of saturated source sites made into planes as the
    electrons are (:func:`source_planes_e`), to go down the same path."""
    return source_planes_e(masked.astype(np.float32), pattern)


def mask_share(planes: np.ndarray, pattern: str) -> np.ndarray:
    """Each site's share (H, W) float32 in [0, 1] of its (moved) value's interpolation weight that came from masked
    source sites: its own colour's plane of the (moved) :func:`mask_planes`."""
    return np.clip(mosaic_of(planes, pattern), 0.0, 1.0)


def mask_png(share: np.ndarray) -> np.ndarray:
    """The mask file's values (H, W) uint8: round(255 · share), with a share strictly between 0 and 1 kept off 0 and
    255 (1 … 254: partly masked)."""
    value = np.rint(share * 255.0)
    partial = (share > 0) & (share < 1)
    value[partial] = np.clip(value[partial], 1, 254)
    return value.astype(np.uint8)


def mask_record(share: np.ndarray) -> dict:
    """The sidecar's ``raw_source`` mask counts of a frame: ``masked_px`` (share > 0), ``masked_fraction``,
    ``masked_partial_px`` (0 < share < 1)."""
    masked = int(np.count_nonzero(share > 0))
    return {"masked_px": masked, "masked_fraction": masked / share.size,
            "masked_partial_px": int(np.count_nonzero((share > 0) & (share < 1)))}


def render_raw_sequence_frames(scene, source: LoadedRaw, intensity_factor: float, *, workers=None):
    """Yield ``("ref", draw, clean, share, extra)`` and then ``(i, draw, clean, share, extra)`` for every frame of the
    raw scene's ``[sequence]`` at F: the frame (:class:`camsim.render.raw_frame.RawDraw`), its EXR clean layer (3,
    H, W) DN, its mask share (H, W) and its sidecar's sequence keys (module docstring)."""
    from camsim.render.sequence import moving_expectation, sequence_frame_record

    seq = scene.sequence
    sensor = scene.sensor
    law = scene.source.photon_law
    pattern = sensor.cfa
    fraction = frame_fraction(sensor, source, intensity_factor)
    height, width = source.electrons_e.shape
    motion = Motion.of(seq, width, height, scene.seed)
    record = seq.record()
    mosaic = source_mosaic_e(source, law, fraction)
    static = source_planes_e(mosaic, pattern)
    from camsim.sensor.fixed_pattern import fixed_pattern

    maps = fixed_pattern(sensor, (height, width))
    ref_clean = expectation_clean_dn(static, sensor, maps, workers)
    ref = RawDraw(np.ascontiguousarray(mosaic_of(ref_clean, pattern)[None]), None, mosaic_of(ref_clean, pattern),
                  maps, None)
    masks = mask_planes(source.masked, pattern) if source.masked.any() else None
    static_share = np.zeros((height, width), np.float32) if masks is None else mask_share(masks, pattern)
    # a moving frame warps the electrons and the mask together (one warp, six channels: one set of coordinates)
    moved_planes = static if masks is None else np.concatenate([static, masks])
    yield "ref", ref, ref_clean, static_share, {"sequence_reference": True, "homography": np.eye(3).tolist(),
                                                "sequence": record}
    for i in range(seq.frames):
        rng = frame_seed_sequence(scene.seed, f"{RAW_ILLUMINANT}/f{i}", intensity_factor)
        if law == "thin":  # static (check_raw_sequence): a raw scene's frame, its own seed
            draw = render_raw_frame(source.electrons_e, sensor, fraction, law="thin", rng=rng, workers=workers)
            clean, share = clean_planes(draw.clean_dn, pattern), static_share
        else:
            if seq.moves:  # the electrons and the mask along the path (a rolling shutter's rows, the light's flicker)
                moved = moving_expectation(moved_planes, motion, i, sensor.exposure_s, workers)
                moving = moved[:3]
                share = static_share if masks is None else mask_share(moved[3:], pattern)
            else:  # S̄ itself, or times each row's share of a flickering light
                moving, share = moving_expectation(static, motion, i, sensor.exposure_s, workers), static_share
            draw = render_expectation_frame(mosaic_of(moving, pattern)[None], sensor, rng=rng, workers=workers)
            clean = expectation_clean_dn(moving, sensor, draw.maps, workers)
        extra = {**sequence_frame_record(motion, i, sensor.exposure_s), "sequence": record}
        yield i, draw, clean, share, extra


def render_raw_sequence(scene, out_dir, *, workers=None, progress=True, exr_compression=None) -> dict:
    """Render every F of a raw scene with a ``[sequence]``: its reference and frames (module docstring), each
    committed by its sidecar, the manifest listing them. :func:`camsim.render.run.render_scene`'s contract."""
    from tqdm import tqdm

    from camsim.io.exr import DEFAULT_EXR_COMPRESSION, check_exr_compression
    from camsim.io.output_folder import output_folder
    from camsim.render.frame_files import frame_stem
    from camsim.render.frame_manifest import MANIFEST_NAME, FrameManifest, manifest_entry
    from camsim.render.sequence import frame_digits

    exr_compression = exr_compression or DEFAULT_EXR_COMPRESSION
    check_raw_sequence(scene)
    check_exr_compression(exr_compression)
    seq = scene.sequence
    digits = frame_digits(seq.frames)
    with output_folder(out_dir) as out_dir:
        out_dir = Path(out_dir)
        manifest = FrameManifest(out_dir, scene.name)
        if manifest.frames or (out_dir / MANIFEST_NAME).exists():
            manifest.write()
        source = read_source(scene)
        bar = tqdm(total=len(scene.intensity_factors) * (seq.frames + 1), desc=f"rendering {scene.name}",
                   unit="frame", disable=not progress)
        with bar, manifest.kept_on_failure():
            for factor in scene.intensity_factors:
                stem = frame_stem(scene.name, RAW_ILLUMINANT, factor)
                fraction = frame_fraction(scene.sensor, source, factor)
                record = source.record(scene.source.photon_law, fraction)
                for index, *frame in render_raw_sequence_frames(scene, source, factor, workers=workers):
                    name = f"{stem}_ref" if index == "ref" else f"{stem}_f{index:0{digits}d}"
                    manifest.withdraw(name)
                    files, meta = write_raw_sequence_frame(out_dir, name, stem, scene, source, factor, *frame,
                                                           record, exr_compression)
                    manifest.commit_entry(manifest_entry({**meta, "files": files}))
                    bar.update()
    return manifest.as_dict()


def write_raw_sequence_frame(out_dir: Path, name: str, stem: str, scene, source: LoadedRaw, intensity_factor: float,
                             draw: RawDraw, clean: np.ndarray, share: np.ndarray, extra: dict, record: dict,
                             exr_compression: str) -> tuple[dict, dict]:
    """Write one frame of :func:`render_raw_sequence_frames` (``draw``, ``clean``, ``share``, ``extra``) as
    ``out_dir/name.dng/.exr/.json`` (and ``name_mask.png`` where a site is masked:
    :func:`camsim.render.raw_render.write_raw_frame`), its sidecar a raw scene's (``record``: its ``raw_source``
    without the mask counts, which the frame's ``share`` sets) with the sequence's keys, whose ``sequence`` gains
    ``stem`` and ``reference`` (``stem_ref.exr``). Returns the files by kind and the sidecar (without ``files``)."""
    from camsim.render.raw_render import write_raw_frame

    meta = raw_sidecar(scene, draw, {**record, **mask_record(share)}, source, intensity_factor, scene.seed, None)
    meta = {**meta, **extra, "sequence": {**extra["sequence"], "stem": stem, "reference": f"{stem}_ref.exr"},
            "units": {**meta["units"], "raw_source": meta["units"]["raw_source"] + MASK_UNITS}}
    files = write_raw_frame(Path(out_dir), name, draw, meta, source, scene.sensor, exr_compression, clean=clean,
                            mask=mask_png(share))
    return files, meta


__all__ = ["COMMON_SHARE_WARNING", "MASK_UNITS", "check_raw_sequence", "common_noise_warnings", "common_share",
           "mask_png", "mask_planes", "mask_record", "mask_share", "raw_sequence_warnings", "render_raw_sequence",
           "render_raw_sequence_frames", "source_mosaic_e", "source_planes_e", "write_raw_sequence_frame"]

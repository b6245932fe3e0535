"""``poisson``, ``gaussian`` and ``auto``: every stage in one pass per channel, straight to digital numbers.

A :class:`~camsim.methods.plan.DrawPlan` says how each spectrum and channel is drawn; :func:`fill_channel` then
walks a block's rectangles of equal label (or, for a cube, its pixels grouped by kind) and writes DN before
quantisation. The exact path composes the stage functions of :mod:`camsim.sensor.stages` (charge, DSNU offset, full
well, read noise, gain; where the full well can act, the charge's Poisson means are capped far above it,
:func:`camsim.sensor.stages.cap_mean_e`); the Gaussian paths replace charge and read noise by one moment-matched normal.
``auto``'s Eq. 4 path (:data:`~camsim.methods.plan.BINS`, ``paper`` statistics at low F) takes the signal of
``spectral``'s per-bin draws (:func:`camsim.methods.spectral.draw_bins`, shared by the three channels of a pixel,
drawn once per block) and goes on as the exact path.
"""

from __future__ import annotations

import numpy as np

from camsim.methods.plan import BINS, EXACT, GAUSSIAN, GAUSSIAN_CLIPPED, SATURATED, TABLE, DrawPlan
from camsim.methods.spectral import draw_bins
from camsim.methods.table import charge_table
from camsim.sensor.cfa import cfa_sites
from camsim.sensor.expected import ExpectedSignal
from camsim.sensor.kernels import alias_draw_words, alias_words, label_runs, standard_normal_f32
from camsim.sensor.params import SensorParams
from camsim.sensor.stages import (
    add_black_level_error_dn,
    add_offset_e,
    add_read_noise_e,
    add_row_noise,
    collect_charge_e,
    draw_read_noise_e,
    electrons_to_dn,
    quantise_dn,
    saturate_e,
    saturation_level_e,
)


def fill_channel(out_c, labels, plan: DrawPlan, expected: ExpectedSignal, sensor: SensorParams,
                 statistics: str, c: int, rng, z, work, offset=None, gain=None, dark_gain=None, bins=None,
                 runs=...):
    """One channel of a block, in DN before quantisation, by the plan: ``out_c`` (h, w) float32 is written in place.

    ``z`` (h, w) float32 and ``work`` are scratch. Each pixel uses one draw from ``z``: its read noise on the exact
    path, or (rescaled) its whole Gaussian value; the clipped Gaussian, and the Gaussian under non-Gaussian read
    noise, draw their own normals. ``offset`` (offset DSNU, e⁻), ``gain`` (PRNU) and ``dark_gain`` (dark-current
    DSNU) are this block's fixed-pattern maps, (h, w), or None. ``bins`` (h, w): this channel's per-bin signal
    (:func:`bins_signal`, e⁻) where the plan has :data:`~camsim.methods.plan.BINS`, else None. ``runs``:
    :func:`camsim.sensor.kernels.label_runs` of ``labels``, when the caller has it (the three channels of a block share
    it).
    """
    k = sensor.dn_per_electron
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    z_scale = read if read > 0 else 1.0
    gaussian_z = sensor.gaussian_read_noise or read == 0
    kinds = plan.kinds_by_channel[c]  # per frame, not per block: K may be one spectrum per pixel
    if read > 0:
        draw_read_noise_e(rng, z, read, sensor.read_noise_model, sensor.tukey_lambda, work)
    elif np.any((kinds != EXACT) & (kinds != TABLE)):  # the Gaussian paths' normals
        standard_normal_f32(rng, z, work, z_scale)
    if runs is ...:
        runs = label_runs(labels)
    # the table kind's rectangles draw their charges from one buffer of raw words and one of charges (a block's)
    words = alias_words(rng, labels.size) if runs is not None and np.any(kinds == TABLE) else None
    charges, used = (np.empty(labels.size, dtype=np.float32), 0) if words is not None else (None, 0)
    # a piece is (where, label): a rectangle of one label, the whole block (every spectrum of the channel drawn the
    # same way: an image's or a cube's pixels, one mean each) or the pixels of one drawing kind (a boolean mask)
    whole = runs is None and kinds.size == 1
    if runs is not None:
        pieces = [((slice(r0, r1), slice(c0, c1)), label) for r0, r1, c0, c1, label in runs]
    elif whole:
        pieces = [((slice(None), slice(None)), None)]
    else:
        pieces = [(labels_of, None) for labels_of in _masks_by_kind(labels, plan.kind[:, c])]
    dark = expected.dark_e[c]
    if not dark > 0:
        dark_gain = None  # no dark current in this channel: nothing for the map to scale
    simple = offset is None and gain is None and dark_gain is None
    for where, label in pieces:
        index = label if label is not None else labels[where]
        kind = plan.kind[label, c] if label is not None else kinds[0] if whole else plan.kind[index[0], c]
        in_place = label is not None or whole  # out_c[where] is a view: write straight into it
        zz = z[where]
        g = None if gain is None else gain[where]
        d = None if dark_gain is None else dark_gain[where]
        if kind == SATURATED:  # far above the full well: the full well plus read noise, exactly
            value = add_read_noise_e(sensor.full_well_e, zz) if read > 0 else np.full(zz.shape, sensor.full_well_e)
        elif kind in (GAUSSIAN, GAUSSIAN_CLIPPED):
            signal = expected.signal_e[index, c]
            mean = signal + dark if g is None else signal + dark + (g - 1) * signal
            mean = mean if offset is None else mean + offset[where]
            signal_var = expected.signal_var_e2[index, c]
            var = signal_var + dark if g is None else signal_var + dark + (g - 1) * signal_var
            if d is not None:  # Poisson(D̄ d): mean and variance both move by (d − 1) D̄
                mean, var = mean + (d - 1) * dark, var + (d - 1) * dark
            if kind == GAUSSIAN and gaussian_z and simple and label is not None:
                view = out_c[where]  # a rectangle: two in-place passes, straight into the output
                np.multiply(zz, np.float32(k * np.sqrt(var + read**2) / z_scale), out=view)
                view += np.float32(k * mean)
                continue
            normal = zz / z_scale if gaussian_z else rng.standard_normal(zz.shape, dtype=np.float32)
            if kind == GAUSSIAN and gaussian_z:
                value = mean + np.sqrt(var + read**2) * normal
            else:  # charge as a normal, clipped, then the read noise from z
                value = mean + np.sqrt(var) * normal
                if kind == GAUSSIAN_CLIPPED:
                    value = saturate_e(value, sensor.full_well_e)
                if read > 0:
                    value = add_read_noise_e(value, zz if not gaussian_z
                                             else read * rng.standard_normal(zz.shape, np.float32))
        else:
            size = out_c[where].shape if label is not None else None
            table = _charge_table(expected, sensor, label, c) if kind == TABLE and words is not None else None
            # the whole block (an image's pixels): clip wherever any spectrum of the channel may reach the full well
            # (a clip that cannot act changes nothing) rather than gather the per-spectrum flags of every pixel
            clip = table is None and bool(plan.clip_by_channel[c]) and (
                whole or bool(np.any(plan.needs_clip[index, c])))
            level = None if not clip else saturation_level_e(sensor.full_well_e,
                                                             None if offset is None else offset[where])
            if table is not None:  # min(N, c) from its alias table: one 64-bit word a pixel
                n = size[0] * size[1]
                charge = alias_draw_words(table, words[used : used + n], charges[used : used + n]).reshape(size)
                used += n
            elif kind == BINS:  # Eq. 4's drawn signal, as a known S̄ per pixel: the stage adds Poisson(D̄) to it
                charge = collect_charge_e(rng, bins[where], expected.dark_e[c], statistics=statistics,
                                          photon_noise=False, gain=g, dark_gain=d, saturation_e=level)
            elif statistics == "pixel" and sensor.photon_noise and label is None and g is None and d is None:
                # S + D ~ Poisson(S̄ + D̄), one draw per pixel: gather the sums from the channel's contiguous row
                # (computed once per frame) instead of S̄ and Var S by a 2-D gather each, then adding D̄
                charge = collect_charge_e(rng, np.take(expected.charge_mean_e[c], index), 0.0,
                                          statistics=statistics, saturation_e=level)
            else:
                charge = collect_charge_e(rng, expected.signal_e[index, c], expected.dark_e[c],
                                          expected.signal_var_e2[index, c], statistics=statistics,
                                          photon_noise=sensor.photon_noise, size=size, gain=g, dark_gain=d,
                                          saturation_e=level)
            charge = add_offset_e(charge, None if offset is None else offset[where])
            if clip:
                charge = saturate_e(charge, sensor.full_well_e)
            if simple and in_place:
                view = out_c[where]  # a rectangle or the block: cast, add the read noise and scale in two passes
                if read > 0:
                    add_read_noise_e(charge, zz, out=view)
                else:
                    view[...] = charge
                electrons_to_dn(view, k, out=view)
                continue
            value = add_read_noise_e(charge, zz) if read > 0 else charge
        out_c[where] = electrons_to_dn(value, k)


def _charge_table(expected: ExpectedSignal, sensor: SensorParams, label: int, c: int):
    """The alias table of spectrum ``label``'s charge in channel ``c`` (:func:`camsim.methods.table.charge_table`),
    or None where its law does not fit one (then drawn as ``poisson`` draws it)."""
    return charge_table(float(expected.signal_e[label, c] + expected.dark_e[c]),
                        float(sensor.full_well_e) if sensor.saturation else None)


def _masks_by_kind(labels, kinds_of_spectra):
    """Boolean masks of the pixels of each drawing kind (for label maps without long runs, e.g. cubes)."""
    per_pixel = kinds_of_spectra[labels]
    return [per_pixel == kind for kind in np.unique(per_pixel)]


def bins_signal(labels, plan: DrawPlan, expected: ExpectedSignal, sensor: SensorParams, rng, offset=None):
    """Eq. 4's signal S (3, h, w) float32 of the block's pixels whose spectrum the plan draws by bins in some
    channel (0 elsewhere), by ``spectral``'s per-bin draws, shared by the channels; None where it has none.
    Unit: e⁻."""
    spectra = plan.bins_spectra
    if spectra is None:
        return None
    mask = spectra[labels]
    if not mask.any():
        return None
    out = np.zeros((3,) + labels.shape, dtype=np.float32)
    signal = np.empty((3, int(np.count_nonzero(mask))), dtype=np.float32)
    level = saturation_level_e(sensor.full_well_e, offset) if sensor.saturation else None
    draw_bins(labels[mask], expected, sensor, "paper", rng, signal, level, dark=False)
    out[:, mask] = signal
    return out


def draw_block(job, r0: int, r1: int, rng: np.random.Generator, scratch) -> None:
    """Rows ``r0:r1`` of a frame by its plan: every channel (or CFA site) in one pass, then row noise and the ADC.

    ``job`` is the frame's :class:`camsim.render.frame.FrameJob`; ``scratch`` the thread's buffers.
    """
    sensor, plan, expected = job.sensor, job.plan, job.expected
    block = job.noisy[:, r0:r1]  # work in place in the output
    labels = job.labels[r0:r1]
    offset, gain, dark_gain = job.maps_rows(r0, r1)
    row_noise_dn = sensor.row_noise_e * sensor.dn_per_electron
    bins = bins_signal(labels, plan, expected, sensor, rng, offset)
    if sensor.cfa is not None:  # each site of the 2 × 2 cell: its channel only
        for dy, dx, c in cfa_sites(sensor.cfa):
            site = (slice(dy, None, 2), slice(dx, None, 2))
            sub_labels = np.ascontiguousarray(labels[site])
            value = np.empty(sub_labels.shape, dtype=np.float32)
            fill_channel(value, sub_labels, plan, expected, sensor, job.statistics, c, rng, np.empty_like(value),
                         scratch.work, None if offset is None else offset[c][site],
                         None if gain is None else gain[c][site], None if dark_gain is None else dark_gain[c][site],
                         None if bins is None else bins[c][site])
            block[0][site] = value
        planes = [0]
    else:
        planes = range(3)
        runs = label_runs(labels)  # once for the three channels
    for p in planes:
        if sensor.cfa is None:
            fill_channel(block[p], labels, plan, expected, sensor, job.statistics, p, rng,
                         scratch.plane[: r1 - r0], scratch.work, None if offset is None else offset[p],
                         None if gain is None else gain[p], None if dark_gain is None else dark_gain[p],
                         None if bins is None else bins[p], runs)
        if sensor.row_noise_e > 0:  # a physical row shares its offset, whatever the colour of its pixels
            add_row_noise(block[p], row_noise_dn, rng)
        if job.black_level_error_dn is not None:
            add_black_level_error_dn(block[p], job.black_level_error_dn, sensor.cfa, p)
        if job.digital is not None:
            quantise_dn(block[p], sensor.bits, out=job.digital[p, r0:r1], pedestal_dn=sensor.pedestal_dn)

"""The colour-edge error of camsim's optics, measured: per-spectrum OTFs and one PSF per channel against a
per-wavelength reference.

camsim blurs each channel's expected electrons with its mean OTF, OTF_c = Σ_λ w_c(λ) OTF(λ), the weights w_c(λ) those
of the light channel c receives averaged over the frame, plus each spectrum's deviation from it in a few components
(:mod:`camsim.render.optics`, :mod:`camsim.optics.spectral`). Where the spectrum changes within the PSF's reach — an
edge between a red and a blue patch — the exact image is the per-wavelength sum

    ref_c = Σ_λ PSF_λ ∗ e_c(λ),        e_c(λ) = Qe_c(λ) g(λ, x) per pixel,

while the mean OTF alone (one PSF per channel) computes PSF_c ∗ Σ_λ e_c(λ). This tool builds a vertical edge between
two ColorChecker patches (N Ohta, under D65, seen by the scene's camera), computes camsim's result
(:func:`camsim.render.optics.apply_optics` with :func:`camsim.render.optics.spectral_otf`), the mean OTF's alone, and
the reference with the same stage functions (:mod:`camsim.optics.stages`: the monochromatic OTFs on the same padded
grid), and prints, per f-number and channel, the largest difference relative to the reference at that pixel and
relative to the channel's brightest value, with the decomposition's ranks and OTF error bounds. A grey edge (one
spectral shape on both sides) has no such error: its row is the check that the computations agree (float32
rounding). Usage::

    python tools/optics_colour_edge.py [--f-number 4 8 16] [--pitch 4] [--left red] [--right blue] [--olpf]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def edge_spectra(left: str, right: str):
    """(wavelengths_nm (N,), photon rates of the two patches (2, N), Qe (3, N)) under D65 by the built-in
    macbeth_26 scene's camera (any unit: the comparison is relative)."""
    from camsim.render.pipeline import light_scene
    from camsim.scene.scene_file import load_scene

    scene = load_scene("macbeth_26").replace(width=120, height=80, illuminants=("D65",))
    lit = light_scene(scene, "D65")
    names = [n.lower() for n in lit.radiance.patch_names]
    rates = np.asarray(lit.photon_rate)
    pick = []
    for name in (left, right):
        if name.startswith("grey"):  # "grey0.2": a flat reflectance, the perfect white's rate scaled
            pick.append(float(name[4:]) * np.asarray(lit.white_photon_rate))
        else:
            pick.append(rates[names.index(name.lower())])
    return lit.grid.wavelengths_nm, np.array(pick), np.asarray(lit.qe)


def colour_edge_difference(f_number: float, pitch_um: float = 4.0, left: str = "red", right: str = "blue",
                           olpf: bool = False, size: tuple[int, int] = (48, 96)) -> dict:
    """The per-channel PSF against the per-wavelength reference at a vertical edge in a (height, width) frame.

    Returns
    -------
    dict
        ``max_rel_pixel`` (3,): max |camsim − ref| / ref over the frame; ``max_rel_peak`` (3,): max |camsim − ref|
        / max(ref); ``where_px`` (3,): the column of the largest relative difference.
    """
    from camsim.optics.params import OpticsParams
    from camsim.optics.stages import (
        RADIAL_SAMPLES_PER_CY,
        channel_otf,
        channel_wavelength_weights,
        convolve_plane,
        lens_otf_radial,
        margin_px,
        padded_shape,
    )
    from camsim.render.optics import apply_optics, spectral_otf

    wavelengths, rates, qe = edge_spectra(left, right)
    height, width = size
    labels = np.zeros(size, dtype=np.intp)
    labels[:, width // 2:] = 1
    optics = OpticsParams(f_number=f_number, pixel_pitch_um=pitch_um, olpf=olpf)
    # camsim: one OTF per channel, from the frame's mean light
    mean_rate = rates[labels.ravel()].mean(axis=0)
    weights = channel_wavelength_weights(mean_rate, qe)
    electrons = np.einsum("cn,kn->kc", qe, rates)  # (2, 3): each side's electrons per channel (Σ over λ)
    planes = np.stack([electrons[labels, c] for c in range(3)]).astype(np.float32)
    spectral = spectral_otf(labels, rates, qe, electrons, weights, wavelengths, optics)
    ours = apply_optics(planes, optics, wavelengths, weights, spectral=spectral, workers=1).astype(np.float64)
    mean = apply_optics(planes, optics, wavelengths, weights, workers=1).astype(np.float64)
    # the reference: every wavelength's own PSF on its own electrons, summed (same grid, margin and reflection)
    margin = margin_px(f_number, pitch_um, 0.0, optics.olpf_shift_px if olpf else 0.0)
    shape = padded_shape(height, width, margin)
    from scipy import fft

    fy, fx = fft.fftfreq(shape[0]), fft.rfftfreq(shape[1])
    step = 1.0 / RADIAL_SAMPLES_PER_CY
    rho = np.arange(int(np.ceil(np.sqrt(0.5) / step)) + 2) * step
    masks = [(labels == k).astype(np.float32) for k in (0, 1)]
    ref = np.zeros((3,) + size)
    for i in range(wavelengths.size):
        mono = np.zeros((3, wavelengths.size))
        mono[:, i] = 1
        radial = lens_otf_radial(rho, wavelengths, mono, f_number=f_number, pixel_pitch_um=pitch_um,
                                 diffraction=True, w020_waves_550=0.0)[0]
        otf = channel_otf(radial, step, fy, fx, olpf_shift_px=optics.olpf_shift_px if olpf else None,
                          fill_factor=optics.fill_factor)
        blurred = [convolve_plane(m, otf, margin, shape, workers=1).astype(np.float64) for m in masks]
        for c in range(3):
            ref[c] += qe[c, i] * (rates[0, i] * blurred[0] + rates[1, i] * blurred[1])
    out = {"ranks": spectral.ranks, "bounds": spectral.bounds}
    for key, image in (("", ours), ("mean_", mean)):
        diff = np.abs(image - ref)
        rel = diff / np.maximum(ref, 1e-300)
        out |= {f"{key}max_rel_pixel": rel.reshape(3, -1).max(axis=1),
                f"{key}max_rel_peak": diff.reshape(3, -1).max(axis=1) / ref.reshape(3, -1).max(axis=1),
                f"{key}where_px": [int(np.unravel_index(np.argmax(rel[c]), size)[1]) for c in range(3)]}
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--f-number", type=float, nargs="+", default=[4.0, 8.0, 16.0])
    parser.add_argument("--pitch", type=float, default=4.0, help="pixel pitch, µm")
    parser.add_argument("--left", default="red", help="a ColorChecker patch name, or greyR (e.g. grey0.2)")
    parser.add_argument("--right", default="blue")
    parser.add_argument("--olpf", action="store_true")
    args = parser.parse_args(argv)
    print(f"edge {args.left} | {args.right}, pitch {args.pitch} µm, diffraction{' + OLPF' if args.olpf else ''}, "
          "D65, Nikon 5100 (NPL) Qe; max |camsim − per-wavelength reference| per channel R, G, B")
    for n in args.f_number:
        out = colour_edge_difference(n, args.pitch, args.left, args.right, args.olpf)
        for key, what in (("mean_", "one PSF per channel (the frame's mean light)"),
                          ("", f"per spectrum, r = {out['ranks']}, OTF bounds "
                               f"({', '.join(f'{b:.1e}' for b in out['bounds'])})")):
            cells = ", ".join(f"{'RGB'[c]} {100 * out[key + 'max_rel_pixel'][c]:.4f} % of the pixel's value "
                              f"({100 * out[key + 'max_rel_peak'][c]:.4f} % of the channel's peak)"
                              for c in range(3))
            print(f"f/{n:g}, {what}: {cells}")


if __name__ == "__main__":
    main()

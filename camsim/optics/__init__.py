"""Optics in front of the sensor (issue 30): a lens's blur, its fall-off and its lateral colour, applied to a frame's
expected electrons before the noise is drawn.

- :mod:`camsim.optics.params`: :class:`~camsim.optics.params.OpticsParams`, a scene file's ``[optics]`` table (one
  schema: the scene reader, ``camsim render --optics NAME=VALUE`` and the sidecar's ``optics`` record);
- :mod:`camsim.optics.stages`: one pure function per stage (the diffraction OTF of a circular pupil per wavelength,
  the defocused OTF (Hopkins), the birefringent 4-spot low-pass filter, the pixel aperture, cos⁴ or tabulated
  vignetting, lateral chromatic aberration's inverse magnification), the per-channel OTF Σ_λ w_c(λ) OTF(λ) and the
  FFT convolution of a frame's planes with it.

The layer sits between the sensor and the file formats: it imports only :mod:`camsim.core`. Where a frame is made
(:mod:`camsim.render.optics`), the stages are applied in order to the per-pixel expectation (3, H, W).
"""

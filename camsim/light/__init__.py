"""Layer 2, the physics of light: spectra and photon rates; imports only :mod:`camsim.core`.

The wavelength grid and the named spectra camsim ships through colour-science (:mod:`camsim.light.spectra`),
spectral radiance to mean photon rates, the paper's Eqs. 1–5 (:mod:`camsim.light.photons`), and spectra given as
linear combinations of a few basis spectra (:mod:`camsim.light.rates`). ``tests/test_layers.py`` checks the layers.
"""

"""Layer 3, colour: camera RGB to CIE XYZ and chromaticity, reflectance recovery from RGB, colour-science's names
and the raw file's colour tags; imports only :mod:`camsim.core` and :mod:`camsim.light`.

:mod:`camsim.colour.colorimetry` (the paper's Eqs. 15–16), :mod:`camsim.colour.recovery` (RGB → reflectance, for
image scenes), :mod:`camsim.colour.colour_names` (the names ``camsim list`` prints, without importing
colour-science) and :mod:`camsim.colour.rawcolour` (ColorMatrix1 and AsShotNeutral). Inside this package an
absolute ``import colour`` is still colour-science (Python 3 imports are absolute). ``tests/test_layers.py`` checks
the layers.
"""

"""Frame and metadata writers and readers (DNG, EXR, JSON), all written atomically.

Layer 5, file formats: the codecs, the atomic writes (:mod:`camsim.io.atomic`), the output folder, the reflectance
cube files and the PNG figures (:mod:`camsim.io.figures`, matplotlib without pyplot); imports only the layers
below (:mod:`camsim.core`, :mod:`camsim.light`, :mod:`camsim.colour`, :mod:`camsim.sensor`).
``tests/test_layers.py`` checks the layers.
"""

"""Layer 1, the foundation: modules every other layer may import; they import no camsim module outside this layer.

Errors (:mod:`camsim.core.errors`), the rule for names that become file and folder names
(:mod:`camsim.core.names`), the one parameter schema (:mod:`camsim.core.schema`), the pixel-count limit
(:mod:`camsim.core.pixel_limit`), optional numbers (:mod:`camsim.core.optional_numbers`), seeds and random
streams (:mod:`camsim.core.seeding`), the array namespace of a device (numpy or CuPy, :mod:`camsim.core.xp`) and
signal handling (:mod:`camsim.core.signals`). ``tests/test_layers.py`` checks the layers.
"""

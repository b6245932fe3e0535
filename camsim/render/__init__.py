"""Layer 8, rendering and frame files: a scene's frames made and written, and read back; imports only the layers
below (:mod:`camsim.core` to :mod:`camsim.scene`).

:mod:`camsim.render.pipeline` (the one place a frame is made), :mod:`camsim.render.frame` (the block scheduler:
per-pixel noise in row blocks, :class:`~camsim.render.frame.Frame`), :mod:`camsim.render.backends` (the CPU's
block renderer or the array path on a device), :mod:`camsim.render.run` (every frame of a scene into a folder),
:mod:`camsim.render.frame_files` (the frame files, both ways), :mod:`camsim.render.frame_manifest` (a render
folder's ``manifest.json``), :mod:`camsim.render.sidecar_schema` (the sidecar read as input, checked) and
:mod:`camsim.render.preview` (an sRGB preview). ``tests/test_layers.py`` checks the layers.
"""

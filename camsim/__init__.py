"""camsim: a physically grounded camera simulator.

Spectral scenes (a label map plus K spectra for charts, or a hyperspectral cube) pass through the image-sensor
model of the 2014 low-light colour-measurement paper (photons, dark current, saturation, read noise, gain,
quantisation) into 8-bit raw DNG and float EXR frames. See ``MODEL.md`` in the shared docs for the contract.
"""

__version__ = "0.1.0"

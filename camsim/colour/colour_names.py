"""The names of the spectra colour-science ships, as ``camsim list`` prints them without importing colour-science.

Importing colour-science takes about half a second (it imports scipy, matplotlib and OpenImageIO), which
``camsim list`` does not need: these are the names of colour-science 0.4.7's ``SDS_ILLUMINANTS``,
``MSDS_CAMERA_SENSITIVITIES`` and ``SDS_COLOURCHECKERS``, sorted. ``tests/test_imports.py`` checks them against the
installed colour-science (:func:`camsim.light.spectra.illuminant_names` and its siblings), which stays the authority
when a scene names a spectrum.
"""

__all__ = ["CAMERAS", "ILLUMINANTS", "REFLECTANCE_SETS"]

#: Illuminants (``colour.SDS_ILLUMINANTS``), for ``--illuminant`` and a scene's ``illuminants``.
ILLUMINANTS = (
    "A", "B", "C", "D50", "D55", "D60", "D65", "D75", "E", "FL1", "FL10", "FL11", "FL12", "FL2", "FL3", "FL3.1",
    "FL3.10", "FL3.11", "FL3.12", "FL3.13", "FL3.14", "FL3.15", "FL3.2", "FL3.3", "FL3.4", "FL3.5", "FL3.6", "FL3.7",
    "FL3.8", "FL3.9", "FL4", "FL5", "FL6", "FL7", "FL8", "FL9", "HP1", "HP2", "HP3", "HP4", "HP5", "ID50", "ID65",
    "ISO 7589 Photoflood", "ISO 7589 Photographic Daylight", "ISO 7589 Sensitometric Daylight",
    "ISO 7589 Sensitometric Photoflood", "ISO 7589 Sensitometric Printer", "ISO 7589 Sensitometric Studio Tungsten",
    "ISO 7589 Studio Tungsten", "LED-B1", "LED-B2", "LED-B3", "LED-B4", "LED-B5", "LED-BH1", "LED-RGB1", "LED-V1",
    "LED-V2",
)

#: Camera sensitivity sets (``colour.MSDS_CAMERA_SENSITIVITIES``), for ``--camera``.
CAMERAS = (
    "Nikon 5100 (NPL)", "Sigma SDMerill (NPL)",
)

#: ColorChecker reflectance sets (``colour.SDS_COLOURCHECKERS``), for a chart's ``reflectances``.
REFLECTANCE_SETS = (
    "BabelColor Average", "ColorChecker N Ohta", "ISO 17321-1", "PMC", "babel_average", "cc_ohta",
)

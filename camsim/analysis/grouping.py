"""Which frames are one measurement at several F: the sidecar keys that must agree (:data:`GROUP_KEYS`) and the
key of a frame (:func:`group_key`), for ``camsim analyze``'s ΔE reference, its figures and ``denoise-eval``."""

from __future__ import annotations

import json

from camsim.sensor.params import EXPOSURE_KEYS, SENSOR_PARAMS, SensorParams

#: Sidecar values that must agree for two frames to be the same measurement at different F (ΔE reference): the
#: scene, light, camera and render settings, and every sensor key the schema writes (so a new sensor parameter
#: joins the grouping by itself), also those it writes only when set (absent: the default, read as None).
GROUP_KEYS = ("scene", "illuminant", "photon_statistics", "method", "auto_tolerance_ks", "camera",
              "sensitivity_basis", "reflectances", "luminance_cd_m2", "normalisation", "scale", "width_px",
              "height_px", "wavelengths_nm", "exposure", "exposure_target_e", "exposure_max_s",
              *SensorParams().sidecar_record(), *(p.name for p in SENSOR_PARAMS if p.omit_default))


def group_key(meta: dict) -> str:
    """The grouping key of a frame's sidecar: frames of an auto-exposed series share it whatever their T (each
    frame's exposure time, and the dark levels that follow from it, are not part of the key)."""
    auto = meta.get("exposure") == "auto"
    return json.dumps([None if auto and key in EXPOSURE_KEYS else meta.get(key) for key in GROUP_KEYS],
                      sort_keys=True)

"""Camera preset files (TOML), as ``camsim calibrate`` writes them and ``--preset PATH.toml`` reads them.

::

    [preset]
    name = "my-camera"
    source = "camsim calibrate: 8 dark frames, 6 flat pairs, 2026-11-23"
    bits = 14
    pedestal_dn = 512
    cfa = "RGGB"                      # omitted: a three-chip (or monochrome) sensor
    read_noise_model = "tukey-lambda"
    # optional: title, full_well_e, conversion_gain_v_per_e, dark_current_e_per_s, dual_gain_iso

    [[iso]]                           # one table per calibrated ISO, lowest first
    iso = 3200
    k_dn_per_e = 3.06
    tukey_lambda = -0.035
    tukey_scale_dn = 2.04
    gaussian_sigma_dn = 3.92
    row_sigma_dn = 0.445
    dsnu_dn = 0.0                     # optional
    prnu_percent = 0.0                # optional
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from camsim.sensor.presets.model import CameraPreset, IsoPoint
from camsim.sensor.cfa import CFA_PATTERNS
from camsim.core.errors import CamsimError
from camsim.core.names import safe_component
from camsim.core.schema import read_toml, typed

_PRESET_KEYS = {"name": str, "title": str, "source": str, "bits": int, "pedestal_dn": int, "cfa": str,
                "read_noise_model": str, "full_well_e": float, "conversion_gain_v_per_e": float,
                "dark_current_e_per_s": float, "dual_gain_iso": float}
_REQUIRED = ("name", "source", "bits")
_ISO_KEYS = {f.name: f for f in dataclasses.fields(IsoPoint)}


def read_preset_file(path: str | Path) -> CameraPreset:
    """A camera preset from a TOML file (module docstring).

    Raises
    ------
    CamsimError
        For a missing or malformed file, unknown or missing keys, or values out of range.
    """
    path = Path(path)
    where = f"camera preset {path}"
    doc = read_toml(path, "camera preset file")
    unknown = set(doc) - {"preset", "iso"}
    if unknown:
        raise CamsimError(f"{where}: unknown table(s) {', '.join(sorted(unknown))}; a preset has [preset] and [[iso]]")
    head = doc.get("preset")
    if not isinstance(head, dict):
        raise CamsimError(f"{where}: needs a [preset] table")
    unknown = set(head) - set(_PRESET_KEYS)
    if unknown:
        raise CamsimError(f"{where}: unknown key(s) in [preset]: {', '.join(sorted(unknown))}")
    missing = [k for k in _REQUIRED if k not in head]
    if missing:
        raise CamsimError(f"{where}: [preset] lacks {', '.join(missing)}")
    fields = {k: typed(head, k, kind, None, where) for k, kind in _PRESET_KEYS.items() if k in head}
    safe_component(fields["name"], f"{where}: name")  # the rule of every name (camsim calibrate --name's too)
    if "cfa" in fields and fields["cfa"] not in CFA_PATTERNS:
        raise CamsimError(f"{where}: cfa must be one of {', '.join(CFA_PATTERNS)}, got {fields['cfa']!r}")
    fields.setdefault("cfa", None)
    fields.setdefault("title", fields["name"])
    rows = doc.get("iso")
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        raise CamsimError(f"{where}: needs at least one [[iso]] table")
    points = []
    for i, row in enumerate(rows):
        at = f"{where} [[iso]] #{i + 1}"
        unknown = set(row) - set(_ISO_KEYS)
        if unknown:
            raise CamsimError(f"{at}: unknown key(s): {', '.join(sorted(unknown))}")
        missing = [f.name for f in _ISO_KEYS.values() if f.default is dataclasses.MISSING and f.name not in row]
        if missing:
            raise CamsimError(f"{at}: lacks {', '.join(missing)}")
        try:
            points.append(IsoPoint(**{k: typed(row, k, float, None, at) for k in row}))
        except CamsimError as exc:
            raise CamsimError(f"{at}: {exc}") from None
    points.sort(key=lambda p: p.iso)
    try:
        return CameraPreset(iso_points=tuple(points), **fields)
    except CamsimError as exc:
        raise CamsimError(f"{where}: {exc}") from None

"""A scene's ``[optics]`` table: the lens and the stages in front of the sensor (issue 30).

Each stage is switchable: diffraction (``diffraction = true``: the Airy pattern of a circular pupil, per wavelength),
defocus (``defocus_waves``, W020 in waves at 550 nm, or ``defocus_um``, the image-plane focus shift Δz,
W020 = Δz / (8 N²) µm), the birefringent 4-spot low-pass filter (``olpf``, spots at (±s/2, ±s/2) px), the pixel
aperture (``fill_factor``: a square of side √ff px, relative to the source's full-pixel area sampling), vignetting
(``vignetting = "cos4"`` from ``focal_length_mm`` and ``pixel_pitch_um``, or ``"table"`` of
``relative_illumination``) and lateral chromatic aberration (``lateral_ca``: a magnification per channel about the
frame's centre). The table's keys are declared once here (:func:`camsim.core.schema.param`): the scene reader,
``camsim render --optics NAME=VALUE``, the sidecar's ``optics`` record and the docs' reference derive from them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from camsim.core.errors import CamsimError
from camsim.core.schema import Param, param, params_of, record, validate

VIGNETTING = ("none", "cos4", "table")
#: The wavelength at which ``defocus_waves`` is given. Unit: µm.
DEFOCUS_REFERENCE_UM = 0.55
#: A table's keys besides the schema's parameters (a list of [angle, value] pairs is no schema kind).
TABLE_ONLY_KEYS = ("relative_illumination",)
#: The largest field angle a vignetting table or the frame may reach. Unit: degrees.
MAX_FIELD_ANGLE_DEG = 89.0
#: The largest defocus: |W020| in waves at 550 nm (a geometric blur of radius 4 N |W020| 0.55 / pitch px: 44 px at
#: f/4 and 4 µm pixels; the OTF's quadrature grows with it). Unit: waves.
MAX_DEFOCUS_WAVES = 20.0
#: The largest OLPF spot separation. Unit: px.
MAX_OLPF_SHIFT_PX = 64.0
#: The f-number's range: N = 1 / (2 NA) is at least 0.5 in air; 10⁴ is far slower than any pinhole camera's (f/500)
#: and keeps the diffraction cut-off pitch / (λ N) a normal float64.
F_NUMBER_RANGE = (0.5, 1e4)
#: The longest focal length: 1 km (the largest telescopes' are under 1 km). Unit: mm.
MAX_FOCAL_LENGTH_MM = 1e6
#: The widest pixel pitch: 1 cm. Unit: µm.
MAX_PIXEL_PITCH_UM = 1e4


@dataclass(frozen=True)
class OpticsParams:
    """The optics in front of the sensor (the scene file's ``[optics]`` table).

    Attributes
    ----------
    relative_illumination : tuple of (float, float) pairs or None
        ``vignetting = "table"``: (field angle in degrees, relative illumination), angles increasing from 0; the
        values are taken relative to the one at 0° and interpolated linearly in the angle (beyond the last angle:
        the last value).
    """

    f_number: float = param(4.0, "float", "the lens's f-number N (working, image side): the diffraction cut-off "
                            "is pitch / (λ N) cycles per pixel", low=F_NUMBER_RANGE[0], high=F_NUMBER_RANGE[1])
    focal_length_mm: float = param(50.0, "float", "the lens's focal length: a pixel's field angle is "
                                   "atan(distance from the centre × pitch / focal length) (cos⁴ vignetting)", "mm",
                                   above=0, high=MAX_FOCAL_LENGTH_MM)
    pixel_pitch_um: float = param(4.0, "float", "the sensor's pixel pitch (the frame's pixel grid)", "µm", above=0,
                                  high=MAX_PIXEL_PITCH_UM)
    diffraction: bool = param(True, "bool", "diffraction of a circular pupil (the Airy pattern per wavelength, OTF "
                              "(2/π)(acos ν − ν√(1−ν²)), ν = f / f_c)")
    defocus_waves: float = param(0.0, "float", "defocus: W020, the peak wavefront error at 550 nm (at λ: "
                                 "W020·0.55/λ_µm waves); the OTF is the pupil's autocorrelation with that phase "
                                 "(Hopkins); at most one of defocus_waves and defocus_um non-zero; |W020| ≤ 20",
                                 "waves")
    defocus_um: float = param(0.0, "float", "defocus as the image-plane focus shift Δz: W020 = Δz / (8 N²) µm", "µm")
    olpf: bool = param(False, "bool", "a birefringent optical low-pass filter: 4 equal spots at (±s/2, ±s/2) px, "
                       "OTF cos(π fx s) cos(π fy s)")
    olpf_shift_px: float = param(1.0, "float", "the OLPF's spot separation s", "px", above=0)
    fill_factor: float = param(1.0, "float", "the pixel aperture: a square of side √ff px; the frame's total "
                               "pixel factor is sinc(√ff fx) sinc(√ff fy). A scene's pixels are already full-pixel "
                               "area samples (sinc(f) per axis), so the stage applies sinc(√ff f) / sinc(f) per "
                               "axis: none at ff = 1, a gain up to π/2 at Nyquist as ff → 0 (the expectation "
                               "clipped at 0 where a sharp edge then rings below it)", above=0)
    vignetting: str = param("none", "str", "'none'; 'cos4': cos⁴ of the field angle, relative to the centre; "
                            "'table': relative_illumination, [[angle_deg, value], …]", choices=VIGNETTING)
    lateral_ca: tuple = param((1.0, 1.0, 1.0), "rgb", "lateral chromatic aberration: the magnification of each "
                              "channel's image about the frame's centre (bilinear; 1 = none)", above=0)
    relative_illumination: tuple | None = None

    def __post_init__(self):
        validate(self, "[optics]")
        ca = self.lateral_ca
        object.__setattr__(self, "lateral_ca", tuple(float(v) for v in (ca if isinstance(ca, (list, tuple))
                                                                         else (ca, ca, ca))))
        if self.fill_factor > 1:
            raise CamsimError(f"[optics]: fill_factor must be in (0, 1], got {self.fill_factor!r}")
        if self.defocus_waves and self.defocus_um:
            raise CamsimError("[optics]: set at most one of defocus_waves and defocus_um")
        if abs(self.w020_waves_550) > MAX_DEFOCUS_WAVES:
            raise CamsimError(f"[optics]: the defocus's W020 = {self.w020_waves_550:.4g} waves at 550 nm is beyond "
                              f"±{MAX_DEFOCUS_WAVES:g} waves")
        if self.olpf_shift_px > MAX_OLPF_SHIFT_PX:
            raise CamsimError(f"[optics]: olpf_shift_px must be at most {MAX_OLPF_SHIFT_PX:g} px, got "
                              f"{self.olpf_shift_px!r}")
        if (self.defocus_waves or self.defocus_um) and not self.diffraction:
            raise CamsimError("[optics]: defocus is the pupil's diffraction with the W020 phase (Hopkins): it needs "
                              "diffraction = true")
        if not all(0.5 <= m <= 2 for m in self.lateral_ca):
            raise CamsimError(f"[optics]: lateral_ca magnifications must be within [0.5, 2], got "
                              f"{list(self.lateral_ca)}")
        table = self.relative_illumination
        if self.vignetting == "table":
            if table is None:
                raise CamsimError("[optics]: vignetting = 'table' needs relative_illumination = [[angle_deg, "
                                  "value], …]")
            object.__setattr__(self, "relative_illumination", parse_relative_illumination(table))
        elif table is not None:
            raise CamsimError("[optics]: relative_illumination applies with vignetting = 'table'")

    @property
    def w020_waves_550(self) -> float:
        """W020, the defocus's peak wavefront error in waves at 550 nm (from ``defocus_um`` where that is set)."""
        if self.defocus_um:
            return self.defocus_um / (8 * self.f_number**2) / DEFOCUS_REFERENCE_UM
        return self.defocus_waves

    def record(self) -> dict:
        """The sidecar's ``optics`` parameters (every key, the table's too)."""
        out = record(self)
        out["relative_illumination"] = (None if self.relative_illumination is None
                                        else [list(pair) for pair in self.relative_illumination])
        return out


#: The schema's parameters of ``[optics]`` (``--optics NAME=VALUE`` takes these and ``relative_illumination``).
OPTICS_PARAMS: tuple[Param, ...] = params_of(OpticsParams)
OPTICS_KEYS = frozenset(p.name for p in OPTICS_PARAMS) | set(TABLE_ONLY_KEYS)


def parse_relative_illumination(value) -> tuple:
    """``[[angle_deg, value], …]`` checked: at least two pairs of finite numbers, angles strictly increasing from 0
    up to :data:`MAX_FIELD_ANGLE_DEG`, values > 0."""
    where = "[optics]: relative_illumination"
    if not isinstance(value, (list, tuple)) or len(value) < 2:
        raise CamsimError(f"{where} must be a list of at least two [angle_deg, value] pairs, got {value!r}")
    pairs = []
    for pair in value:
        if (not isinstance(pair, (list, tuple)) or len(pair) != 2
                or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in pair)):
            raise CamsimError(f"{where}: each entry must be [angle_deg, value] (two finite numbers), got {pair!r}")
        pairs.append((float(pair[0]), float(pair[1])))
    angles = [a for a, _ in pairs]
    if angles[0] != 0 or any(b <= a for a, b in zip(angles, angles[1:])) or angles[-1] > MAX_FIELD_ANGLE_DEG:
        raise CamsimError(f"{where}: the angles must increase strictly from 0 up to {MAX_FIELD_ANGLE_DEG:g}°, "
                          f"got {angles}")
    if any(not v > 0 for _, v in pairs):
        raise CamsimError(f"{where}: the values must be positive, got {[v for _, v in pairs]}")
    return tuple(pairs)


def parse_optics(table) -> OpticsParams:
    """An :class:`OpticsParams` from a scene file's ``[optics]`` table (or the command line's settings).

    Raises
    ------
    CamsimError
        Unknown keys, values of the wrong type or range (one line).
    """
    if not isinstance(table, dict):
        raise CamsimError("[optics] must be a table")
    unknown = set(table) - OPTICS_KEYS
    if unknown:
        raise CamsimError(f"[optics]: unknown key(s): {', '.join(sorted(unknown))}")
    params = {p.name: p for p in OPTICS_PARAMS}
    values = {k: params[k].coerce(v, "[optics]") if k in params else v for k, v in table.items()}
    return OpticsParams(**values)


def optics_setting(text: str) -> tuple:
    """``NAME=VALUE`` of ``--optics``: a key of ``[optics]`` and its value as in a scene file (a TOML literal or a
    bare name), typed by the schema.

    Raises
    ------
    CamsimError
        An unknown name or a bad value (one line).
    """
    import tomllib

    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep or name not in OPTICS_KEYS:
        raise CamsimError(f"--optics: expected NAME=VALUE with NAME one of {', '.join(sorted(OPTICS_KEYS))}, got "
                          f"{text!r}")
    params = {p.name: p for p in OPTICS_PARAMS}
    if name in params:
        return name, params[name].parse_text(value.strip(), "--optics")
    try:
        parsed = tomllib.loads(f"v = {value.strip()}")["v"]
    except (ValueError, RecursionError):
        raise CamsimError(f"--optics: {name} must be a TOML list of [angle_deg, value] pairs, got {value!r}") from None
    return name, parse_relative_illumination(parsed)

"""A real camera's raw file as the scene: per pixel and CFA site, the electron rate it recorded.

A ``[raw]`` table names any file LibRaw reads (DNG, ARW, NEF, CR2, …) and, optionally, a crop. Its light is its
own: no illuminant, camera curves or chart. What the file gives is, at each site, the source's electrons
(DN − black) / K_source, K_source the source camera's gain at the file's ISO (a built-in camera preset found from
the file's Make and Model, the ``[raw]`` table's ``preset``, or the scene's camera preset), and so its electron rate
(DN − black) / K_source / T_source. A frame at intensity factor F and exposure T expects F · rate · T electrons at
each site; every later stage is the scene's sensor's (the docs' guide *Real raws in*). The frames are drawn by
:mod:`camsim.render.raw_render`, not from spectra.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.scene.sources.base import SceneSource, typed


@dataclass(frozen=True)
class RawSource(SceneSource):
    """A raw file scene (scene-file table ``[raw]``).

    Attributes
    ----------
    path : pathlib.Path
        The raw file (anything LibRaw reads with a 2 × 2 RGB Bayer mosaic).
    crop : tuple of int or None
        (x, y, width, height) of the visible image to keep, in pixels; width and height even (None: all of it).
    photon_law : {'add', 'thin'}
        How a frame's electrons are drawn from the source's (:mod:`camsim.sensor.raw_laws`): ``add``, Poisson of
        the expectation, the source taken as noise-free; ``thin``, binomial thinning of the source's electron count.
    preset : str or None
        The source camera's preset (a camera preset name or a ``camsim calibrate`` preset file, relative to the scene
        file): its gain K at the file's ISO turns DN into electrons. None: the built-in preset of the file's Make
        and Model (:func:`camsim.sensor.presets.preset_for_camera`), else the scene's ``[sensor] preset``.
    iso : float or None
        The source's ISO where the file records none (or records it wrongly). Unit: ISO.
    exposure_s : float or None
        The source's exposure time where the file records none. Unit: s.
    base_dir : pathlib.Path or None
        Where a preset file is looked for (the scene file's folder).
    """

    table = "raw"
    keys = frozenset({"path", "crop", "photon_law", "preset", "iso", "exposure_s"})
    has_own_size = True

    path: Path
    crop: tuple | None = None
    photon_law: str = "add"
    preset: str | None = None
    iso: float | None = None
    exposure_s: float | None = None
    base_dir: Path | None = None

    def __post_init__(self):
        from camsim.sensor.raw_laws import PHOTON_LAWS  # (not at import: the command line's start-up)

        if self.photon_law not in PHOTON_LAWS:
            raise CamsimError(f"[raw] photon_law must be one of {', '.join(PHOTON_LAWS)}, got {self.photon_law!r}")
        if self.crop is not None:
            crop = tuple(self.crop)
            if (len(crop) != 4 or any(isinstance(v, bool) or not isinstance(v, int) for v in crop)
                    or crop[0] < 0 or crop[1] < 0 or crop[2] <= 0 or crop[3] <= 0 or crop[2] % 2 or crop[3] % 2):
                raise CamsimError(f"[raw] crop must be [x, y, width, height]: integers, x, y ≥ 0, width and height "
                                  f"even and positive (whole 2 × 2 cells), got {list(self.crop)}")
            object.__setattr__(self, "crop", crop)
        for name in ("iso", "exposure_s"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and not isinstance(value, bool)
                                          and 0 < value < float("inf")):
                raise CamsimError(f"[raw] {name} must be a positive number, got {value!r}")

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> RawSource:
        if "path" not in table:
            raise CamsimError(f"{where}: [raw] needs a path to a raw file (DNG, ARW, NEF, CR2, … : what LibRaw reads)")
        crop = typed(table, "crop", list, None, where)
        try:
            return cls(path=Path(base_dir) / typed(table, "path", str, "", where),
                       crop=None if crop is None else tuple(crop),
                       photon_law=typed(table, "photon_law", str, "add", where),
                       preset=typed(table, "preset", str, None, where),
                       iso=typed(table, "iso", float, None, where),
                       exposure_s=typed(table, "exposure_s", float, None, where),
                       base_dir=Path(base_dir))
        except CamsimError as exc:
            raise CamsimError(f"{where}: {exc}") from None

    @cached_property
    def header(self):
        """The file's :class:`camsim.io.raw_capture.RawHeader` (size, pattern, ISO, exposure, camera), read once."""
        from camsim.io.raw_capture import raw_header

        return raw_header(self.path)

    def own_size(self) -> tuple[int, int]:
        """(W, H): the crop's, else the file's visible image's (from its header)."""
        if self.crop is not None:
            width, height = self.header.size
            x, y, w, h = self.crop
            if x + w > width or y + h > height:
                raise CamsimError(f"[raw] crop {list(self.crop)} is off the {width}x{height} image of {self.path}")
            return w, h
        width, height = self.header.size
        return width - width % 2, height - height % 2

    @property
    def cfa(self) -> str:
        """The Bayer pattern of the (cropped) frame: the file's, shifted by an odd crop offset."""
        pattern = self.header.cfa
        x, y = (0, 0) if self.crop is None else self.crop[:2]
        return "".join(pattern[2 * ((i // 2 + y) % 2) + (i % 2 + x) % 2] for i in range(4))

    def capture(self):
        """The file's pixels and metadata, cropped (:func:`camsim.io.raw_capture.read_raw_capture`)."""
        from camsim.io.raw_capture import read_raw_capture

        return read_raw_capture(self.path, self.crop)

    @property
    def source_iso(self) -> float:
        """The source's ISO: ``iso`` where given, else the file's. Raises :class:`CamsimError` where neither says."""
        iso = self.iso if self.iso is not None else self.header.iso
        if iso is None:
            raise CamsimError(f"{self.path} records no ISO: set [raw] iso (the source camera's gain depends on it)")
        return float(iso)

    @property
    def source_exposure_s(self) -> float:
        """The source's exposure time: ``exposure_s`` where given, else the file's. Unit: s."""
        exposure = self.exposure_s if self.exposure_s is not None else self.header.exposure_s
        if exposure is None:
            raise CamsimError(f"{self.path} records no exposure time: set [raw] exposure_s")
        return float(exposure)

    def source_preset(self, scene_preset: str | None = None) -> str:
        """The source camera's preset: ``preset``; else the built-in preset of the file's Make and Model; else
        ``scene_preset`` where it is a camera preset. Raises :class:`CamsimError` naming the camera otherwise."""
        from camsim.sensor.presets import camera_preset, preset_for_camera

        if self.preset is not None:
            if camera_preset(self.preset, self.base_dir) is None:
                raise CamsimError(f"[raw] preset {self.preset!r} is a model preset without an ISO axis: name a camera "
                                  "preset (camsim list) or a camsim calibrate preset file PATH.toml")
            return self.preset
        head = self.header
        found = preset_for_camera(head.make, head.model, head.unique_camera_model)
        if found is not None:
            return found
        if scene_preset is not None and camera_preset(scene_preset, self.base_dir) is not None:
            return scene_preset
        said = head.unique_camera_model or " ".join(v for v in (head.make, head.model) if v) or "no Make or Model"
        raise CamsimError(f"{self.path}: unknown camera ({said}) and no preset given: set [raw] preset to a camera "
                          "preset (camsim list) or to the preset.toml camsim calibrate writes for this camera")

    def source_gain_dn_per_e(self) -> float:
        """K_source: the source camera's gain at the source's ISO (:func:`source_gain_dn_per_e` of
        :meth:`source_preset`, which must be resolved: ``preset`` set, as :func:`camsim.scene.scene_file.load_scene`
        leaves it). Unit: DN/e⁻."""
        return source_gain_dn_per_e(self.source_preset(), self.source_iso, self.base_dir)

    def record(self) -> dict:
        """What the sidecar says of the source besides the numbers drawn from it."""
        return {"file": self.path.name, "crop_xywh": None if self.crop is None else list(self.crop),
                "photon_law": self.photon_law}

    def spectra(self, grid, width: int, height: int):
        raise CamsimError("a raw scene has no spectra: its frames are drawn from the file's electrons "
                          "(camsim.render.raw_render)")


def source_gain_dn_per_e(preset: str, iso: float, base_dir=None) -> float:
    """K_source: the gain of camera preset ``preset`` (a name, or a preset file relative to ``base_dir``) at a raw
    source's ``iso``; an ISO outside the preset's range is a :class:`CamsimError` that says it is the source's.
    Unit: DN/e⁻."""
    from camsim.sensor.presets import camera_preset

    try:
        return float(camera_preset(preset, base_dir).point_at(iso).k_dn_per_e)
    except CamsimError as exc:
        raise CamsimError(f"the source camera ({preset}, [raw] preset) at the raw's ISO {iso:g}: {exc}") from None

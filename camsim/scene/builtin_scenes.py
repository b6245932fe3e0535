"""The scene files shipped with camsim (package data in ``camsim/scenes/``), addressable by name.

A built-in scene is named by its file's stem: ``macbeth_26`` is ``camsim/scenes/macbeth_26.toml``. The folder
also holds example dataset specs (``denoise_small.toml``, a TOML file with a top-level ``scene`` key, which a
scene file never has); they are shipped beside the scene they refer to, are not scenes, and are named the same
way (``camsim dataset denoise_small``: :func:`resolve_spec_file`). In a checkout,
``scenes/`` at the repository root is a symbolic link to this folder, so ``scenes/macbeth_26.toml`` keeps
working.

This module imports nothing from camsim but the foundation (:mod:`camsim.core`), so that
:mod:`camsim.scene.scene_file` can use it.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.core.schema import read_toml

__all__ = ["SCENES_DIR", "builtin_scene_names", "builtin_scene_path", "builtin_spec_names", "is_scene_name",
           "resolve_scene_file", "resolve_spec_file"]

#: The folder of the built-in scene files (and example dataset specs).
SCENES_DIR = Path(__file__).parents[1] / "scenes"
SUFFIX = ".toml"


@functools.cache
def _builtin_files() -> dict[str, tuple[str, Path]]:
    """``{stem: (kind, path)}`` for every ``.toml`` file in :data:`SCENES_DIR`; kind ``scene`` or ``dataset``."""
    files = {}
    for path in sorted(SCENES_DIR.glob(f"*{SUFFIX}")):
        doc = read_toml(path, "built-in scene file")  # one line for a file that is not one (a FIFO, a bad TOML)
        files[path.stem] = ("dataset" if "scene" in doc else "scene", path)
    return files


def builtin_scene_names() -> tuple[str, ...]:
    """The names of the built-in scenes, sorted (``macbeth_26``, ...); dataset specs are not listed."""
    return tuple(name for name, (kind, _) in _builtin_files().items() if kind == "scene")


def builtin_spec_names() -> tuple[str, ...]:
    """The names of the built-in dataset specs, sorted (``denoise_small``)."""
    return tuple(name for name, (kind, _) in _builtin_files().items() if kind == "dataset")


def builtin_scene_path(name: str) -> Path:
    """The file of the built-in scene ``name``.

    Raises
    ------
    CamsimError
        If ``name`` is not a built-in scene; the message lists the built-in names.
    """
    kind, path = _builtin_files().get(name, (None, None))
    if kind != "scene":
        raise CamsimError(f"unknown built-in scene {name!r}: the built-in scenes are "
                          f"{', '.join(builtin_scene_names())}")
    return path


def is_scene_name(text: str | os.PathLike) -> bool:
    """Whether ``text`` has the form of a scene name rather than a path: no ``/`` (or ``os.sep``), no ``.toml``."""
    text = os.fspath(text)
    return bool(text) and "/" not in text and os.sep not in text and not text.lower().endswith(SUFFIX)


def _no_nul(name_or_path, what: str) -> None:
    """Refuse a name with a NUL byte, which no file name holds (and which the operating system's calls on a path,
    ``resolve()`` among them, raise ``ValueError`` for), as :func:`camsim.core.input_files.open_input` does."""
    name = os.fspath(name_or_path)
    if "\x00" in (os.fsdecode(name) if isinstance(name, bytes) else name):
        raise CamsimError(f"{what} path {name!r} holds a NUL byte, which no file name can")


def resolve_scene_file(name_or_path: str | os.PathLike, base_dir: str | os.PathLike | None = None) -> Path:
    """The scene file that ``name_or_path`` designates.

    An existing file always wins; otherwise a name (see :func:`is_scene_name`) is looked up among the built-in
    scenes. Anything else is returned as a path, for the reader to report as missing.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A scene file's path or a built-in scene's name (``macbeth_26``).
    base_dir : str or os.PathLike, optional
        The folder a relative path is relative to (a dataset spec's folder); default: the working directory.

    Raises
    ------
    CamsimError
        For a name that is neither an existing file nor a built-in scene (the message lists the built-in names), or
        one with a NUL byte.
    """
    _no_nul(name_or_path, "scene file")
    path = Path(name_or_path) if base_dir is None else Path(base_dir) / name_or_path
    if path.is_file() or not is_scene_name(name_or_path):
        return path
    name = os.fspath(name_or_path)
    if name in builtin_scene_names():
        return builtin_scene_path(name)
    if name in _builtin_files():
        raise CamsimError(f"{name!r} is a built-in dataset spec ({_builtin_files()[name][1]}: camsim dataset), not a "
                          f"scene: the built-in scenes are {', '.join(builtin_scene_names())}")
    where = "" if base_dir is None else f" in {base_dir}"
    raise CamsimError(f"no scene file {name!r}{where} and no built-in scene of that name: the built-in scenes are "
                      f"{', '.join(builtin_scene_names())} (a scene file's path ends in .toml)")


def resolve_spec_file(name_or_path: str | os.PathLike) -> Path:
    """The dataset spec file that ``name_or_path`` designates: an existing file, else a built-in spec's name.

    The rules of :func:`resolve_scene_file`: an existing file always wins; a name (no ``/``, no ``.toml``) is looked
    up among the built-in dataset specs (``denoise_small``); anything else is returned as a path.

    Raises
    ------
    CamsimError
        For a name that is neither an existing file nor a built-in dataset spec (a built-in scene's name is said to
        be one); the message lists the built-in specs.
    """
    _no_nul(name_or_path, "dataset spec")
    path = Path(name_or_path)
    if path.is_file() or not is_scene_name(name_or_path):
        return path
    name = os.fspath(name_or_path)
    specs = ", ".join(builtin_spec_names())
    kind, builtin = _builtin_files().get(name, (None, None))
    if kind == "dataset":
        return builtin
    if kind == "scene":
        raise CamsimError(f"{name!r} is a built-in scene (camsim render {name}), not a dataset spec: the built-in "
                          f"dataset specs are {specs}")
    raise CamsimError(f"no dataset spec file {name!r} and no built-in dataset spec of that name: the built-in dataset "
                      f"specs are {specs} (a spec file's path ends in .toml)")

"""The bundled presets (JSON package data) and the one place that locates them.

``<name>.json`` here are dataset presets for the renderer; their components live in
``styles/``, ``cameras/``, ``quality/`` and ``fog/`` (fog levels, also used by ``fogsim fog``).
A name resolves to the bundled file; a path ending in ``.json`` (or an existing file) is the
user's own preset.
"""
from __future__ import annotations

from pathlib import Path

from fogsim.errors import InputError

ROOT = Path(__file__).resolve().parent
COMPONENTS = ("styles", "cameras", "quality", "fog")


def presets_dir() -> Path:
    """The folder of the bundled presets (inside the installed package)."""
    return ROOT


def names(kind: str | None = None) -> list[str]:
    """Bundled dataset presets (``kind=None``) or components of one kind, sorted."""
    folder = ROOT if kind is None else ROOT / kind
    return sorted(p.stem for p in folder.glob("*.json"))


def component_path(kind: str, name: str, source) -> Path:
    """The bundled component ``kind/name.json``; an unknown name is an error naming ``source``."""
    path = ROOT / kind / f"{name}.json"
    if not path.is_file():
        what = {"styles": "style", "cameras": "camera", "fog": "fog preset"}.get(kind, kind)
        raise InputError(source, f"unknown {what} {name!r} (known: {', '.join(names(kind))})")
    return path


def preset_path(name_or_path: str | None) -> Path:
    """``None`` → the default dataset preset; a name → the bundled one; else the path itself."""
    if name_or_path is None:
        return ROOT / "default.json"
    p = Path(name_or_path)
    if p.suffix == ".json" or p.exists():
        return p
    return ROOT / f"{name_or_path}.json"

"""The bundled presets (JSON package data) and the one place that locates them.

``<name>.json`` here are dataset presets for the renderer; their components live in
``styles/``, ``cameras/``, ``quality/`` and ``fog/`` (fog levels, also used by ``fogsim fog``).
A name resolves to the bundled file; a path ending in ``.json`` (or an existing file) is the
user's own preset.
"""
from __future__ import annotations

from pathlib import Path

from fogsim.errors import InputError
from fogsim.schema.presets import COMPONENT_NAME as NAME  # a name, never a path (no '/', '..', '.json')

ROOT = Path(__file__).resolve().parent
COMPONENTS = ("styles", "cameras", "quality", "fog")
#: The JSON Schema of a dataset preset (``fogsim schema preset`` writes it; a test checks it is current).
SCHEMA_FILE = ROOT / "preset.schema.json"


def presets_dir() -> Path:
    """The folder of the bundled presets (inside the installed package)."""
    return ROOT


def names(kind: str | None = None) -> list[str]:
    """Bundled dataset presets (``kind=None``) or components of one kind, sorted."""
    folder = ROOT if kind is None else ROOT / kind
    return sorted(p.stem for p in folder.glob("*.json") if p.name != SCHEMA_FILE.name)


def _what(kind: str) -> str:
    return {"styles": "style", "cameras": "camera", "fog": "fog preset"}.get(kind, kind)


def check_component_name(name: str, kind: str) -> str:
    """``name`` if it can name a bundled component (letters, digits, '-', '_'), else ValueError."""
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise ValueError(f"{_what(kind)} name {name!r} may hold only letters, digits, '-' and '_' "
                         f"(bundled: {', '.join(names(kind))})")
    return name


def component_path(kind: str, name: str, source) -> Path:
    """The bundled component ``kind/name.json``; a bad or unknown name is an error naming ``source``."""
    try:
        check_component_name(name, kind)
    except ValueError as exc:
        raise InputError(source, str(exc)) from None
    path = ROOT / kind / f"{name}.json"
    if not path.is_file():
        raise InputError(source, f"unknown {_what(kind)} {name!r} (known: {', '.join(names(kind))})")
    return path


def preset_path(name_or_path: str | None) -> Path:
    """``None`` → the default dataset preset; a name → the bundled one; else the path itself."""
    if name_or_path is None:
        return ROOT / "default.json"
    p = Path(name_or_path)
    if p.suffix == ".json" or p.exists():
        return p
    return ROOT / f"{name_or_path}.json"

"""The user's own models in the procedural streets: files, normalisation, size rules, sampling (no bpy).

A library is the preset's ``assets`` object (:class:`fogsim.schema.presets.Assets`): per class a
folder or glob of model files (:data:`FORMATS`). The renderer imports each file once per run
with Blender's own importer and hands its triangles here; :func:`normalise` turns them into the
asset frame every fogsim asset uses (metres, origin at the centre of the ground footprint,
z up, the front toward +y) and :func:`fit_size` checks the model against its class's real size
(:data:`SIZE_RANGES`), refusing it — an :class:`~fogsim.errors.InputError` naming the file and
its size — or scaling it into range when the preset says ``out_of_range: "scale"``.

The layout asks :meth:`AssetLibrary.pick` for a model per object; it draws from the frame's
generator only for classes that have a library, so a preset without ``assets`` lays out the
very streets it always did. A picked model is the asset spec ``{"type": "library", "params":
{"file": …, "class": …, "extent": [sx, sy, sz], "scale": s}}``; the file is what the frame's
meta records for the object.
"""
from __future__ import annotations

import glob
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.schema.presets import ASSET_CLASSES, ASSET_UNITS

#: model file suffix → Blender importer (fogsim.render.blender.library)
FORMATS = {".glb": "gltf", ".gltf": "gltf", ".obj": "obj", ".fbx": "fbx", ".blend": "blend"}
#: real size per class: (dimension, low, high) in metres; "length" is along the front (local y),
#: "height" is z above the ground
SIZE_RANGES = {"car": ("length", 3.0, 6.0), "van": ("length", 4.0, 7.5), "truck": ("length", 5.0, 20.0),
               "bus": ("length", 8.0, 20.0), "pedestrian": ("height", 1.4, 2.1), "cyclist": ("height", 1.4, 2.3),
               "traffic_light": ("height", 2.0, 8.0), "traffic_sign": ("height", 1.0, 5.0)}
assert tuple(SIZE_RANGES) == ASSET_CLASSES  # one list of classes, declared by the schema
#: rotation about z (degrees) that turns a model's front axis to +y
_TURN = {"+y": 0.0, "-y": 180.0, "+x": 90.0, "-x": -90.0}


def model_files(where: str, base: Path | None = None) -> list[Path]:
    """The model files of one class: every file of a supported format under the folder ``where``
    (recursively), or matching the glob ``where``; relative to ``base``. Sorted; [] if none."""
    path = Path(where).expanduser()
    if not path.is_absolute() and base is not None:
        path = base / path
    found = path.rglob("*") if path.is_dir() else (Path(p) for p in glob.glob(str(path), recursive=True))
    return sorted(p.resolve() for p in found if p.is_file() and p.suffix.lower() in FORMATS)


def library_files(assets: dict, source, base: Path | None = None) -> dict[str, list[str]]:
    """Class → model files (absolute paths) of a checked ``assets`` object; a class whose folder
    or glob holds no model file is an InputError naming ``source`` (the preset or --assets)."""
    out = {}
    for cls in ASSET_CLASSES:
        if assets.get(cls) is None:
            continue
        files = model_files(assets[cls], base)
        if not files:
            raise InputError(source, f"assets.{cls}: no model file ({', '.join(FORMATS)}) in or matching "
                                     f"{assets[cls]!r}")
        out[cls] = [str(f) for f in files]
    return out


def assets_dir(folder: str | Path) -> dict[str, str]:
    """``--assets DIR``: one sub-folder per class (``DIR/car``, ``DIR/pedestrian`` …) → the
    ``assets`` class entries. Another sub-folder, or none of a class, is an InputError."""
    root = Path(folder).expanduser()
    if not root.is_dir():
        raise InputError(root, "--assets: not a folder")
    subs = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    unknown = [s for s in subs if s not in ASSET_CLASSES]
    if unknown:
        raise InputError(root, f"--assets: sub-folder(s) {unknown} are not classes (one sub-folder per class: "
                               f"{', '.join(ASSET_CLASSES)})")
    if not subs:
        raise InputError(root, f"--assets: no class sub-folder ({', '.join(ASSET_CLASSES)})")
    return {s: str((root / s).resolve()) for s in subs}


def normalise(vertices: np.ndarray, forward: str, units: str) -> np.ndarray:
    """The 4×4 that takes a model as Blender imported it (z up, ``units``, front toward
    ``forward``) into the asset frame: metres, front toward +y, footprint centred on the
    origin, lowest point on z = 0 (wheels and feet on the ground)."""
    s = ASSET_UNITS[units]
    a = math.radians(_TURN[forward])
    M = np.eye(4)
    M[:3, :3] = s * np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    v = np.asarray(vertices, np.float64) @ M[:3, :3].T
    lo, hi = v.min(axis=0), v.max(axis=0)
    M[:3, 3] = [-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]]
    return M


def extent(vertices: np.ndarray) -> tuple[float, float, float]:
    """(size_x, size_y, size_z) of the vertices' bounding box, metres."""
    v = np.asarray(vertices, np.float64)
    return tuple(float(d) for d in v.max(axis=0) - v.min(axis=0))


def fit_size(file: str, cls: str, size: tuple[float, float, float], out_of_range: str = "refuse") -> float:
    """The scale that puts a normalised model of ``size`` (metres) in its class's range: 1 inside
    it; outside it an InputError naming the file and its size, or (``out_of_range="scale"``)
    the uniform scale to the nearest end of the range."""
    dim, lo, hi = SIZE_RANGES[cls]
    value = size[1] if dim == "length" else size[2]
    if lo <= value <= hi:
        return 1.0
    if out_of_range == "scale" and value > 0:
        return (lo if value < lo else hi) / value
    w, ln, h = size
    raise InputError(file, f"a {cls} model must be {lo:g}–{hi:g} m in {dim}, this one is {value:.3g} m "
                           f"({ln:.3g} m long, {w:.3g} m wide, {h:.3g} m high after import); check its units "
                           "(assets.units), its front axis (assets.forward) or set assets.out_of_range \"scale\"")


@dataclass(frozen=True)
class LibraryModel:
    """One imported model in the asset frame: ``vertices`` (N×3 metres) and triangle ``faces``
    (F×3), its bounding-box ``extent`` and the ``scale`` applied on top of its units (≠ 1 only
    when scaled into range)."""

    file: str
    cls: str
    vertices: np.ndarray
    faces: np.ndarray
    extent: tuple[float, float, float]
    scale: float = 1.0

    def spec(self) -> dict:
        return {"type": "library", "params": {"file": self.file, "class": self.cls,
                                              "extent": [round(e, 6) for e in self.extent],
                                              "scale": self.scale}, "materials": {}}


@dataclass
class AssetLibrary:
    """The models of a run by class, and the share of library models per class (``mix``)."""

    models: dict[str, list[LibraryModel]] = field(default_factory=dict)
    mix: dict[str, float] = field(default_factory=dict)

    def pick(self, cls: str, rng: np.random.Generator) -> dict | None:
        """A library model's spec for an object of ``cls``, or None (procedural). Draws from
        ``rng`` only when ``cls`` has models."""
        models = self.models.get(cls)
        if not models:
            return None
        if rng.random() >= self.mix.get(cls, 1.0):
            return None
        return models[int(rng.integers(len(models)))].spec()

    def mesh(self, file: str) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, faces) of the model ``file`` in the asset frame."""
        for models in self.models.values():
            for m in models:
                if m.file == file:
                    return m.vertices, m.faces
        raise KeyError(f"{file} is not in the asset library of this run")

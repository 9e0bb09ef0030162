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
import re
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
#: the material slot of a library model's parts (``library:<material name>``; ``library`` alone: unnamed)
LIBRARY_SLOT = "library"
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


def library_files(assets: dict, source, base: Path | None = None, root: Path | None = None) -> dict[str, list[str]]:
    """Class → model files (absolute paths) of a checked ``assets`` object; a class whose folder
    or glob holds no model file is an InputError naming ``source`` (the preset or --assets).

    Every model, and every file it refers to, must lie inside the library (:func:`reference_problem`):
    ``root`` (the ``--assets`` folder), else the preset's folder ``base`` for a relative entry, else
    the entry's own folder (an absolute one); one that does not is an InputError naming it."""
    out = {}
    for cls in ASSET_CLASSES:
        if assets.get(cls) is None:
            continue
        files = model_files(assets[cls], base)
        if not files:
            raise InputError(source, f"assets.{cls}: no model file ({', '.join(FORMATS)}) in or matching "
                                     f"{assets[cls]!r}")
        inside = root or _entry_root(assets[cls], base)
        for f in files:
            if problem := reference_problem(f, inside):
                raise InputError(f, f"assets.{cls}: {problem}")
        out[cls] = [str(f) for f in files]
    return out


def _entry_root(where: str, base: Path | None) -> Path:
    """The folder a preset's class entry confines its models to: the preset's folder for a relative
    entry, else the entry's folder (a glob: the part before its first wildcard)."""
    path = Path(where).expanduser()
    if not path.is_absolute() and base is not None:
        return Path(base)
    plain = Path(*[p for p in path.parts[:next((i for i, p in enumerate(path.parts) if glob.has_magic(p)),
                                                len(path.parts))]])
    return plain if plain.is_dir() else plain.parent


# ----------------------------------------------------------------------------- confinement
#: an URI with a scheme (http:, file:, …): a glTF's files must be relative references or data: URIs
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
#: OBJ / MTL statements that name a file (the file is the statement's last word; MTL options come first)
_OBJ_FILES = re.compile(rb"^[ \t]*(mtllib|map_\w+|bump|disp|decal|refl|norm)[ \t]+(.+?)[ \t]*$",
                        re.MULTILINE | re.IGNORECASE)
#: an FBX's external files: node FileName / RelativeFilename, one string property (binary FBX) or ASCII
_FBX_FILES = (re.compile(rb"[\x08]FileNameS(....)|[\x10]RelativeFilenameS(....)", re.DOTALL),
              re.compile(rb'(?:FileName|RelativeFilename)\s*:\s*"([^"]*)"'))


def inside(path: Path, root: Path) -> bool:
    """Whether ``path``, its symlinks resolved, lies in the folder ``root`` (resolved too)."""
    from fogsim.io.paths import resolve_path

    p, r = resolve_path(path), resolve_path(root)
    return p == r or r in p.parents


def reference_problem(file: str | Path, root: Path) -> str | None:
    """Why the model ``file`` reaches outside the library folder ``root``, or None: the file itself
    (a symlink out of the library), a glTF's buffer or image ``uri`` (data: URIs are fine; another
    scheme or a path outside is not), an OBJ's ``mtllib`` and the texture maps of those MTL files,
    an FBX's external texture names. Blender's importers follow these references, so they are read
    here first, without Blender: the model's own JSON or text (no geometry is decoded)."""
    file = Path(file)
    if not inside(file, root):
        return f"the model file is outside the library folder {root} (a link out of it?)"
    refs = []
    try:
        suffix = file.suffix.lower()
        if suffix in (".gltf", ".glb"):
            refs = _gltf_uris(file)
        elif suffix == ".obj":
            refs = _obj_refs(file, root)
        elif suffix == ".fbx":
            refs = _fbx_refs(file)
    except InputError as exc:
        return exc.problem
    for where, ref in refs:
        if ref.startswith("data:"):
            continue
        if _SCHEME.match(ref) and not re.match(r"^[A-Za-z]:[\\/]", ref):
            return f"{where} {ref[:80]!r} is not a file of the library (only relative paths and data: URIs)"
        target = Path(ref.replace("\\", "/"))
        target = target if target.is_absolute() else file.parent / target
        if suffix == ".fbx" and not target.exists():
            continue  # FBX keeps the authoring machine's absolute paths: one that is not here reads nothing
        if not inside(target, root):
            return (f"{where} {ref[:80]!r} points outside the library folder {root}: refused before any "
                    "importer reads it")
    return None


def _gltf_uris(file: Path) -> list[tuple[str, str]]:
    """The ``uri`` of every buffer and image of a .gltf (JSON) or .glb (its JSON chunk), percent-decoded."""
    import struct
    from urllib.parse import unquote

    from fogsim.io.documents import MAX_JSON_BYTES, parse_json, read_text_bounded

    if file.suffix.lower() == ".glb":
        with open(file, "rb") as f:
            head = f.read(20)
            if len(head) < 20 or head[:4] != b"glTF":
                raise InputError(file, "not a GLB file (no glTF header)")
            size, kind = struct.unpack("<II", head[12:20])
            if kind != 0x4E4F534A or size > MAX_JSON_BYTES:
                raise InputError(file, "not a GLB file (its first chunk is not JSON of a sane size)")
            text = f.read(size)
    else:
        text = read_text_bounded(file, MAX_JSON_BYTES, "glTF file")
    doc = parse_json(text, file)
    refs = []
    for key in ("buffers", "images"):
        items = doc.get(key, []) if isinstance(doc, dict) else []
        for i, item in enumerate(items if isinstance(items, list) else []):
            uri = item.get("uri") if isinstance(item, dict) else None
            if uri is not None:
                if not isinstance(uri, str):
                    raise InputError(file, f"{key}[{i}].uri must be a string")
                refs.append((f"{key}[{i}].uri", uri if uri.startswith("data:") else unquote(uri)))
    return refs


def _obj_refs(file: Path, root: Path) -> list[tuple[str, str]]:
    """An OBJ's material libraries and, of those inside the library, their texture maps."""
    refs = []
    for match in _OBJ_FILES.finditer(file.read_bytes()):
        if match.group(1).lower() != b"mtllib":
            continue
        name = match.group(2).decode("utf-8", "replace")
        refs.append(("mtllib", name))
        mtl = Path(name) if Path(name).is_absolute() else file.parent / name
        if mtl.is_file() and inside(mtl, root):
            for m in _OBJ_FILES.finditer(mtl.read_bytes()):
                if m.group(1).lower() != b"mtllib":
                    word = m.group(2).split()[-1].decode("utf-8", "replace")
                    # an MTL's maps are relative to the MTL's folder
                    refs.append((f"{mtl.name}: {m.group(1).decode()}",
                                 word if Path(word).is_absolute() else str(mtl.parent / word)))
    return refs


def _fbx_refs(file: Path) -> list[tuple[str, str]]:
    """An FBX's external file names (binary or ASCII FBX; embedded textures need none)."""
    import struct

    data = file.read_bytes()
    refs = []
    binary, ascii_ = _FBX_FILES
    for m in binary.finditer(data):
        start = m.end()
        (n,) = struct.unpack("<I", m.group(1) or m.group(2))
        refs.append(("texture file", data[start:start + n].decode("utf-8", "replace")))
    for m in ascii_.finditer(data):
        refs.append(("texture file", m.group(1).decode("utf-8", "replace")))
    return [(w, r) for w, r in refs if r]


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
    when scaled into range); ``materials``: what its file says of each of its materials (``name``;
    ``color``, the base colour in linear RGB or None; ``transmission`` 0–1; ``reflectivity``, its own
    ``fogsim_reflectivity`` or None) and ``face_material`` (F int, an index into them; None: one unnamed
    material), which the LiDAR maps to 905 nm reflectivities by name and kind
    (:func:`fogsim.scene.reflectivity.material_entry`)."""

    file: str
    cls: str
    vertices: np.ndarray
    faces: np.ndarray
    extent: tuple[float, float, float]
    scale: float = 1.0
    materials: tuple[dict, ...] = ()
    face_material: np.ndarray | None = None

    def slots(self) -> list[str]:
        """The material slot of each of :attr:`materials`: ``library:<name>`` (:data:`LIBRARY_SLOT`)."""
        return [f"{LIBRARY_SLOT}:{m['name']}" if m.get("name") else LIBRARY_SLOT for m in self.materials]

    def spec(self) -> dict:
        return {"type": "library", "params": {"file": self.file, "class": self.cls,
                                              "extent": [round(e, 6) for e in self.extent],
                                              "scale": self.scale},
                "materials": {slot: {k: m[k] for k in ("color", "transmission", "reflectivity") if m.get(k) is not None}
                              for slot, m in zip(self.slots(), self.materials)}}

    def parts(self) -> list[tuple[np.ndarray, np.ndarray, str]]:
        """(vertices, faces, slot) per material (each with only the vertices its faces use); one
        ``library`` part without materials."""
        if self.face_material is None or not self.materials:
            return [(self.vertices, self.faces, LIBRARY_SLOT)]
        out = []
        for k, slot in enumerate(self.slots()):
            f = self.faces[self.face_material == k]
            if len(f):
                used, inverse = np.unique(f, return_inverse=True)
                out.append((self.vertices[used], inverse.reshape(f.shape), slot))
        return out


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

    def model(self, file: str) -> LibraryModel:
        """The model ``file``."""
        for models in self.models.values():
            for m in models:
                if m.file == file:
                    return m
        raise KeyError(f"{file} is not in the asset library of this run")

    def mesh(self, file: str) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, faces) of the model ``file`` in the asset frame."""
        m = self.model(file)
        return m.vertices, m.faces

"""Class maps: evaluating detections of one class list against another, to compare sources.

A :class:`ClassMap` sends each *source* class (a dataset's or a model's class list) to a
*target* class or drops it (None). It is applied to COCO ground truth and COCO results alike
(category id = index in the class list + 1, :mod:`fogsim.boxes`): annotations and detections
of dropped classes are removed, the others take the target's category id. Maps run from the
finer list to the coarser one, never the other way round.

Built-in maps (``--class-map NAME``):

* ``fogsim-to-waymo`` — fogsim's renderer classes to Waymo's 2D classes
  (``docs/real-data.md``): car, van, truck, bus → vehicle; pedestrian → pedestrian;
  cyclist → cyclist; traffic_light, traffic_sign dropped (Waymo has no 2D sign labels).
* ``fogsim-to-cityscapes`` — to the 8 Cityscapes detection classes: car, truck, bus as they
  are; van → car (Cityscapes' car includes vans); pedestrian → person; cyclist → rider (the
  Cityscapes rider box excludes the bicycle, fogsim's cyclist box holds both: an approximation);
  traffic_light, traffic_sign dropped. Cityscapes' train, motorcycle and bicycle have no fogsim
  class: no source reaches them.

A JSON map (``--class-map FILE.json`` or the JSON text itself): ``{"map": {"car": "vehicle",
"traffic_sign": null, …}, "classes": ["vehicle", …]}`` (``classes``, the target list, defaults
to the mapped names in order of first appearance), or the flat ``{"car": "vehicle", …}``.
Every class of the source list must have an entry (a target or null), so nothing is dropped
by accident.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fogsim.boxes import coco_category
from fogsim.errors import InputError
from fogsim.io.documents import MAX_DOCUMENT_BYTES, parse_json, read_text_bounded
from fogsim.readers.cityscapes_labels import CITYSCAPES_CLASSES
from fogsim.readers.waymo.labels import WAYMO_CLASSES
from fogsim.scene.classes import LABELLED
from fogsim.schema.base import check
from fogsim.schema.documents import ClassMapFile


@dataclass(frozen=True)
class ClassMap:
    """``mapping``: source class → target class (None = dropped); ``targets``: the target class
    list (its order gives the category ids, index + 1)."""

    name: str
    mapping: dict
    targets: tuple[str, ...]

    def __post_init__(self):
        bad = [t for t in self.mapping.values() if t is not None and t not in self.targets]
        if bad:
            raise ValueError(f"class map {self.name}: targets {bad} are not in its class list {list(self.targets)}")

    def check_source(self, classes, where: str) -> None:
        """Every class of ``classes`` (the list the map is applied to) must have an entry."""
        missing = [c for c in classes if c not in self.mapping]
        if missing:
            raise InputError(where, f"classes {missing} have no entry in class map {self.name} "
                                    "(map each class to a target, or to null to drop it)")

    def reached(self) -> list[str]:
        """The target classes some source class maps to, in target order."""
        hit = set(v for v in self.mapping.values() if v is not None)
        return [t for t in self.targets if t in hit]

    def category_ids(self, source_classes) -> dict[int, int | None]:
        """Source category id → target category id (None: dropped)."""
        return {coco_category(i): (None if self.mapping.get(c) is None else
                                   coco_category(self.targets.index(self.mapping[c])))
                for i, c in enumerate(source_classes)}

    def to_dict(self) -> dict:
        return {"name": self.name, "map": dict(self.mapping), "classes": list(self.targets)}


def identity(classes, name: str = "identity") -> ClassMap:
    return ClassMap(name, {c: c for c in classes}, tuple(classes))


def restriction(classes, keep, name: str) -> ClassMap:
    """``classes`` onto themselves, keeping only ``keep`` (the others dropped)."""
    return ClassMap(name, {c: (c if c in keep else None) for c in classes}, tuple(classes))


def _from_fogsim(name: str, mapping: dict, targets) -> ClassMap:
    """A built-in map from fogsim's renderer classes: an entry for every one of them."""
    if set(mapping) != set(LABELLED):
        raise AssertionError(f"class map {name} must cover fogsim's classes {LABELLED}")
    return ClassMap(name, mapping, tuple(targets))


BUILTIN = {
    "fogsim-to-waymo": _from_fogsim("fogsim-to-waymo", {
        "car": "vehicle", "van": "vehicle", "truck": "vehicle", "bus": "vehicle", "pedestrian": "pedestrian",
        "cyclist": "cyclist", "traffic_light": None, "traffic_sign": None}, WAYMO_CLASSES),
    "fogsim-to-cityscapes": _from_fogsim("fogsim-to-cityscapes", {
        "car": "car", "van": "car", "truck": "truck", "bus": "bus", "pedestrian": "person", "cyclist": "rider",
        "traffic_light": None, "traffic_sign": None}, CITYSCAPES_CLASSES),
}


def load_class_map(text: str) -> ClassMap:
    """A built-in map by name, a JSON file, or JSON text (see the module docstring)."""
    if text in BUILTIN:
        return BUILTIN[text]
    source = text
    if not text.lstrip().startswith("{"):
        path = Path(text)
        if not path.is_file():
            raise InputError(text, f"not a class map: no such file, and not one of {', '.join(BUILTIN)}")
        text = read_text_bounded(path, MAX_DOCUMENT_BYTES, "class map")
        source = str(path)
    data = parse_json(text, source if source != text or len(source) < 80 else "--class-map")
    where = source if source != text else "--class-map"  # the file, or the flag that gave the JSON text
    if isinstance(data, dict) and "map" not in data:  # the flat form {source: target}
        data = {"map": data}
    doc = check(data, ClassMapFile, where)
    mapping = doc.map
    targets = doc.classes
    if targets is None:
        targets = list(dict.fromkeys(v for v in mapping.values() if v is not None))
    try:
        return ClassMap(Path(source).name if source != text else "json", dict(mapping), tuple(targets))
    except ValueError as exc:
        raise InputError(where, str(exc)) from None


def map_ground_truth(gt: dict, cmap: ClassMap, source_classes) -> dict:
    """A copy of a COCO ground-truth dict in the map's target classes: dropped classes' annotations
    removed, categories = the reached target classes."""
    ids = cmap.category_ids(source_classes)
    anns = [dict(a, category_id=ids[a["category_id"]]) for a in gt["annotations"]
            if ids.get(a["category_id"]) is not None]
    cats = [{"id": coco_category(cmap.targets.index(t)), "name": t, "supercategory": "street"} for t in cmap.reached()]
    return {**gt, "annotations": anns, "categories": cats}


def map_detections(dets: list[dict], cmap: ClassMap, source_classes) -> list[dict]:
    """COCO results in the map's target classes (detections of dropped classes removed)."""
    ids = cmap.category_ids(source_classes)
    return [dict(d, category_id=ids[d["category_id"]]) for d in dets if ids.get(d["category_id"]) is not None]

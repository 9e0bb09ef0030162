"""KITTI ``label_2/NNNNNN.txt`` (and STF's ``gt_labels/cam_left_labels_TMP``) as fogsim
:class:`~fogsim.readers.base.Labels`, and the one formatter of a label line (the KITTI writer's).

A line holds 15 space-separated fields (16 with a detector's ``score``): type; truncated (0–1);
occluded (0 visible, 1 partly, 2 largely, 3 unknown); alpha (rad); the 2D box left top right bottom
(px, image 2); dimensions h w l (m); location x y z (m, rectified camera frame, the box's **bottom**
centre); rotation_y (rad, about the camera's y axis). STF adds columns after these 15 (3D rotation
angles, quaternions, visibility flags: 27 in all, as its ``lib/read.py`` reads them); the STF variant
reads the first 15 of lines with ≥ 15 fields.

Records (the fields of :class:`~fogsim.readers.base.Labels`, plus the label's own):

* ``bbox`` = ``[left, top, right + 1, bottom + 1)`` clamped to the image: KITTI's box coordinates are
  inclusive pixel indices (integer = pixel centre), fogsim's are pixel edges; ``pixels`` its area;
  ``kitti_bbox`` the four numbers as written.
* ``truncation`` (KITTI's truncated), ``occlusion`` (occluded), ``alpha``, ``dimensions_m`` [h, w, l],
  ``location_m`` [x, y, z], ``rotation_y``, ``score`` (16-field lines), ``line`` (1-based).
* ``distance_m``: the ray distance from camera 2's centre to the 3D box's centre (location − h/2 along
  y), ``distance_source`` says so; ``planar_depth_m`` that centre's depth along camera 2's axis.
* ``difficulty``: KITTI's benchmark level, 1 easy (box height ≥ 40 px, occluded 0, truncated ≤ 0.15),
  2 moderate (≥ 25 px, ≤ 1, ≤ 0.30), 3 hard (≥ 25 px, ≤ 2, ≤ 0.50), 0 none of them.
* ``DontCare`` rows are ignore regions: one record per class (``kept`` False, reason ``"DontCare region"``),
  so a detection of any class there is neither a hit nor a false alarm; the copies share their ``line``, and
  the dataset's writers write the region once (``label_2``: one line; COCO: one ``DontCare`` annotation,
  :mod:`fogsim.dataset.coco`). STF: a type outside
  :data:`STF_CLASSES` is an ignore region the same way (reason ``"unlabelled type …"``), a ``…_is_group``
  type an ignore region of its base class (reason ``"group"``).

A line with the wrong number of fields, a non-number, or (KITTI) an unknown type is one
:class:`~fogsim.errors.InputError` naming the file and line.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.io.documents import read_text_file
from fogsim.readers.base import Labels
from fogsim.readers.kitti.calib import KittiCalib, read_kitti_calib

__all__ = ["DISTANCE_SOURCE", "KITTI_CLASSES", "KittiLabels", "STF_CLASSES", "format_label_line", "label_records",
           "parse_label_line"]

KITTI_CLASSES = ("Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc")
#: STF's four main classes and its two fallbacks (its README)
STF_CLASSES = ("PassengerCar", "Pedestrian", "RidableVehicle", "LargeVehicle", "Vehicle", "Obstacle")
DONT_CARE = "DontCare"
DISTANCE_SOURCE = "3D box centre (label location − h/2), from camera 2's centre"
#: KITTI's difficulty levels: (min box height px, max occluded, max truncated)
DIFFICULTY = ((40, 0, 0.15), (25, 1, 0.30), (25, 2, 0.50))


@dataclass(frozen=True)
class LabelLine:
    """The 15 (16) fields of one line, as numbers."""

    type: str
    truncated: float
    occluded: int
    alpha: float
    box: tuple[float, float, float, float]
    dimensions: tuple[float, float, float]  # h, w, l
    location: tuple[float, float, float]
    rotation_y: float
    score: float | None = None


def parse_label_line(line: str, source, n: int, variant: str = "kitti") -> LabelLine:
    """One line (``variant`` ``kitti``: 15 or 16 fields; ``stf``: ≥ 15, the first 15 read)."""
    f = line.split()
    ok = len(f) in (15, 16) if variant == "kitti" else len(f) >= 15
    if not ok:
        want = "15 (16 with a score)" if variant == "kitti" else "at least 15"
        raise InputError(source, f"line {n}: {len(f)} fields, expected {want}")
    try:
        nums = [float(v) for v in f[1:15]]
        score = float(f[15]) if variant == "kitti" and len(f) == 16 else None
    except ValueError:
        raise InputError(source, f"line {n}: fields 2–{len(f)} must be numbers") from None
    if not np.isfinite(nums).all() or (score is not None and not np.isfinite(score)):
        raise InputError(source, f"line {n}: NaN or infinite values")
    if nums[1] != int(nums[1]):
        raise InputError(source, f"line {n}: occluded must be an integer 0–3, got {f[2]}")
    return LabelLine(f[0], nums[0], int(nums[1]), nums[2], tuple(nums[3:7]), tuple(nums[7:10]), tuple(nums[10:13]),
                     nums[13], score)


def format_label_line(record: dict) -> str:
    """The 15-field KITTI line of a record made by :func:`label_records` (or written to its fields)."""
    def num(v) -> str:
        return f"{float(v):.2f}"
    box = record["kitti_bbox"]
    h, w, length = record["dimensions_m"]
    x, y, z = record["location_m"]
    kind = record["kitti_type"] if "kitti_type" in record else record["class"]
    fields = [kind, num(record["truncation"]), str(int(record["occlusion"])),
              num(record["alpha"]), *(num(v) for v in box), num(h), num(w), num(length), num(x), num(y), num(z),
              num(record["rotation_y"])]
    return " ".join(fields)


def _difficulty(line: LabelLine) -> int:
    height = line.box[3] - line.box[1]
    for level, (min_h, max_occ, max_trunc) in enumerate(DIFFICULTY, 1):
        if height >= min_h and line.occluded <= max_occ and line.truncated <= max_trunc:
            return level
    return 0


def _bbox(box, width: int, height: int) -> list[float]:
    left, top, right, bottom = box
    return [float(np.clip(left, 0, width)), float(np.clip(top, 0, height)),
            float(np.clip(right + 1, 0, width)), float(np.clip(bottom + 1, 0, height))]


def label_records(text: str, source, width: int, height: int, calib: KittiCalib | None = None,
                  variant: str = "kitti") -> tuple[tuple[str, ...], list[dict]]:
    """(classes, records) of a label file's text (the module docstring)."""
    classes = KITTI_CLASSES if variant == "kitti" else STF_CLASSES
    centre = calib.camera_centre(2) if calib is not None else np.zeros(3)
    third = calib.P[2][2] if calib is not None else np.array([0, 0, 1.0, 0])  # P's third row: the depth
    records: list[dict] = []
    for n, raw in enumerate(text.splitlines(), 1):
        if not raw.strip():
            continue
        line = parse_label_line(raw, source, n, variant)
        base = {"kitti_type": line.type, "truncation": line.truncated, "occlusion": line.occluded,
                "alpha": line.alpha, "kitti_bbox": list(line.box), "dimensions_m": list(line.dimensions),
                "location_m": list(line.location), "rotation_y": line.rotation_y, "line": n}
        if line.score is not None:
            base["score"] = line.score
        bbox = _bbox(line.box, width, height)
        pixels = max(0.0, bbox[2] - bbox[0]) * max(0.0, bbox[3] - bbox[1])
        kind, reason = line.type, None
        if variant == "stf" and kind.endswith("_is_group") and kind[: -len("_is_group")] in classes:
            kind, reason = kind[: -len("_is_group")], "group"
        if kind == DONT_CARE or kind not in classes:
            if variant == "kitti" and kind != DONT_CARE:
                raise InputError(source, f"line {n}: unknown object type {line.type!r} (KITTI's: "
                                         f"{', '.join(KITTI_CLASSES + (DONT_CARE,))})")
            why = "DontCare region" if kind == DONT_CARE else f"unlabelled type {line.type!r}"
            for cid, name in enumerate(classes):  # an ignore region for every class
                records.append({**base, "class": name, "class_id": cid, "bbox": bbox, "pixels": pixels,
                                "kept": False, "reason": why, "distance_m": None, "distance_source": "unknown"})
            continue
        if variant == "kitti" and min(line.dimensions) <= 0:  # only DontCare rows carry KITTI's −1 sizes
            raise InputError(source, f"line {n}: a {line.type}'s dimensions h w l must be positive metres, got "
                                     f"{' '.join(f'{v:g}' for v in line.dimensions)}")
        h = line.dimensions[0]
        c = np.asarray(line.location) - [0.0, h / 2.0, 0.0]
        ray = c - centre
        records.append({**base, "class": kind, "class_id": classes.index(kind), "bbox": bbox, "pixels": pixels,
                        "kept": reason is None, "reason": reason, "difficulty": _difficulty(line),
                        "distance_m": float(np.linalg.norm(ray)), "distance_source": DISTANCE_SOURCE,
                        "planar_depth_m": float(third[:3] @ c + third[3])})
    return classes, records


@dataclass(frozen=True)
class KittiLabels:
    """Picklable label reader: ``KittiLabels(label, calib, width, height)() → Labels`` (``calib``: the
    frame's calibration file, or one file for a whole STF tree; ``variant`` ``kitti`` or ``stf``; a
    :class:`KittiCalib` may be given instead of a path)."""

    label_path: str
    calib: "str | KittiCalib | None"
    width: int
    height: int
    variant: str = "kitti"

    @property
    def classes(self) -> tuple[str, ...]:
        """The class list of every frame's labels (KITTI's or STF's), known without reading a file."""
        return KITTI_CLASSES if self.variant == "kitti" else STF_CLASSES

    def __call__(self) -> Labels:
        path = Path(self.label_path)
        text = read_text_file(path, "label file")
        calib = self.calib
        if isinstance(calib, (str, os.PathLike)):
            calib = read_kitti_calib(calib, require_imu=self.variant == "kitti")
        classes, records = label_records(text, str(path), self.width, self.height, calib, self.variant)
        return Labels(classes, records)

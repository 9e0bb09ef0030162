"""Cityscapes instance labels → detection records (:class:`fogsim.readers.base.Labels`).

Source: ``ROOT/gtFine/<split>/<city>/<stem>_gtFine_instanceIds.png`` (16-bit, the image's
size). Pixel values (official ``cityscapesscripts/helpers/labels.py``): for classes with
instances, ``classId·1000 + k`` (k = 0, 1, … in polygon order; the first car is 26000); groups
(``cargroup``, ``persongroup`` …) and every other class store the plain class id (< 1000).
Masks are the visible ones (later polygons overwrite earlier ones).

Detection classes: :data:`CITYSCAPES_CLASSES`, the 8 of the Foggy Cityscapes
domain-adaptation benchmark, in this order (YOLO id = index): person 24, rider 25, car 26,
truck 27, bus 28, train 31, motorcycle 32, bicycle 33.

Ignore regions (``kept = False``, COCO ``iscrowd = 1``, not in YOLO):

* the group pixels (value < 1000) of those 8 classes, one region per 8-connected component,
  category the group's own class (``cargroup`` → car), reason ``"group (cargroup)"``;
* ``caravan`` (29) and ``trailer`` (30) instances and groups (``ignoreInEval`` in Cityscapes),
  category car (caravan) and truck (trailer), reason ``"ignored class (caravan)"``.

Boxes: the min/max of the mask pixels in fogsim's pixel-edge convention ``[x0, y0, x1 + 1,
y1 + 1)`` (:mod:`fogsim.boxes`), equal to maskrcnn-benchmark's converter; ``pixels`` = the
mask's pixel count.
``segmentation``: the mask itself (the instance's pixels; a group's: its component's) as COCO's
compressed RLE (:mod:`fogsim.rle`), which the dataset's COCO files carry.

Distance (``distance_m``): the median **ray** distance (metres, camera centre → surface) over
the instance's pixels with *valid* disparity (p > 0 in ``disparity/``; holes are excluded,
never hole-filled: filling would smear the background into small objects), from planar
Z = baseline·fx/d and the camera JSON's intrinsics (:func:`fogsim.camera.planar_to_ray`).
Fewer than ``min_valid_pixels`` valid pixels → ``None``, ``distance_source = "unknown"``.
No erosion against SGM edge fattening is applied.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fogsim.boxes import boxes_from_mask, median_distance
from fogsim.camera import disparity_to_depth, planar_to_ray
from fogsim.errors import InputError
from fogsim.io.depth_files import read_uint16_map
from fogsim.io.headers import image_header
from fogsim.readers.base import Labels
from fogsim.readers.cityscapes_files import read_cityscapes_disparity
from fogsim.rle import rle_encode

#: the 8 detection classes (YOLO id = index), Foggy Cityscapes' domain-adaptation convention
CITYSCAPES_CLASSES = ("person", "rider", "car", "truck", "bus", "train", "motorcycle", "bicycle")
#: official Cityscapes label ids of the detection classes
CLASS_OF_ID = {24: "person", 25: "rider", 26: "car", 27: "truck", 28: "bus", 31: "train",
               32: "motorcycle", 33: "bicycle"}
#: instance classes Cityscapes ignores in evaluation → ignore regions of this detection class
IGNORED_IDS = {29: ("caravan", "car"), 30: ("trailer", "truck")}
CLASS_INDEX = {name: i for i, name in enumerate(CITYSCAPES_CLASSES)}
DISTANCE_SOURCE = "valid disparity (median ray distance)"
MIN_VALID_PIXELS = 10
GT_SUFFIX = "_gtFine_instanceIds.png"


def instance_ids_path(root: str | Path, split: str, city: str, base: str) -> Path:
    """``ROOT/gtFine/<split>/<city>/<base>_gtFine_instanceIds.png`` (``base`` = city_seq_frame)."""
    return Path(root) / "gtFine" / split / city / f"{base}{GT_SUFFIX}"


def png_size(path: str | Path) -> tuple[int, int] | None:
    """(width, height) from a PNG's header (:func:`fogsim.io.headers.image_header`; 26 bytes read), None when it
    is no PNG."""
    try:
        with open(path, "rb") as f:
            header = image_header(f.read(26))
    except OSError:
        return None
    return (header.width, header.height) if header is not None and header.kind == "png" else None


def instance_records(ids: np.ndarray, ray: np.ndarray | None, min_valid_pixels: int = MIN_VALID_PIXELS,
                     source: str = "instanceIds") -> list[dict]:
    """Detection records of a Cityscapes instanceIds map (H×W integers) in the order: instances by
    id, then ignore regions (groups by class id and component, scanned in raster order).

    ``ray``: H×W ray distance in metres with NaN where the disparity is invalid (None: every
    distance unknown). Each record: ``id`` (the instanceIds value; groups: the class id),
    ``class``, ``class_id``, ``bbox``, ``pixels``, ``truncated``, ``kept``, ``reason``,
    ``distance_m``, ``distance_source``, ``valid_disparity_pixels``, ``segmentation`` (RLE)."""
    h, w = ids.shape
    ids = ids.astype(np.int64, copy=False)  # group labels 100000·k + class id pass 2³¹ at k ≈ 21,475
    if ray is not None and ray.shape != ids.shape:
        raise InputError(source, f"instanceIds is {w}×{h} but the disparity is {ray.shape[1]}×{ray.shape[0]}")
    cls = np.where(ids >= 1000, ids // 1000, ids)
    wanted = set(CLASS_OF_ID) | set(IGNORED_IDS)
    regions = np.where(np.isin(cls, list(wanted)), ids, 0)
    # group pixels (< 1000) get one label per 8-connected component: 100000·(k+1) + class id
    groups = []
    for cid in sorted(c for c in np.unique(regions[(regions > 0) & (regions < 1000)])):
        mask = regions == cid
        n, comp = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
        regions[mask] = 100000 * comp[mask].astype(np.int64) + int(cid)
        groups.extend(100000 * k + int(cid) for k in range(1, n))
    boxes = boxes_from_mask(regions)
    valid = np.isfinite(ray) if ray is not None else np.zeros(ids.shape, bool)
    labels, counts = np.unique(regions[valid & (regions > 0)], return_counts=True)
    n_valid = dict(zip(labels.tolist(), counts.tolist()))
    enough = [lab for lab in boxes if n_valid.get(lab, 0) >= min_valid_pixels]
    dist = median_distance(regions, ray, enough) if ray is not None and enough else {}
    records = []
    for label in [lab for lab in sorted(boxes) if lab < 100000] + groups:
        cid = label % 100000 if label >= 100000 else (label // 1000 if label >= 1000 else label)
        if cid in CLASS_OF_ID:
            name = CLASS_OF_ID[cid]
            reason = f"group ({name}group)" if label >= 100000 else None
        else:
            ignored, name = IGNORED_IDS[cid]
            reason = f"ignored class ({ignored})"
        box = boxes[label]
        x0, y0, x1, y1 = box["bbox"]
        inside = np.zeros((h, w), bool)  # the mask, built in its box
        inside[y0:y1, x0:x1] = regions[y0:y1, x0:x1] == label
        d = dist.get(label, float("nan"))
        known = np.isfinite(d)
        records.append({"id": int(cid if label >= 100000 else label), "class": name, "class_id": CLASS_INDEX[name],
                        "bbox": box["bbox"], "pixels": box["pixels"],
                        "truncated": x0 == 0 or y0 == 0 or x1 == w or y1 == h,
                        "kept": reason is None, "reason": reason,
                        "distance_m": round(float(d), 3) if known else None,
                        "distance_source": DISTANCE_SOURCE if known else "unknown",
                        "valid_disparity_pixels": int(n_valid.get(label, 0)), "segmentation": rle_encode(inside)})
    return records


@dataclass(frozen=True)
class CityscapesLabels:
    """A picklable :data:`fogsim.readers.base.LabelReader` of one Cityscapes image: reads its
    instanceIds, checks its size against the image and the disparity, and returns
    :class:`Labels` of :data:`CITYSCAPES_CLASSES` (see the module docstring)."""

    instance_ids: str
    image: str
    disparity: str
    camera: str
    min_valid_pixels: int = MIN_VALID_PIXELS
    classes: tuple[str, ...] = CITYSCAPES_CLASSES

    @property
    def source(self) -> str:
        """The label file, named in messages about these labels."""
        return self.instance_ids

    def __call__(self) -> Labels:
        path = Path(self.instance_ids)
        if not path.is_file():
            raise InputError(path, "missing Cityscapes instance labels (gtFine *_gtFine_instanceIds.png) of "
                                   f"{self.image}; pass --no-labels to fog without labels")
        ids = read_uint16_map(path)
        size = png_size(self.image)
        if size is not None and size != (ids.shape[1], ids.shape[0]):
            raise InputError(path, f"instanceIds is {ids.shape[1]}×{ids.shape[0]} but the image {self.image} "
                                   f"is {size[0]}×{size[1]}")
        disparity, camera = read_cityscapes_disparity(self.disparity, self.camera)
        if disparity.shape != ids.shape:
            raise InputError(self.disparity, f"disparity is {disparity.shape[1]}×{disparity.shape[0]} but the "
                                             f"instanceIds {path} is {ids.shape[1]}×{ids.shape[0]}")
        depth = disparity_to_depth(disparity, camera.baseline, camera.intrinsics.fx)
        depth[disparity <= 0] = np.nan  # holes are excluded from the median, never filled
        ray = planar_to_ray(depth, camera.intrinsics)
        return Labels(self.classes, instance_records(ids, ray, self.min_valid_pixels, str(path)))

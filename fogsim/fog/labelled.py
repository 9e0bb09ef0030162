"""The annotations of a labelled ``fogsim fog`` run: the checks a real dataset's labels pass
before they are written (class list, box inside the image, distance in metres), and the
run-wide checks and the split rule of a labelled run. Boxes are ``[x0, y0, x1, y1)`` in
pixel-edge coordinates (:class:`fogsim.readers.base.Labels`); a box within
:data:`BOX_TOLERANCE_PX` of the image is clamped, a box farther out is an error naming the label
file.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from fogsim.dataset.layout import frames_from_keys
from fogsim.errors import InputError
from fogsim.fog.depth_input import SetupError
from fogsim.readers.base import Labels, Sample

#: how far (pixels) a label box may lie outside the image and still be clamped into it
BOX_TOLERANCE_PX = 1.0
#: how the train/val split of a labelled run groups frames (``fogsim fog --split-by``): by frame,
#: or by the sample key's folder (:func:`key_folder`)
SPLIT_BY = ("frame", "folder")


def key_folder(key: str) -> str:
    """The folder of a sample key (its parent path: Waymo ``ctx/ts_CAM`` → the segment ``ctx``;
    Cityscapes ``leftImg8bit/val/<city>/<name>`` → ``leftImg8bit/val/<city>``; "" at the top)."""
    return key.rpartition("/")[0]


def labels_source(sample: Sample) -> str:
    """What to name for a sample's labels: its reader's ``source`` attribute (the label file),
    else the sample's source."""
    return str(getattr(sample.labels, "source", None) or sample.source)


def checked_records(sample: Sample, classes: Sequence[str], min_pixels: int, width: int, height: int) -> list[dict]:
    """The sample's annotations (its label reader runs here), checked against the run's class
    list ``classes`` and the image size ``width`` × ``height``: boxes more than
    :data:`BOX_TOLERANCE_PX` outside the image are an :class:`InputError`, boxes within it are
    clamped. Kept records below ``min_pixels`` pixels become ignore regions (reason
    ``"too few pixels"``). Returns copies."""
    where = labels_source(sample)
    if sample.labels is None:
        raise InputError(sample.source, "has no labels, but this run writes a labelled dataset")
    labels = sample.labels()
    if not isinstance(labels, Labels):
        raise InputError(where, f"the label reader returned {type(labels).__name__}, not Labels")
    classes = tuple(classes)
    if tuple(labels.classes) != classes:
        raise InputError(where, f"labels of classes {list(labels.classes)}, but the run's class list is "
                                f"{list(classes)}")
    out = []
    for n, obj in enumerate(labels.objects):
        rec = dict(obj)
        name, cid = rec.get("class"), rec.get("class_id")
        if name not in classes or cid != classes.index(name):
            raise InputError(where, f"annotation {n}: class {name!r} with id {cid!r} is not in the class list "
                                    f"{list(classes)} (the id must be the index)")
        try:
            x0, y0, x1, y1 = (float(v) for v in rec["bbox"])
        except (KeyError, TypeError, ValueError):
            raise InputError(where, f"annotation {n}: bbox must be [x0, y0, x1, y1], got {rec.get('bbox')!r}") from None
        tol = BOX_TOLERANCE_PX
        if not (x0 >= -tol and y0 >= -tol and x1 <= width + tol and y1 <= height + tol and x0 <= x1 and y0 <= y1):
            raise InputError(where, f"annotation {n}: box {rec['bbox']} lies outside the {width}×{height} image "
                                    f"{sample.source} (labels and image of other sizes?)")
        box = [min(max(v, 0), lim) for v, lim in zip(rec["bbox"], (width, height, width, height))]
        rec["bbox"] = box
        rec.setdefault("pixels", (box[2] - box[0]) * (box[3] - box[1]))
        rec["kept"] = bool(rec.get("kept", True))
        rec.setdefault("reason", None)
        d = rec.get("distance_m")
        if d is not None and not (isinstance(d, (int, float)) and np.isfinite(d) and d >= 0):
            raise InputError(where, f"annotation {n}: distance_m must be a distance in metres or None, got {d!r}")
        rec.setdefault("distance_m", None)
        rec.setdefault("distance_source", "unknown")
        if rec["kept"] and rec["pixels"] < min_pixels:
            rec["kept"], rec["reason"] = False, f"too few pixels (< {min_pixels})"
        out.append(rec)
    return out


def check_labelled(samples: list[Sample], image_format: str = "png") -> None:
    """A labelled run: every sample has labels, frame names are distinct, images are PNG."""
    if image_format != "png":
        raise SetupError(samples[0].source if samples else "--format",
                         "a labelled dataset holds PNG images (images/<level>/<frame>.png): drop --format jpg, "
                         "or pass --no-labels")
    unlabelled = [s for s in samples if s.labels is None]
    if unlabelled:
        raise SetupError(unlabelled[0].source, f"has no labels while other samples have ({len(unlabelled)} "
                                               "without): pass --no-labels to fog the images alone")
    try:
        frames_from_keys([s.key for s in samples], [s.source for s in samples])
    except InputError as exc:
        raise SetupError(exc.source, exc.problem) from None


def sample_classes(samples: list[Sample]) -> tuple[str, ...]:
    """The class list of a labelled run: the first label reader's ``classes`` attribute, else
    the ``classes`` of the first sample's :class:`Labels` (read here, once)."""
    first = next(s for s in samples if s.labels is not None)
    classes = getattr(first.labels, "classes", None)
    if classes is None:
        labels = first.labels()
        if not isinstance(labels, Labels):
            raise InputError(labels_source(first), f"the label reader returned {type(labels).__name__}, not Labels")
        classes = labels.classes
    classes = tuple(classes)
    if not classes or len(set(classes)) != len(classes) or not all(isinstance(c, str) and c for c in classes):
        raise SetupError(labels_source(first), f"a dataset's class list holds distinct names, got {list(classes)}")
    return classes

"""Boxes: from an instance mask, and between every box format fogsim reads or writes.

The one home of box conversions (as torchvision's ``box_convert``). Coordinates are
*pixel-edge*: pixel column c spans [c, c + 1), so a box ``[x0, y0, x1, y1)`` has x1 = last
column + 1 and a single pixel at column 5 has x0 = 5, x1 = 6; width = x1 − x0.

Formats:

* ``xyxy`` — ``[x0, y0, x1, y1]``, pixels (the mask boxes and Ultralytics' ``boxes.xyxy``).
* ``xywh`` — ``[x0, y0, w, h]``, pixels: COCO's ``bbox``.
* ``cxcywh`` — ``[cx, cy, w, h]``, the centre and size; YOLO lines hold it normalised by the
  image width and height: ``"cls cx cy w h"``, 6 decimals, so rounding back recovers the
  integer box exactly (for images under 600 000 pixels a side).
* COCO category id = YOLO class id + 1 (COCO ids start at 1; 0 is the background for most
  COCO consumers).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BOX_FORMATS = ("xyxy", "xywh", "cxcywh")


# ----------------------------------------------------------------------------- mask → boxes
@dataclass(frozen=True)
class MaskRuns:
    """An H×W instance mask as its horizontal runs of equal non-zero ids, grouped by id (raster
    order within an id): built once (:meth:`of`), it gives every id's box (:meth:`boxes`) and
    median distance (:meth:`median_distance`) at a cost that does not grow with the number of ids."""

    id: np.ndarray      # id of each run
    start: np.ndarray   # flat index of its first pixel
    length: np.ndarray  # its length in pixels
    ids: np.ndarray     # the distinct ids, ascending
    first: np.ndarray   # index of each id's first run
    width: int          # the mask's width in pixels

    @classmethod
    def of(cls, mask: np.ndarray) -> "MaskRuns":
        if mask.ndim != 2:
            raise ValueError(f"an instance mask is 2-D, got shape {mask.shape}")
        w = mask.shape[1]
        flat = np.ascontiguousarray(mask).ravel()
        change = np.empty(flat.size, bool)
        change[:1] = True
        np.not_equal(flat[1:], flat[:-1], out=change[1:])
        change[::w] = True  # every row starts a run, so no run crosses a row end
        start = np.flatnonzero(change)
        length = np.diff(np.append(start, flat.size))
        run_id = flat[start]
        fg = run_id > 0
        run_id, start, length = run_id[fg], start[fg], length[fg]
        order = np.argsort(run_id, kind="stable")
        run_id, start, length = run_id[order], start[order], length[order]
        ids, first = np.unique(run_id, return_index=True)
        return cls(run_id, start, length, ids, first, w)

    def pixel_index(self, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flat indices of the pixels of the ``wanted`` ids (all present), grouped by id, and the
        group bounds: id k's pixels are ``idx[bounds[k]:bounds[k + 1]]``."""
        sel = np.isin(self.id, wanted)
        start, length = self.start[sel], self.length[sel]
        offsets = np.cumsum(length) - length
        idx = np.repeat(start - offsets, length) + np.arange(length.sum())
        run_id = self.id[sel]
        _, group_start = np.unique(run_id, return_index=True)
        bounds = np.append(offsets[group_start], idx.size)
        return idx, bounds

    def boxes(self) -> dict[int, dict]:
        """:func:`boxes_from_mask` of the mask."""
        if not self.ids.size:
            return {}
        row, x0 = np.divmod(self.start, self.width)
        x1 = x0 + self.length
        last = np.append(self.first[1:], self.id.size) - 1
        bx0 = np.minimum.reduceat(x0, self.first)
        bx1 = np.maximum.reduceat(x1, self.first)
        pixels = np.add.reduceat(self.length, self.first)
        y0, y1 = row[self.first], row[last] + 1  # runs are in raster order within an id
        return {int(i): {"bbox": [int(a), int(b), int(c), int(d)], "pixels": int(n)}
                for i, a, b, c, d, n in zip(self.ids, bx0, y0, bx1, y1, pixels)}

    def median_distance(self, ray_distance: np.ndarray, ids) -> dict[int, float]:
        """:func:`median_distance` of the mask."""
        wanted = np.asarray(sorted(set(int(i) for i in ids)), dtype=np.int64)
        out = {int(i): float("nan") for i in wanted}
        present = wanted[np.isin(wanted, self.ids)]
        if not present.size:
            return out
        idx, bounds = self.pixel_index(present)
        values = np.ascontiguousarray(ray_distance).ravel()[idx]
        for i, a, b in zip(present, bounds[:-1], bounds[1:]):
            v = values[a:b]
            v = v[np.isfinite(v)]
            if v.size:
                out[int(i)] = float(np.median(v))
        return out


def boxes_from_mask(mask: np.ndarray) -> dict[int, dict]:
    """``{id: {"bbox": [x0, y0, x1, y1], "pixels": n}}`` (pixel-edge xyxy) for every id > 0 of
    an H×W instance mask (0 = background).

    Works on the horizontal runs of the mask (one pass over the pixels), so its cost
    does not grow with the number of ids.
    """
    return MaskRuns.of(mask).boxes()


def median_distance(mask: np.ndarray, ray_distance: np.ndarray, ids) -> dict[int, float]:
    """Median ray distance (metres) over each id's pixels, ignoring non-finite values.

    Ids absent from the mask, or with no finite distance, map to NaN.
    """
    return MaskRuns.of(mask).median_distance(ray_distance, ids)


# ----------------------------------------------------------------------------- formats
def box_convert(boxes: np.ndarray, in_fmt: str, out_fmt: str) -> np.ndarray:
    """N×4 boxes from one of :data:`BOX_FORMATS` to another (float arrays; torchvision's
    ``box_convert`` without its torch)."""
    for fmt in (in_fmt, out_fmt):
        if fmt not in BOX_FORMATS:
            raise ValueError(f"box format must be one of {', '.join(BOX_FORMATS)}, got {fmt!r}")
    b = np.asarray(boxes)
    if in_fmt == out_fmt:
        return b.copy()
    if in_fmt == "xywh":
        xyxy = np.stack([b[:, 0], b[:, 1], b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]], axis=1)
    elif in_fmt == "cxcywh":
        xyxy = np.stack([b[:, 0] - b[:, 2] / 2, b[:, 1] - b[:, 3] / 2,
                         b[:, 0] + b[:, 2] / 2, b[:, 1] + b[:, 3] / 2], axis=1)
    else:
        xyxy = b
    if out_fmt == "xyxy":
        return xyxy
    if out_fmt == "xywh":
        return np.stack([xyxy[:, 0], xyxy[:, 1], xyxy[:, 2] - xyxy[:, 0], xyxy[:, 3] - xyxy[:, 1]], axis=1)
    return np.stack([(xyxy[:, 0] + xyxy[:, 2]) / 2, (xyxy[:, 1] + xyxy[:, 3]) / 2,
                     xyxy[:, 2] - xyxy[:, 0], xyxy[:, 3] - xyxy[:, 1]], axis=1)


def xyxy_to_xywh(box) -> list:
    """``[x0, y0, x1, y1]`` → COCO's ``[x0, y0, w, h]`` (same number types, pixel edges)."""
    x0, y0, x1, y1 = box
    return [x0, y0, x1 - x0, y1 - y0]


def yolo_line(record: dict, width: int, height: int) -> str:
    """``"cls cx cy w h"`` of ``record["class_id"]`` and its pixel-edge ``record["bbox"]``
    (xyxy): the box centre and size normalised by the image size, 6 decimals."""
    x0, y0, x1, y1 = record["bbox"]
    return (f"{record['class_id']} {(x0 + x1) / 2 / width:.6f} {(y0 + y1) / 2 / height:.6f} "
            f"{(x1 - x0) / width:.6f} {(y1 - y0) / height:.6f}")


def yolo_to_xyxy(cx: float, cy: float, w: float, h: float, width: int, height: int) -> list[float]:
    """Normalised YOLO centre/size → pixel-edge ``[x0, y0, x1, y1]``, in float pixels."""
    return [(cx - w / 2) * width, (cy - h / 2) * height, (cx + w / 2) * width, (cy + h / 2) * height]


def yolo_to_xywh(cx: float, cy: float, w: float, h: float, width: int, height: int) -> list[float]:
    """Normalised YOLO centre/size → COCO ``[x0, y0, w, h]`` in float pixels (the size is scaled
    directly, not taken as x1 − x0, so no rounding error enters it)."""
    return [(cx - w / 2) * width, (cy - h / 2) * height, w * width, h * height]


def parse_yolo_line(line: str, width: int, height: int) -> tuple[int, list[int]]:
    """Inverse of :func:`yolo_line`: ``(class_id, [x0, y0, x1, y1])`` in whole pixels."""
    fields = line.split()
    if len(fields) != 5:
        raise ValueError(f"a YOLO box line has 5 fields (cls cx cy w h), got {line!r}")
    cx, cy, bw, bh = (float(f) for f in fields[1:])
    return int(fields[0]), [round(v) for v in yolo_to_xyxy(cx, cy, bw, bh, width, height)]


def coco_category(class_id: int) -> int:
    """COCO category id of a YOLO class id: one more (COCO ids start at 1)."""
    return class_id + 1

"""COCO's run-length encoding of binary masks (the ``segmentation`` of an annotation), written from the
format's definition so the core needs no pycocotools.

A mask H×W is read **column-major** (down the first column, then the next: Fortran order); its run
lengths alternate 0-runs and 1-runs, starting with a 0-run (of length 0 when the first pixel is set);
an empty mask is one run ``[H·W]``. The compressed form (pycocotools' ``rleToString``) writes each run
length — from the fourth on, as the difference to the run two before — in 5-bit groups, least
significant first, as characters ``48 + group`` with bit 6 (``| 0x20``) set while more groups follow; a
group's bit 5 (``0x10``) is the sign, so a negative difference ends on ``-1`` instead of ``0``. The
record is ``{"size": [H, W], "counts": "<string>"}``: what ``pycocotools.mask.encode`` returns (its
``counts`` as ``bytes``), what ``annToMask`` and ``COCOeval(iouType="segm")`` read, ``iscrowd`` or not.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["box_counts", "box_mask", "box_rle", "rle_counts", "rle_encode", "rle_encode_box", "rle_string"]


def rle_counts(mask: np.ndarray) -> list[int]:
    """The run lengths of a 2-D mask (non-zero = set), column-major, starting with a 0-run."""
    mask = np.asarray(mask).astype(bool, copy=False)
    h, w = mask.shape
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return [h * w]
    return box_counts(mask[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1], int(rows[0]), int(cols[0]), h, w)


def box_counts(crop: np.ndarray, top: int, left: int, height: int, width: int) -> list[int]:
    """:func:`rle_counts` of a ``height`` × ``width`` mask that is clear outside ``crop`` (its pixels from row
    ``top``, column ``left``): the cost grows with the crop, not the image."""
    crop = np.asarray(crop).astype(bool, copy=False)
    ch, cw = crop.shape
    if not (0 <= top and top + ch <= height and 0 <= left and left + cw <= width):
        raise ValueError(f"a {ch}×{cw} crop at row {top}, column {left} is not inside a {height}×{width} mask")
    # a clear row above and below each column of the crop, so no run crosses into the next column
    pad = np.zeros((ch + 2, cw), np.int8)
    pad[1:-1] = crop
    step = np.diff(pad.ravel(order="F"))
    q_start, q_end = np.flatnonzero(step == 1) + 1, np.flatnonzero(step == -1) + 1  # in the padded crop
    if not len(q_start):
        return [height * width]

    def full(q):  # a padded-crop index → the mask's column-major index
        return (left + q // (ch + 2)) * height + top + q % (ch + 2) - 1

    start, end = full(q_start), full(q_end)
    joined = end[:-1] == start[1:]  # a column's run that reaches its last row and goes on at the next's first
    start, end = start[np.r_[True, ~joined]], end[np.r_[~joined, True]]
    edges = np.empty(2 * len(start), np.int64)
    edges[0::2], edges[1::2] = start, end  # alternately: a 1-run starts, it ends (exclusive)
    counts = np.diff(np.concatenate(([0], edges, [height * width]))).tolist()
    return counts[:-1] if counts[-1] == 0 else counts  # the mask ends in a 1-run: no empty 0-run after it


def rle_string(counts: list[int]) -> str:
    """The compressed string of run lengths (pycocotools' ``rleToString``, the module docstring)."""
    out = []
    for i, x in enumerate(counts):
        x = int(x) - (int(counts[i - 2]) if i > 2 else 0)
        more = True
        while more:
            c = x & 0x1F
            x >>= 5  # arithmetic: a negative difference reaches -1
            more = x != -1 if c & 0x10 else x != 0
            out.append(chr(48 + (c | 0x20 if more else c)))
    return "".join(out)


def rle_encode(mask: np.ndarray) -> dict:
    """The COCO RLE record ``{"size": [H, W], "counts": str}`` of an H×W mask (non-zero = set)."""
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"a mask is H×W, got shape {mask.shape}")
    return {"size": [int(mask.shape[0]), int(mask.shape[1])], "counts": rle_string(rle_counts(mask))}


def rle_encode_box(crop: np.ndarray, top: int, left: int, height: int, width: int) -> dict:
    """:func:`rle_encode` of a ``height`` × ``width`` mask that is clear outside ``crop`` (:func:`box_counts`)."""
    return {"size": [int(height), int(width)], "counts": rle_string(box_counts(crop, top, left, height, width))}


def box_mask(bbox, height: int, width: int) -> np.ndarray:
    """The H×W mask of a box ``[x0, y0, x1, y1)`` in pixel-edge coordinates (:mod:`fogsim.boxes`):
    the pixels whose centres lie in it (an integer box: exactly its columns x0 … x1 − 1 and rows
    y0 … y1 − 1), clipped to the image."""
    x0, y0, x1, y1 = (float(v) for v in bbox)
    c0, c1 = (min(max(math.ceil(v - 0.5), 0), width) for v in (x0, x1))
    r0, r1 = (min(max(math.ceil(v - 0.5), 0), height) for v in (y0, y1))
    mask = np.zeros((height, width), bool)
    mask[r0:r1, c0:c1] = True
    return mask


def box_rle(bbox, height: int, width: int) -> dict:
    """The COCO RLE record of a box's pixels (:func:`box_mask`): an ignore region that is a box."""
    return rle_encode(box_mask(bbox, height, width))

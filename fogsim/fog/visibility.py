"""What fog does to each object: its transmission, its measured contrast, and whether it is visible.

Per object and fog level (β in 1/m):

* ``transmission`` t = exp(−β·d), d = the record's ``distance_m`` (ray distance, metres);
  None when the distance is unknown.
* ``contrast`` C = |L_obj − L_bg| / max(L_bg, :data:`LUMINANCE_FLOOR`) — Weber contrast of the
  object against its surround in the fogged image. L is relative luminance in *linear light*
  (:func:`fogsim.colour.srgb_luminance`: sRGB decoded, Rec. 709 weights, white = 1), averaged
  (mean) over a region:

  - **mask-based** (``method = "mask"``, when an instance mask holds the record's ``id``):
    L_obj over the object's pixels eroded by ``gap_px`` (a 3×3 square step per pixel, so the
    anti-aliased edge pixels are left out; the whole object when erosion leaves nothing);
    L_bg over the ring of pixels at Chebyshev distance ``gap_px`` < r ≤ ``gap_px + ring_px``
    from the object (every pixel there that is not the object itself: road, sky, other objects
    — whatever the eye sees around it).
  - **box-based** (``method = "box"``, where only boxes exist): L_obj over the box
    ``[x0, y0, x1, y1)`` shrunk by ``gap_px`` on each side (the whole box when that is
    empty), L_bg over the ring of width ``ring_px`` outside the box grown by ``gap_px``,
    clipped to the image. The box interior holds background too, so C is an underestimate
    for thin or non-rectangular objects.

  None when either region is empty (e.g. an object filling the image).
* ``contrast_clear`` C0: the same measure in the clear image, so C/C0 can be set against t.
  For an object seen against the horizon sky (L_bg = A) Koschmieder's law in linear light
  gives exactly C/C0 = t; against a background at the object's own distance it gives
  C/C0 = t·L_bg / (t·L_bg + A(1 − t)) < t.
* ``visible``: C ≥ ``threshold`` (default 0.05). This is the threshold that defines the
  meteorological visibility V = ln(20)/β: the distance at which a black object's contrast
  against the horizon sky falls to 5 %. None when C is None.

Records are the render's (``meta["objects"]``) or a real dataset's
(:class:`fogsim.readers.base.Labels`): ``bbox`` ``[x0, y0, x1, y1)`` pixel-edge, ``distance_m``
(None = unknown) and, for the mask method, an integer ``id`` of the instance mask. Which of these
fields reach the COCO files: :func:`fogsim.dataset.coco.visibility_fields`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from fogsim.colour import srgb_luminance

#: Contrast at which an object is no longer seen (meteorological visibility: V = ln(20)/β).
VISIBLE_CONTRAST = 0.05
#: the rule in words, as reports and help texts say it ("contrast < 5 %")
INVISIBLE_RULE = f"contrast < {VISIBLE_CONTRAST * 100:g} %"
#: Lower bound on the surround luminance in the Weber denominator (linear light, white = 1),
#: so a black surround gives a large but finite contrast.
LUMINANCE_FLOOR = 1e-3
RING_PX = 3
GAP_PX = 1


@dataclass(frozen=True)
class Region:
    """An object's interior and its surrounding ring, as boolean maps over ``window`` (a crop)."""

    window: tuple[slice, slice]
    interior: np.ndarray
    ring: np.ndarray
    method: str

    def contrast(self, lum: np.ndarray) -> float | None:
        """Weber contrast |L_obj − L_bg| / max(L_bg, floor) on a luminance map (None: empty region)."""
        crop = lum[self.window]
        if not self.interior.any() or not self.ring.any():
            return None
        l_obj, l_bg = float(crop[self.interior].mean()), float(crop[self.ring].mean())
        return abs(l_obj - l_bg) / max(l_bg, LUMINANCE_FLOOR)


def _window(x0: int, y0: int, x1: int, y1: int, pad: int, h: int, w: int) -> tuple[slice, slice]:
    return slice(max(0, y0 - pad), min(h, y1 + pad)), slice(max(0, x0 - pad), min(w, x1 + pad))


def _square(radius: int) -> np.ndarray:
    return np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)


def mask_region(mask: np.ndarray, oid: int, bbox, ring_px: int = RING_PX, gap_px: int = GAP_PX) -> Region:
    """The mask-based region of object ``oid`` (``bbox`` = its mask box, to crop the work)."""
    h, w = mask.shape
    x0, y0, x1, y1 = (int(round(v)) for v in bbox)
    win = _window(x0, y0, x1, y1, ring_px + gap_px + 1, h, w)
    obj = (mask[win] == oid).astype(np.uint8)
    interior = cv2.erode(obj, _square(gap_px), borderType=cv2.BORDER_REPLICATE) if gap_px else obj
    if not interior.any():
        interior = obj
    # pixels beyond the image are not part of the object, so dilation pads with 0
    near = cv2.dilate(obj, _square(gap_px), borderType=cv2.BORDER_CONSTANT, borderValue=0) if gap_px else obj
    far = cv2.dilate(obj, _square(gap_px + ring_px), borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return Region(win, interior.astype(bool), far.astype(bool) & ~near.astype(bool), "mask")


def box_region(bbox, shape: tuple[int, int], ring_px: int = RING_PX, gap_px: int = GAP_PX) -> Region:
    """The box-based region of a ``[x0, y0, x1, y1)`` box (rounded to whole pixels) in an image of ``shape``."""
    h, w = shape
    x0, y0, x1, y1 = (int(round(v)) for v in bbox)
    x0, y0, x1, y1 = max(0, x0), max(0, y0), min(w, x1), min(h, y1)
    win = _window(x0, y0, x1, y1, ring_px + gap_px, h, w)
    oy, ox = win[0].start, win[1].start
    ch, cw = win[0].stop - oy, win[1].stop - ox
    yy, xx = np.mgrid[oy:oy + ch, ox:ox + cw]

    def inside(pad: int) -> np.ndarray:
        return (xx >= x0 - pad) & (xx < x1 + pad) & (yy >= y0 - pad) & (yy < y1 + pad)

    box = inside(0)
    interior = inside(-gap_px)
    if not interior.any():
        interior = box
    return Region(win, interior, inside(gap_px + ring_px) & ~inside(gap_px), "box")


def object_regions(records: list[dict], shape: tuple[int, int], mask: np.ndarray | None = None,
                   ring_px: int = RING_PX, gap_px: int = GAP_PX) -> list[Region]:
    """One region per record: mask-based where ``mask`` holds the record's integer ``id``, else box-based."""
    present = set()
    if mask is not None:  # the ids in the mask (a count per value is quicker than sorting for uint masks)
        ids = np.flatnonzero(np.bincount(mask.ravel())) if mask.dtype.kind == "u" else np.unique(mask)
        present = set(ids.tolist())
    out = []
    for rec in records:
        oid = rec.get("id")
        if mask is not None and isinstance(oid, (int, np.integer)) and not isinstance(oid, bool) and oid in present:
            out.append(mask_region(mask, int(oid), rec["bbox"], ring_px, gap_px))
        else:
            out.append(box_region(rec["bbox"], shape, ring_px, gap_px))
    return out


def transmission_at(distance_m, beta: float) -> float | None:
    """exp(−β·d) for one distance in metres (None or non-finite = unknown → None; β = 0 → 1)."""
    if distance_m is None or not math.isfinite(float(distance_m)):
        return None
    if beta == 0:
        return 1.0
    return math.exp(-beta * float(distance_m))


def _round(v, digits: int = 5):
    return None if v is None else round(float(v), digits)


def _check_image(image: np.ndarray, what: str) -> None:
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"{what} must be H×W×3 RGB, got shape {image.shape}")


def frame_visibility(clear: np.ndarray, foggy: dict[str, np.ndarray], betas: dict[str, float],
                     records: list[dict], mask: np.ndarray | None = None,
                     threshold: float = VISIBLE_CONTRAST, ring_px: int = RING_PX,
                     gap_px: int = GAP_PX) -> list[dict[str, dict]]:
    """Per record, ``{level key: visibility}`` for every fogged image of one frame.

    ``clear``: the clear image (sRGB-encoded, uint8/uint16/float 0–1, H×W×3); ``foggy``: level
    key → fogged image of the same size (a β = 0 level may be the clear image itself);
    ``betas``: level key → β (1/m); ``mask``: instance mask (H×W, 0 = background) or None for
    box-based regions. Each visibility is ``{"transmission", "contrast", "contrast_clear",
    "visible", "method"}`` (see the module docstring); the regions and C0 are computed once.
    """
    _check_image(clear, "the clear image")
    h, w = clear.shape[:2]
    if mask is not None and mask.shape != (h, w):
        raise ValueError(f"mask is {mask.shape[1]}×{mask.shape[0]} but the image is {w}×{h}")
    regions = object_regions(records, (h, w), mask, ring_px, gap_px)
    lum_clear = srgb_luminance(clear)
    c0 = [r.contrast(lum_clear) for r in regions]
    out: list[dict[str, dict]] = [{} for _ in records]
    for key, image in foggy.items():
        _check_image(image, f"fog level {key}")
        if image.shape[:2] != (h, w):
            raise ValueError(f"fog level {key} is {image.shape[1]}×{image.shape[0]} but the clear image is {w}×{h}")
        lum = srgb_luminance(image)
        for i, (rec, region) in enumerate(zip(records, regions)):
            c = region.contrast(lum)
            out[i][key] = {"transmission": _round(transmission_at(rec.get("distance_m"), betas[key])),
                           "contrast": _round(c), "contrast_clear": _round(c0[i]),
                           "visible": None if c is None else bool(c >= threshold), "method": region.method}
    return out


def object_visibility(image: np.ndarray, records: list[dict], beta: float, mask: np.ndarray | None = None,
                      threshold: float = VISIBLE_CONTRAST, clear: np.ndarray | None = None,
                      ring_px: int = RING_PX, gap_px: int = GAP_PX) -> list[dict]:
    """Visibility of every record in one fogged ``image`` at extinction ``beta`` (1/m).

    ``clear``: the clear image, for ``contrast_clear`` (None → ``contrast_clear`` is None).
    Returns one ``{"transmission", "contrast", "contrast_clear", "visible", "method"}`` per
    record, in order. For a real dataset's boxes pass ``mask=None`` (box-based).
    """
    base = image if clear is None else clear
    per = frame_visibility(base, {"_": image}, {"_": beta}, records, mask, threshold, ring_px, gap_px)
    out = [v["_"] for v in per]
    if clear is None:
        for v in out:
            v["contrast_clear"] = None
    return out


def attach_visibility(records: list[dict], clear: np.ndarray, foggy: dict[str, np.ndarray],
                      betas: dict[str, float], mask: np.ndarray | None = None, **kw) -> list[dict]:
    """Set ``record["visibility"] = {level key: {...}}`` on every record (in place; returns them).
    The one call the renderer's commit and a real dataset's fog batch make."""
    for rec, vis in zip(records, frame_visibility(clear, foggy, betas, records, mask, **kw)):
        rec["visibility"] = vis
    return records

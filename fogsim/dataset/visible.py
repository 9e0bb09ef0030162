"""Visible-only label sets: per fog level, the YOLO labels of the objects that level's fog leaves visible.

``labels/<level>/`` holds every kept object at every level — the clear scene's boxes, as the paper's
protocol and Foggy Cityscapes label a fogged image — so at β = 0.12 1/m most of its boxes are objects no
eye can see. Beside it, finalize writes the visible-only set of each level::

    visible/labels/<level>/<frame>.txt   the kept objects visible at that level (may be empty)
    visible/images/<level>/<frame>.png   hard links to images/<level>/ (no bytes copied where links work):
                                         Ultralytics finds a label by its image's path
    splits/<level>.visible_{train,val}.txt, data/<level>.visible.yaml   the same frames and split, and the
                                         mixed set ``all.visible``

The rule (:func:`visible_at`): at a foggy level (β > 0), a kept record whose ``visibility[<level>]["visible"]``
is not False — its Weber contrast in that level's image is ≥ 5 % (:mod:`fogsim.fog.visibility`; an unknown
visibility counts as visible, as in :func:`fogsim.detection.coco_eval.mark_invisible_ignored`); at a clear
level (β = 0) every kept record: fog hides nothing there, and the contrast of means can call an object whose
mean luminance matches its surroundings' (a white van before a white wall) invisible in clear air.
"""
from __future__ import annotations

from fogsim.boxes import yolo_line
from fogsim.dataset.layout import MIXED_SPLIT, DatasetLayout, visible_set
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.links import link_or_copy

__all__ = ["VISIBLE_RULE", "visible_at", "visible_counts", "write_visible_labels"]

#: the rule in words (``dataset.json``'s ``visible_labels.rule``)
VISIBLE_RULE = ("at a foggy level, a kept object whose contrast in that level's image is >= 5 % (meta "
                "visibility[<level>].visible; unknown counts as visible); at a clear level every kept object")


def visible_at(record: dict, level) -> bool:
    """True when ``record`` is a kept object visible at ``level`` (its ``key`` and ``beta``; the module's rule)."""
    if not record["kept"]:
        return False
    vis = (record.get("visibility") or {}).get(level.key) or {}
    return level.beta == 0 or vis.get("visible") is not False


def write_visible_labels(layout: DatasetLayout, levels, frames: list[str], metas: list[dict]) -> None:
    """Each level's visible-only labels and image links of ``frames`` (their checked ``metas``)."""
    for frame, meta in zip(frames, metas):
        w, h = meta["width"], meta["height"]
        for lv in levels:
            lines = "".join(yolo_line(r, w, h) + "\n" for r in meta["objects"] if visible_at(r, lv))
            atomic_write_bytes(layout.visible_label(lv.key, frame), lines.encode())
            link_or_copy(layout.image(lv.key, frame), layout.visible_image(lv.key, frame))


def visible_counts(levels, metas: list[dict]) -> dict:
    """``dataset.json``'s ``visible_labels``: the rule, and per level the boxes of ``labels/`` and of the
    visible-only set, and the data file to train on."""
    out = {}
    for lv in levels:
        kept = [r for m in metas for r in m["objects"] if r["kept"]]
        out[lv.key] = {"labels": len(kept), "visible": sum(visible_at(r, lv) for r in kept),
                       "data": f"data/{visible_set(lv.key)}.yaml"}
    return {"rule": VISIBLE_RULE, "mixed": f"data/{visible_set(MIXED_SPLIT)}.yaml", "levels": out}


def visible_line(summary: dict) -> str | None:
    """One line for people: each level's visible boxes of its labels (None when the dataset has none)."""
    block = summary.get("visible_labels")
    if not block:
        return None
    parts = [f"{key} {v['visible']}/{v['labels']}" for key, v in block["levels"].items()]
    return ("visible-only labels (visible/labels/, data/<level>.visible.yaml): " + ", ".join(parts)
            + " boxes of labels/ are visible")

"""A small fogsim dataset built without Blender: the analytic demo street with coloured boxes
("cars") at known distances, fogged at the paper's levels and written in fogsim's layout by the
same writer as the renderer (labels, COCO, split lists, data YAMLs, dataset.json)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fogsim.camera import planar_to_ray
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.writer import finalize, write_frame_labels
from fogsim.fog.levels import parse_levels
from fogsim.fog.model import Fogger
from fogsim.fog.synthetic import demo_scene
from fogsim.io.depth_files import write_depth
from fogsim.io.documents import write_json
from fogsim.io.images import write_image

COLOURS = ((200, 30, 30), (30, 160, 40), (40, 60, 200), (230, 200, 40))


def make_dataset(root: Path, frames: int = 10, width: int = 96, height: int = 64, seed: int = 0,
                 train_fraction: float = 0.8, depth: bool = False) -> Path:
    """``depth``: also write ``depth/<frame>.exr`` (planar Z) and the camera in the frame record,
    as the renderer does."""
    levels = parse_levels("paper")
    layout = DatasetLayout(root)
    rng = np.random.default_rng(seed)
    for i in range(frames):
        frame = f"{i:06d}"
        rgb, depth_map, K = demo_scene(rng, width, height)
        records = []
        for k in range(3):
            slot = width // 3  # one box per third of the width: no box hides another
            w, h = int(rng.integers(slot // 3, slot - 2)), int(rng.integers(height // 6, height // 3))
            x0, y0 = k * slot + int(rng.integers(0, slot - w)), int(rng.integers(height // 3, height - h))
            d = 140.0 if k == 2 else float(rng.choice([8.0, 30.0, 70.0]))  # each distance bin; one too far
            rgb[y0:y0 + h, x0:x0 + w] = COLOURS[k % len(COLOURS)]
            depth_map[y0:y0 + h, x0:x0 + w] = d
            records.append({"class": "car", "class_id": 0, "bbox": [x0, y0, x0 + w, y0 + h], "kept": True,
                            "pixels": w * h, "distance_m": d, "visible_fraction": 1.0, "truncation": 0.0})
        fogger = Fogger(rgb, planar_to_ray(depth_map, K))
        for lv in levels:
            write_image(layout.image(lv.key, frame), fogger(lv.beta))
        write_frame_labels(layout, frame, levels, records, width, height)
        meta = {"frame": frame, "width": width, "height": height, "objects": records}
        if depth:
            write_depth(layout.depth(frame), depth_map)
            meta |= {"camera": {"intrinsics": K.to_dict()},
                     "depth": {"file": layout.relative(layout.depth(frame)), "kind": "planar Z, metres"}}
        write_json(layout.meta(frame), meta)
    finalize(layout, levels, {"preset": "synthetic (tests)"}, train_fraction)
    return root


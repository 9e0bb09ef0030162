"""A render's LiDAR levels as SemanticKITTI sequences that SemanticKITTI's API (semantic-kitti-api) reads:

    OUT/semantic_kitti/<level>/sequences/00/velodyne/<frame>.bin   4 × float32 LE: x y z remission (0–1)
    OUT/semantic_kitti/<level>/sequences/00/labels/<frame>.label   uint32 LE per point: instance << 16 | class
    OUT/semantic_kitti/<level>/sequences/00/calib.txt              P0–P3 (the render's K | 0), Tr (LiDAR → camera)
    OUT/semantic_kitti/<level>/sequences/00/poses.txt              camera pose of frame i in frame 0's camera
    OUT/semantic_kitti/<level>/semantic-kitti.yaml                 labels, color_map, learning_map(_inv), …

Class ids are SemanticKITTI's own (its ``config/semantic-kitti.yaml``: 10 car, 30 person, 40 road …),
mapped from fogsim's classes by :data:`FOGSIM_TO_SEMANTIC_KITTI`. Fog clutter (a return from the fog's own
echo, :data:`fogsim.lidar.fog.CLUTTER`) is :data:`FOG_ID` = 110, an id SemanticKITTI leaves unused: WADS
(the winter adverse-weather LiDAR set published in SemanticKITTI's format) gives 110 to airborne falling
snow, the same kind of return — from particles in the air, not from a surface — so a filter or a model that
already treats 110 as weather clutter treats fog clutter alike. The yaml's ``learning_map`` is
SemanticKITTI's 19 training classes plus class 20 ``fog`` (an extra, not ignored: learning to spot fog
clutter is what a fogged set is for; remap 110 → 0 to train the 19 classes alone).

Per frame (written by the render's frame commit, before the frame's meta): the scan and its labels. Per
sequence (written at finalize from the committed frames' records, :func:`write_sequences`): ``calib.txt``,
``poses.txt`` (one line per frame, in sorted frame order — the order of the velodyne folder's listing, which
is how the API pairs them) and the yaml. ``calib.txt`` holds the first frame's calibration (a render's
camera and LiDAR mount are the same in every frame). Poses are the render's camera poses; frames of
independent scenes (the default render) each live in their own world, so aggregating scans over frames is
meaningful only for a moving-camera render of one scene.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from fogsim.dataset.layout import DatasetLayout
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.links import link_or_copy
from fogsim.lidar.formats import encode_points
from fogsim.lidar.points import PointCloud

__all__ = ["FOGSIM_TO_SEMANTIC_KITTI", "FOG_ID", "LABELS", "LEARNING_MAP", "LEARNING_MAP_INV", "SEQUENCE",
           "SEMANTIC_KITTI_DIR", "SemanticKittiTree", "label_yaml", "semantic_id", "write_sequences"]

SEMANTIC_KITTI_DIR = "semantic_kitti"
SEQUENCE = "00"
YAML_NAME = "semantic-kitti.yaml"
#: the id of fog clutter (see the module docstring for why 110)
FOG_ID = 110

#: SemanticKITTI's ids: name and colour (BGR, as its yaml), plus fogsim's fog class
LABELS: dict[int, tuple[str, tuple[int, int, int]]] = {
    0: ("unlabeled", (0, 0, 0)), 1: ("outlier", (0, 0, 255)), 10: ("car", (245, 150, 100)),
    11: ("bicycle", (245, 230, 100)), 13: ("bus", (250, 80, 100)), 15: ("motorcycle", (150, 60, 30)),
    16: ("on-rails", (255, 0, 0)), 18: ("truck", (180, 30, 80)), 20: ("other-vehicle", (255, 0, 0)),
    30: ("person", (30, 30, 255)), 31: ("bicyclist", (200, 40, 255)), 32: ("motorcyclist", (90, 30, 150)),
    40: ("road", (255, 0, 255)), 44: ("parking", (255, 150, 255)), 48: ("sidewalk", (75, 0, 75)),
    49: ("other-ground", (75, 0, 175)), 50: ("building", (0, 200, 255)), 51: ("fence", (50, 120, 255)),
    52: ("other-structure", (0, 150, 255)), 60: ("lane-marking", (170, 255, 150)),
    70: ("vegetation", (0, 175, 0)), 71: ("trunk", (0, 60, 135)), 72: ("terrain", (80, 240, 150)),
    80: ("pole", (150, 240, 255)), 81: ("traffic-sign", (0, 0, 255)), 99: ("other-object", (255, 255, 50)),
    FOG_ID: ("fog", (200, 200, 200)),
    252: ("moving-car", (245, 150, 100)), 253: ("moving-bicyclist", (200, 40, 255)),
    254: ("moving-person", (30, 30, 255)), 255: ("moving-motorcyclist", (90, 30, 150)),
    256: ("moving-on-rails", (255, 0, 0)), 257: ("moving-bus", (250, 80, 100)),
    258: ("moving-truck", (180, 30, 80)), 259: ("moving-other-vehicle", (255, 0, 0)),
}
#: SemanticKITTI's training classes (0 ignored) and fogsim's fog as class 20
LEARNING_NAMES = ("unlabeled", "car", "bicycle", "motorcycle", "truck", "other-vehicle", "person", "bicyclist",
                  "motorcyclist", "road", "parking", "sidewalk", "other-ground", "building", "fence", "vegetation",
                  "trunk", "terrain", "pole", "traffic-sign", "fog")
LEARNING_MAP_INV = {0: 0, 1: 10, 2: 11, 3: 15, 4: 18, 5: 20, 6: 30, 7: 31, 8: 32, 9: 40, 10: 44, 11: 48, 12: 49,
                    13: 50, 14: 51, 15: 70, 16: 71, 17: 72, 18: 80, 19: 81, 20: FOG_ID}
#: every id → its training class (SemanticKITTI's merges: bus, on-rails → other-vehicle; lane-marking → road;
#: outlier, other-structure, other-object → unlabeled; moving-* → their static class)
LEARNING_MAP = {**{v: k for k, v in LEARNING_MAP_INV.items()}, 1: 0, 13: 5, 16: 5, 52: 0, 60: 9, 99: 0, 252: 1,
                253: 7, 254: 6, 255: 8, 256: 5, 257: 5, 258: 4, 259: 5}
#: fogsim's classes (:mod:`fogsim.scene.classes`) → SemanticKITTI ids; a van is a car (SemanticKITTI's car
#: includes vans), a cyclist object (rider and bicycle, one instance) is a bicyclist, a traffic light is a
#: traffic-sign (SemanticKITTI has no traffic-light class), a curb belongs to the sidewalk, a tree is vegetation
FOGSIM_TO_SEMANTIC_KITTI = {"car": 10, "van": 10, "truck": 18, "bus": 13, "pedestrian": 30, "cyclist": 31,
                            "traffic_light": 81, "traffic_sign": 81, "road": 40, "lane_marking": 60,
                            "sidewalk": 48, "curb": 48, "building": 50, "pole": 80, "tree": 70, "fog": FOG_ID}


def semantic_id(cls: str | None) -> int:
    """The SemanticKITTI id of a fogsim class (0 unlabeled for anything else)."""
    return FOGSIM_TO_SEMANTIC_KITTI.get(cls or "", 0)


def label_yaml() -> str:
    """The yaml SemanticKITTI's API takes as ``--config``: its keys and layout (``labels``, ``color_map``
    BGR, ``content``, ``learning_map``, ``learning_map_inv``, ``learning_ignore``), fog included."""
    ids = sorted(LABELS)
    lines = ["# fogsim's SemanticKITTI label config: SemanticKITTI's own ids, plus 110 fog (fog-echo clutter)",
             'name: "fogsim"', "labels:"]
    lines += [f'  {i}: "{LABELS[i][0]}"' for i in ids]
    lines += ["color_map: # bgr"] + [f"  {i}: [{', '.join(str(c) for c in LABELS[i][1])}]" for i in ids]
    lines += ["content: # share of points: not measured (0 for every class)"] + [f"  {i}: 0.0" for i in ids]
    lines += ["learning_map:"] + [f"  {i}: {LEARNING_MAP[i]}  # {LABELS[i][0]} → {LEARNING_NAMES[LEARNING_MAP[i]]}"
                                  for i in ids]
    lines += ["learning_map_inv: # inverse of learning_map"]
    lines += [f"  {k}: {v}  # {LEARNING_NAMES[k]}" for k, v in sorted(LEARNING_MAP_INV.items())]
    lines += ["learning_ignore: # ignore unlabeled"]
    lines += [f"  {k}: {'True' if k == 0 else 'False'}  # {LEARNING_NAMES[k]}" for k in sorted(LEARNING_MAP_INV)]
    lines += ["split: # every frame of the render is in sequence 00", "  train: [0]", "  valid: [0]", "  test: []"]
    return "\n".join(lines) + "\n"


def _matrix_line(key: str, m) -> str:
    return f"{key}: " + " ".join(f"{float(v):.12e}" for v in np.asarray(m, np.float64)[:3, :4].reshape(-1))


class SemanticKittiTree:
    """One fog level's SemanticKITTI dataset root, ``OUT/semantic_kitti/<level>`` (the module docstring)."""

    def __init__(self, out: str | os.PathLike, level: str, sequence: str = SEQUENCE):
        self.root = Path(out) / SEMANTIC_KITTI_DIR / level
        self.sequence = self.root / "sequences" / sequence

    def scan(self, frame: str) -> Path:
        return self.sequence / "velodyne" / f"{frame}.bin"

    def labels(self, frame: str) -> Path:
        return self.sequence / "labels" / f"{frame}.label"

    def write_frame(self, frame: str, cloud: PointCloud, labels: np.ndarray, scan_file: Path | None = None) -> None:
        """The frame's scan (KITTI's 4 × float32, intensities through the 0–1 scale) and its labels (one
        uint32 per point), each atomically; the labels first. ``scan_file``: the level's scan already written
        in KITTI's format (the same bytes), linked instead of written again (:func:`fogsim.io.links.link_or_copy`)."""
        labels = np.asarray(labels, np.uint32)
        if labels.shape != (len(cloud),):
            raise ValueError(f"{labels.size} labels for {len(cloud)} points")
        atomic_write_bytes(self.labels(frame), labels.astype("<u4").tobytes())
        if scan_file is not None:
            link_or_copy(scan_file, self.scan(frame))
        else:
            atomic_write_bytes(self.scan(frame), encode_points(cloud, "kitti"))

    def write_sequence(self, P: np.ndarray, lidar_to_camera: np.ndarray, poses: list[np.ndarray]) -> None:
        """``calib.txt`` (P0–P3 = ``P``, Tr = ``lidar_to_camera``), ``poses.txt`` (one 3×4 per frame) and
        the yaml."""
        calib = [_matrix_line(f"P{i}", P) for i in range(4)] + [_matrix_line("Tr", lidar_to_camera)]
        atomic_write_bytes(self.sequence / "calib.txt", ("\n".join(calib) + "\n").encode())
        atomic_write_bytes(self.sequence / "poses.txt",
                           "".join(_matrix_line("", p)[2:] + "\n" for p in poses).encode())
        atomic_write_bytes(self.root / YAML_NAME, label_yaml().encode())


def write_sequences(layout: DatasetLayout, frames: list[str], metas: list[dict]) -> dict | None:
    """Each level's ``calib.txt``, ``poses.txt`` and yaml from the committed frames whose record has a
    ``lidar.semantic_kitti`` block (``{"levels": [...], "P": 3×4}``; the camera pose and the LiDAR → camera
    transform from ``camera.world_to_camera`` and ``lidar.lidar_to_camera``); None when no frame has one.
    Scans of frames without a record (a frame that failed after writing them) are named in the returned
    block's ``uncommitted_scans``: they shift the API's pairing of poses with scans (remove them, or render
    those frames again)."""
    done = [(f, m) for f, m in zip(frames, metas) if (m.get("lidar") or {}).get("semantic_kitti")]
    if not done:
        return None
    done.sort(key=lambda fm: fm[0])
    first = done[0][1]
    c2w = [np.linalg.inv(np.asarray(m["camera"]["world_to_camera"], np.float64)) for _, m in done]
    poses = [np.linalg.inv(c2w[0]) @ c for c in c2w]
    block = first["lidar"]["semantic_kitti"]
    levels = sorted({lv for _, m in done for lv in m["lidar"]["semantic_kitti"]["levels"]})
    names = {f for f, _ in done}
    out = {"root": f"{SEMANTIC_KITTI_DIR}/<level>", "sequence": SEQUENCE, "levels": levels, "frames": len(done),
           "config": YAML_NAME, "fog_id": FOG_ID}
    for level in levels:
        tree = SemanticKittiTree(layout.root, level)
        tree.write_sequence(np.asarray(block["P"], np.float64), np.asarray(first["lidar"]["lidar_to_camera"]), poses)
        stray = sorted(p.stem for p in (tree.sequence / "velodyne").glob("*.bin") if p.stem not in names)
        if stray:  # a frame that failed after its scans: the API pairs poses with the sorted listing
            out.setdefault("uncommitted_scans", {})[level] = stray
    return out

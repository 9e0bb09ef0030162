"""Meshes of scene objects in world coordinates, from their JSON description (no bpy).

Object record (an entry of ``scene["objects"]``)::

    {"id": 12, "class": "car", "asset": {"type": "car", "params": {...}, "materials": {...}},
     "transform": 4×4 local→world (list of lists)}

``asset.type`` is one of :data:`fogsim.scene.assets.ASSET_TYPES`, or ``"box"`` with
``params.size = [sx, sy, sz]`` (metres, resting on z = 0, centred in x and y), or ``"boxes"``
with ``params.boxes = [[cx, cy, z0, sx, sy, sz], …]`` (each resting on z0) — both with
``params.material``: the road, sidewalks, curbs and lane marks are boxes.
"""
from __future__ import annotations

import numpy as np
import trimesh


def local_parts(asset: dict) -> list[tuple[trimesh.Trimesh, str]]:
    """(mesh in the asset's local frame, material slot) pairs."""
    if asset["type"] == "box":
        return [(_box(0.0, 0.0, 0.0, *asset["params"]["size"]), asset["params"]["material"])]
    if asset["type"] == "boxes":
        boxes = [_box(*b) for b in asset["params"]["boxes"]]
        return [(trimesh.util.concatenate(boxes), asset["params"]["material"])]
    from .assets import build_asset

    return build_asset(asset)


def _box(cx: float, cy: float, z0: float, sx: float, sy: float, sz: float) -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=(sx, sy, sz))
    box.apply_translation((cx, cy, z0 + sz / 2.0))
    return box


def world_parts(obj: dict) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """(vertices N×3 world metres, faces F×3, material slot) per part of an object."""
    M = np.asarray(obj["transform"], dtype=np.float64)
    out = []
    for mesh, slot in local_parts(obj["asset"]):
        v = np.asarray(mesh.vertices, dtype=np.float64) @ M[:3, :3].T + M[:3, 3]
        out.append((v, np.asarray(mesh.faces, dtype=np.int64), slot))
    return out


def material_key(obj: dict, slot: str) -> tuple[str, tuple]:
    """Material identity: the catalogue slot plus this instance's colour override, if any."""
    override = obj["asset"].get("materials", {}).get(slot, {})
    return slot, tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in override.items()))

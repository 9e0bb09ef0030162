"""Meshes of scene objects in world coordinates, from their JSON description (no bpy).

Object record (an entry of ``scene["objects"]``)::

    {"id": 12, "class": "car", "asset": {"type": "car", "params": {...}, "materials": {...}},
     "transform": 4×4 local→world (list of lists)}

``asset.type`` is one of :data:`fogsim.scene.assets.ASSET_TYPES`, or ``"box"`` with
``params.size = [sx, sy, sz]`` (metres, resting on z = 0, centred in x and y), or ``"boxes"``
with ``params.boxes = [[cx, cy, z0, sx, sy, sz], …]`` (each resting on z0) — both with
``params.material``: the road, sidewalks, curbs and lane marks are boxes. ``"library"`` is one of
the user's models (:mod:`fogsim.scene.library`): its mesh comes from the run's asset library
(one part per material, slot ``"library:<material name>"``, or one ``"library"``; the renderer keeps the
model's own materials, the LiDAR maps them by name and kind).
"""
from __future__ import annotations

import numpy as np
import trimesh

from fogsim.scene.assets_parts import box_arrays


def local_parts(asset: dict, library=None) -> list[tuple[trimesh.Trimesh, str]]:
    """(mesh in the asset's local frame, material slot) pairs; ``library`` (an
    :class:`fogsim.scene.library.AssetLibrary`) holds the meshes of library models."""
    if asset["type"] == "library":
        if library is None:
            raise ValueError(f"the library model {asset['params']['file']} needs the run's asset library")
        return [(trimesh.Trimesh(vertices=v, faces=f, process=False), slot)
                for v, f, slot in library.model(asset["params"]["file"]).parts()]
    if asset["type"] in ("box", "boxes"):
        p = asset["params"]
        boxes = [[0.0, 0.0, 0.0, *p["size"]]] if asset["type"] == "box" else p["boxes"]
        return [(_boxes_mesh(np.asarray(boxes, dtype=np.float64)), p["material"])]
    from fogsim.scene.assets import build_asset

    return build_asset(asset)


def _boxes_mesh(boxes: np.ndarray) -> trimesh.Trimesh:
    """One mesh of many boxes given as rows [cx, cy, z0, sx, sy, sz]."""
    lo = np.column_stack([boxes[:, 0] - boxes[:, 3] / 2, boxes[:, 1] - boxes[:, 4] / 2, boxes[:, 2]])
    hi = lo + boxes[:, 3:6]
    v, f = box_arrays(np.zeros(3), np.ones(3))
    verts = (lo[:, None, :] + v[None] * (hi - lo)[:, None, :]).reshape(-1, 3)
    faces = (f[None] + 8 * np.arange(len(boxes))[:, None, None]).reshape(-1, 3)
    return trimesh.Trimesh(vertices=verts, faces=faces, process=False)


def world_parts(obj: dict, library=None) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """(vertices N×3 world metres, faces F×3, material slot) per part of an object."""
    M = np.asarray(obj["transform"], dtype=np.float64)
    out = []
    for mesh, slot in local_parts(obj["asset"], library):
        v = np.asarray(mesh.vertices, dtype=np.float64) @ M[:3, :3].T + M[:3, 3]
        out.append((v, np.asarray(mesh.faces, dtype=np.int64), slot))
    return out


def material_key(obj: dict, slot: str) -> tuple[str, tuple]:
    """Material identity: the catalogue slot plus this instance's colour override, if any."""
    override = obj["asset"].get("materials", {}).get(slot, {})
    return slot, tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in override.items()))

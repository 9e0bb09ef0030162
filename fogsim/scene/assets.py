"""The procedural asset library: seeded specs and their meshes (trimesh + numpy, no bpy).

An asset spec is JSON: ``{"type": …, "params": {…}, "materials": {slot: {"color": […]}, …}}``.
:func:`sample_asset` draws one from a ``numpy.random.Generator``; :func:`build_asset` turns it
into (mesh, material slot) pairs, deterministically; :func:`asset_extent` sizes it without
meshing. Local frame: metres, origin at the centre of the ground footprint, z up, the object's
front toward +y (vehicles drive toward +y, people face +y, a building's street facade is its
+y face). Material slots name entries of :data:`fogsim.scene.materials.MATERIALS`; the spec's
``materials`` holds per-instance overrides of them.
"""
from __future__ import annotations

import numpy as np
import trimesh

from fogsim.scene import assets_buildings, assets_people, assets_street, assets_vehicles
from fogsim.scene.assets_parts import Part, merge, parts_extent

ASSET_TYPES = ("car", "van", "truck", "bus", "pedestrian", "cyclist",
               "traffic_light", "traffic_sign", "pole", "tree", "building")

_MODULES = (assets_vehicles, assets_people, assets_street, assets_buildings)
_SAMPLERS = {k: v for m in _MODULES for k, v in m.SAMPLERS.items()}
_BUILDERS = {k: v for m in _MODULES for k, v in m.BUILDERS.items()}


def _check_type(asset_type: str) -> None:
    if asset_type not in ASSET_TYPES:
        raise ValueError(f"unknown asset type {asset_type!r}; known: {', '.join(ASSET_TYPES)}")


def sample_asset(asset_type: str, rng: np.random.Generator, **constraints) -> dict:
    """A random instance of ``asset_type`` drawn only from ``rng`` (same state → same spec).

    ``constraints`` fix named parameters instead of drawing them, e.g. a building's plot
    ``width`` (along x, m), ``depth`` (y, m) and ``height`` (m), a traffic light's ``state``
    or a sign's ``shape``; an unknown name raises ValueError.
    """
    _check_type(asset_type)
    left = dict(constraints)
    params, materials = _SAMPLERS[asset_type](rng, left)
    if left:
        raise ValueError(f"unknown constraint(s) for {asset_type}: {', '.join(sorted(left))}")
    return {"type": asset_type, "params": params, "materials": materials}


def _parts(spec: dict) -> list[Part]:
    _check_type(spec["type"])
    return _BUILDERS[spec["type"]](spec["params"])


def asset_parts(spec: dict) -> list[Part]:
    """The asset's primitives, unmeshed: material slot and local bounding box (lo, hi) of each
    (e.g. where a vehicle's headlight lenses are, for :mod:`fogsim.scene.lights`)."""
    return _parts(spec)


def build_asset(spec: dict) -> list[tuple[trimesh.Trimesh, str]]:
    """(mesh in the local frame, material slot) pairs, one mesh per slot; deterministic."""
    return merge(_parts(spec))


def asset_extent(spec: dict) -> tuple[float, float, float]:
    """(size_x, size_y, size_z) of the local bounding box in metres, from the params alone
    (no meshing); never smaller than the built mesh and at most ~1 cm larger. A library model
    (``"type": "library"``, :mod:`fogsim.scene.library`) carries its extent in its params."""
    if spec["type"] == "library":
        return tuple(spec["params"]["extent"])
    return parts_extent(_parts(spec))

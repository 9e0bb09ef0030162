"""Mesh primitives for the asset library, each with its bounding box known before meshing.

A :class:`Part` pairs a material slot with an analytic axis-aligned bounding box (metres, in
the asset's local frame) and a function that makes the triangles. Assets are lists of parts,
so :func:`parts_extent` sizes an asset without meshing it and :func:`merge` meshes it, one
mesh per material slot. Circles are tessellated with a multiple of 4 segments starting on an
axis, so axis-aligned cylinders reach their analytic bounds exactly; blobs are rescaled to fill
their box exactly.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Callable, NamedTuple

import numpy as np
import trimesh

from fogsim.colour import srgb_to_linear


class Part(NamedTuple):
    """One primitive: material slot, bounding box corners (lo, hi), and a (vertices, faces) maker."""

    slot: str
    lo: np.ndarray
    hi: np.ndarray
    make: Callable[[], tuple[np.ndarray, np.ndarray]]


def _cross(b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (np.cross costs ~10 µs of overhead per call)."""
    return np.stack([b[..., 1] * c[..., 2] - b[..., 2] * c[..., 1],
                     b[..., 2] * c[..., 0] - b[..., 0] * c[..., 2],
                     b[..., 0] * c[..., 1] - b[..., 1] * c[..., 0]], axis=-1)


def _oriented(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flip a closed mesh's winding if its signed volume is negative (normals point outward)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    volume = np.einsum("ij,ij->i", a, _cross(b, c)).sum()
    return (v, f[:, ::-1].copy()) if volume < 0 else (v, f)


_UNIT_BOX = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
_UNIT_BOX_V = np.asarray(_UNIT_BOX.vertices) + 0.5  # corners of [0, 1]³
_UNIT_BOX_F = np.asarray(_UNIT_BOX.faces)


def box_arrays(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """(8 vertices, 12 outward triangles) of the box between corners ``lo`` < ``hi``.

    Plain arrays: thousands of windows and lane dashes per scene, so no Trimesh per box.
    """
    lo = np.asarray(lo, float)
    return lo + _UNIT_BOX_V * (np.asarray(hi, float) - lo), _UNIT_BOX_F


def box(slot: str, lo, hi) -> Part:
    """Axis-aligned box between opposite corners ``lo`` and ``hi`` (in any order per axis)."""
    a, b = np.asarray(lo, float), np.asarray(hi, float)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    return Part(slot, lo, hi, lambda: box_arrays(lo, hi))


def loft_mesh(rings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed surface through ``rings`` (m × k × 3, each a convex loop), capped at both ends."""
    m, k, _ = rings.shape
    idx = np.arange(m * k).reshape(m, k)
    a, b = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = np.roll(idx[1:], -1, axis=1), idx[1:]
    sides = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    j = np.arange(1, k - 1)
    first = np.stack([np.zeros_like(j), j + 1, j], -1)
    last = np.stack([np.zeros_like(j), j, j + 1], -1) + (m - 1) * k
    return _oriented(rings.reshape(-1, 3), np.concatenate([sides, first, last]))


def loft(slot: str, rings) -> Part:
    """A solid through polygon ``rings`` (m × k × 3); its bounds are the rings' bounds."""
    rings = np.asarray(rings, float)
    pts = rings.reshape(-1, 3)
    return Part(slot, pts.min(0), pts.max(0), lambda: loft_mesh(rings))


def prism(slot: str, polygon_yz, x0: float, x1: float) -> Part:
    """A convex side profile (points (y, z), in order) extruded across x from ``x0`` to ``x1``."""
    p = np.asarray(polygon_yz, float)
    rings = [np.column_stack([np.full(len(p), x), p]) for x in (x0, x1)]
    return loft(slot, rings)


def _frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane normal to ``axis`` (axis-aligned when axis is)."""
    ref = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = _cross(axis, ref)
    u /= np.sqrt(u @ u)
    return u, _cross(axis, u)


def _circle(center, axis, radius: float, n: int) -> np.ndarray:
    u, v = _frame(axis)
    t = 2.0 * np.pi * np.arange(n) / n
    return np.asarray(center, float) + radius * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v))


def _circle_bounds(center, axis, radius: float) -> tuple[np.ndarray, np.ndarray]:
    half = radius * np.sqrt(np.clip(1.0 - axis ** 2, 0.0, 1.0))
    return np.asarray(center, float) - half, np.asarray(center, float) + half


def tube(slot: str, points, radii, n: int = 12) -> Part:
    """A tube of circular cross-sections through ``points`` (each ring normal to the path)."""
    points = np.asarray(points, float)
    radii = np.broadcast_to(np.asarray(radii, float), (len(points),))
    seg = np.diff(points, axis=0)
    seg /= np.linalg.norm(seg, axis=1, keepdims=True)
    axes = np.concatenate([seg[:1], seg[:-1] + seg[1:], seg[-1:]])
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    bounds = [_circle_bounds(p, a, r) for p, a, r in zip(points, axes, radii)]
    lo = np.min([b[0] for b in bounds], axis=0)
    hi = np.max([b[1] for b in bounds], axis=0)
    return Part(slot, lo, hi, lambda: loft_mesh(np.stack([_circle(p, a, r, n)
                                                          for p, a, r in zip(points, axes, radii)])))


def cylinder(slot: str, p0, p1, radius: float, n: int = 16) -> Part:
    """A straight cylinder from ``p0`` to ``p1``."""
    return tube(slot, [p0, p1], radius, n)


def ellipse(center, a: float, b: float, n: int = 16) -> np.ndarray:
    """A horizontal ellipse ring (n × 3) with half-axes ``a`` (x) and ``b`` (y)."""
    t = 2.0 * np.pi * np.arange(n) / n
    c = np.asarray(center, float)
    return np.column_stack([c[0] + a * np.cos(t), c[1] + b * np.sin(t), np.full(n, c[2])])


def blob(slot: str, center, radii, seed: int, jitter: float = 0.0, subdivisions: int = 2) -> Part:
    """An icosphere, radially jittered by up to ``jitter`` (fraction), stretched to fill
    the box ``center ± radii`` exactly."""
    center, radii = np.asarray(center, float), np.asarray(radii, float)

    def make():
        base_v, base_f = _icosphere(subdivisions)
        v = base_v
        if jitter > 0:
            v = v * (1.0 + jitter * np.random.default_rng(seed).uniform(-1, 1, (len(v), 1)))
        lo, hi = v.min(0), v.max(0)
        v = (v - (lo + hi) / 2.0) / ((hi - lo) / 2.0)
        return _oriented(center + v * radii, base_f)
    return Part(slot, center - radii, center + radii, make)


@lru_cache(maxsize=4)
def _icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    v, f = np.asarray(m.vertices, float), np.asarray(m.faces)
    v.flags.writeable = f.flags.writeable = False
    return v, f


def torus(slot: str, center, axis, major: float, minor: float, n_major: int = 24, n_minor: int = 8) -> Part:
    """A ring of tube radius ``minor`` around ``axis`` at distance ``major`` from ``center``."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    center = np.asarray(center, float)
    half = major * np.sqrt(np.clip(1.0 - axis ** 2, 0.0, 1.0)) + minor

    def make():
        u, v = _frame(axis)
        t = 2.0 * np.pi * np.arange(n_major) / n_major
        p = 2.0 * np.pi * np.arange(n_minor) / n_minor
        radial = np.cos(t)[:, None, None] * u + np.sin(t)[:, None, None] * v
        rings = (center + (major + minor * np.cos(p))[None, :, None] * radial
                 + (minor * np.sin(p))[None, :, None] * axis)
        idx = np.arange(n_major * n_minor).reshape(n_major, n_minor)
        a, b = idx, np.roll(idx, -1, axis=1)
        c, d = np.roll(b, -1, axis=0), np.roll(idx, -1, axis=0)
        faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
        return _oriented(rings.reshape(-1, 3), faces)
    return Part(slot, center - half, center + half, make)


def parts_bounds(parts: list[Part]) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) corners of the union of the parts' boxes."""
    return np.min([p.lo for p in parts], axis=0), np.max([p.hi for p in parts], axis=0)


def parts_extent(parts: list[Part]) -> tuple[float, float, float]:
    """(size_x, size_y, size_z) of the parts' union box, metres."""
    lo, hi = parts_bounds(parts)
    return tuple(float(s) for s in hi - lo)


def merge(parts: list[Part]) -> list[tuple[trimesh.Trimesh, str]]:
    """One mesh per material slot (in order of first use), made from the parts."""
    by_slot: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for part in parts:
        by_slot.setdefault(part.slot, []).append(part.make())
    out = []
    for slot, pieces in by_slot.items():
        offsets = np.cumsum([0] + [len(v) for v, _ in pieces[:-1]])
        verts = np.concatenate([v for v, _ in pieces])
        faces = np.concatenate([f + o for (_, f), o in zip(pieces, offsets)])
        out.append((trimesh.Trimesh(vertices=verts, faces=faces, process=False), slot))
    return out


def srgb(hex_colour: str) -> list[float]:
    """Linear RGB of an sRGB hex colour like ``"#a0b0c0"``."""
    c = np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
    return [round(float(x), 4) for x in srgb_to_linear(c, np.float64)]


def pick_colour(rng: np.random.Generator, palette: dict[str, float], jitter: float = 0.06) -> list[float]:
    """A colour from a {hex: weight} palette, brightness-jittered by ± ``jitter`` (fraction)."""
    names = list(palette)
    w = np.array([palette[k] for k in names], float)
    base = np.array(srgb(names[int(rng.choice(len(names), p=w / w.sum()))]))
    scale = 1.0 + float(rng.uniform(-jitter, jitter))
    return [round(float(x), 4) for x in np.clip(base * scale, 0.0, 1.0)]


def draw(rng: np.random.Generator, constraints: dict, key: str, lo: float, hi: float) -> float:
    """Uniform draw in [lo, hi), replaced by ``constraints[key]`` when given (popped).
    The draw is always made, so constraints never shift the rest of the random stream."""
    value = float(rng.uniform(lo, hi))
    return float(constraints.pop(key)) if key in constraints else value


def draw_choice(rng: np.random.Generator, constraints: dict, key: str, options, p=None):
    """Like :func:`draw` for a choice among ``options`` (optionally weighted by ``p``)."""
    p = None if p is None else np.asarray(p, float) / np.sum(p)
    value = options[int(rng.choice(len(options), p=p))]
    if key not in constraints:
        return value
    given = constraints.pop(key)
    if given not in options:
        raise ValueError(f"{key} must be one of {list(options)}, got {given!r}")
    return given

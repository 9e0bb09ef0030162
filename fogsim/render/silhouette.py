"""Unoccluded object silhouettes by software rasterisation (no Blender), for occlusion and truncation.

Each object's triangles are projected through the OpenCV camera (x right, y down, z forward;
pixel centres at integers) and rasterised alone, so the count is the area the object would
cover with nothing in front of it. Convention, as in a renderer sampling pixel centres: a
pixel counts when its centre lies inside (or on the edge of) one of the object's triangles.
The rasteriser is an exact scanline one written with numpy: per triangle and pixel row it
finds the span of covered centres; the spans, sorted by row, are merged to count the union
(no image-sized buffer, so memory follows the number of spans). ``cv2.fillPoly`` is not
used: it also draws the outline and rounds spans outwards, which inflates a 10×10-pixel
square to 121 pixels.

The counted region (the canvas) reaches ``margin``·W and ``margin``·H beyond each image side, so the parts of a
truncated object outside the image count in ``pixels_total`` (parts beyond the margin do
not). Triangles are clipped against the near plane z = :data:`NEAR` metres (a triangle
with one vertex behind becomes two, with two behind one; with three behind it is dropped).
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.camera import Intrinsics

NEAR = 0.05  # metres

Bounds = tuple[int, int, int, int]  # a pixel rectangle [x0, x1) × [y0, y1)


def project_points(points_world: np.ndarray, K: Intrinsics,
                   world_to_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points (N×3, metres) → pixel coordinates ``uv`` (N×2) and camera depth ``z`` (N,).

    ``uv`` is meaningless where z ≤ 0 (behind the camera).
    """
    cam = _to_camera(np.asarray(points_world, dtype=np.float64).reshape(-1, 3), world_to_camera)
    return _project(cam, K), cam[:, 2]


def _to_camera(points: np.ndarray, world_to_camera: np.ndarray) -> np.ndarray:
    M = np.asarray(world_to_camera, dtype=np.float64)
    return points @ M[:3, :3].T + M[:3, 3]


def _project(cam: np.ndarray, K: Intrinsics) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([K.fx * cam[..., 0] / cam[..., 2] + K.cx,
                         K.fy * cam[..., 1] / cam[..., 2] + K.cy], axis=-1)


def clip_near(tris: np.ndarray, near: float = NEAR) -> np.ndarray:
    """Camera-space triangles (T×3×3) clipped to z ≥ ``near``; returns T'×3×3."""
    behind = tris[:, :, 2] < near
    n_behind = behind[:, 0].astype(np.int8) + behind[:, 1] + behind[:, 2]
    out = [tris[n_behind == 0]]
    for count, special in ((1, behind), (2, ~behind)):
        sel = n_behind == count
        if not sel.any():
            continue
        # rotate each triangle so its odd vertex out (the one behind, or the one in front) is first
        first = np.argmax(special[sel], axis=1)
        order = (first[:, None] + np.arange(3)) % 3
        a, b, c = np.moveaxis(np.take_along_axis(tris[sel], order[:, :, None], axis=1), 1, 0)
        ab, ac = _cut(a, b, near), _cut(a, c, near)
        if count == 1:
            out += [np.stack([ab, b, c], axis=1), np.stack([ab, c, ac], axis=1)]
        else:
            out.append(np.stack([a, ab, ac], axis=1))
    return np.concatenate(out)


def _cut(p: np.ndarray, q: np.ndarray, near: float) -> np.ndarray:
    """Where the segment p→q crosses z = near (one end on each side)."""
    t = (near - p[:, 2]) / (q[:, 2] - p[:, 2])
    return p + t[:, None] * (q - p)


def _spans(tri_uv: np.ndarray, bounds: Bounds) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covered pixel-centre spans of 2-D triangles (T×3×2, pixels) inside ``bounds``.

    Returns (row, left, right) int64 arrays, one entry per triangle and pixel row, with
    columns left…right inclusive, sorted by (row, left).
    """
    x0, y0, x1, y1 = bounds
    (u0, v0), (u1, v1), (u2, v2) = _sorted_by_v(tri_uv)
    first = np.maximum(np.ceil(v0), y0)
    n = np.minimum(np.floor(v2), y1 - 1) - first + 1
    n = np.where((v2 > v0) & np.isfinite(n), n, 0).clip(0).astype(np.int64)
    tri = np.repeat(np.arange(n.size), n)
    y = first[tri] + (np.arange(tri.size) - np.repeat(np.cumsum(n) - n, n))
    u0, v0, u1, v1, u2, v2 = (a[tri] for a in (u0, v0, u1, v1, u2, v2))
    long_edge = u0 + (y - v0) * (u2 - u0) / (v2 - v0)
    upper = y < v1
    short_edge = np.where(upper, u0 + (y - v0) * (u1 - u0) / np.where(upper, v1 - v0, 1.0),
                          u1 + (y - v1) * (u2 - u1) / np.where(v2 > v1, v2 - v1, 1.0))
    left = np.maximum(np.ceil(np.minimum(long_edge, short_edge)), x0)
    right = np.minimum(np.floor(np.maximum(long_edge, short_edge)), x1 - 1)
    ok = left <= right
    row, left, right = y[ok].astype(np.int64), left[ok].astype(np.int64), right[ok].astype(np.int64)
    order = np.argsort((row - y0) * (x1 - x0) + (left - x0))
    return row[order], left[order], right[order]


def _union_size(row: np.ndarray, left: np.ndarray, right: np.ndarray, bounds: Bounds) -> int:
    """Pixels covered by spans sorted by (row, left), clipped to ``bounds``."""
    x0, y0, x1, y1 = bounds
    sel = (row >= y0) & (row < y1)
    row, left, right = row[sel], np.maximum(left[sel], x0), np.minimum(right[sel], x1 - 1)
    sel = left <= right
    # one number line for all rows: row r occupies [r·stride, r·stride + width), so a running
    # maximum of span ends never carries over from one row into the next
    stride = x1 - x0 + 1
    base = (row[sel] - y0) * stride - x0
    lo, hi = base + left[sel], base + right[sel]
    covered_before = np.maximum.accumulate(np.concatenate([[-1], hi]))[:-1]
    return int(np.maximum(hi - np.maximum(lo, covered_before + 1) + 1, 0).sum())


def covered_pixels(tri_uv: np.ndarray, bounds: Bounds) -> int:
    """Pixels of ``bounds`` = (x0, y0, x1, y1) (a half-open pixel rectangle) whose centre lies
    inside at least one of the 2-D triangles ``tri_uv`` (T×3×2, pixel coordinates)."""
    return _union_size(*_spans(tri_uv, bounds), bounds)


def _sorted_by_v(tri_uv: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The three vertices of every triangle as (u, v) arrays, ordered by v (a sorting network)."""
    vert = [(tri_uv[:, i, 0], tri_uv[:, i, 1]) for i in range(3)]
    for i, j in ((0, 1), (1, 2), (0, 1)):
        (ui, vi), (uj, vj) = vert[i], vert[j]
        swap = vj < vi
        vert[i] = (np.where(swap, uj, ui), np.where(swap, vj, vi))
        vert[j] = (np.where(swap, ui, uj), np.where(swap, vi, vj))
    return vert


def _camera_triangles(parts: list, world_to_camera: np.ndarray) -> np.ndarray:
    """Camera-space triangles (T×3×3) of an object's parts (trimesh meshes or (vertices, faces))."""
    tris = [np.zeros((0, 3, 3))]
    for part in parts:
        v, f = (part.vertices, part.faces) if hasattr(part, "faces") else part
        cam = _to_camera(np.asarray(v, dtype=np.float64), world_to_camera)
        tris.append(cam[np.asarray(f, dtype=np.int64)])
    return np.concatenate(tris)


def silhouette_areas(meshes: dict[int, list], K: Intrinsics, world_to_camera: np.ndarray,
                     margin: float = 1.0) -> dict[int, dict]:
    """``{id: {"pixels_in_image": n, "pixels_total": m}}``: unoccluded silhouette areas in pixels.

    ``meshes`` maps object id → parts in world coordinates (trimesh meshes or
    (vertices N×3, faces F×3) pairs). ``pixels_total`` counts the silhouette on a canvas
    extending ``margin``·W and ``margin``·H beyond each side of the image.
    """
    mx, my = math.ceil(margin * K.width), math.ceil(margin * K.height)
    canvas = (-mx, -my, K.width + mx, K.height + my)
    out = {}
    for oid, parts in meshes.items():
        tris = clip_near(_camera_triangles(parts, world_to_camera))
        out[int(oid)] = _areas(_project(tris, K), canvas, K.width, K.height)
    return out


def _areas(tri_uv: np.ndarray, canvas: Bounds, width: int, height: int) -> dict:
    """Silhouette pixel counts of projected triangles inside the image and on the whole canvas."""
    if not tri_uv.size:
        return {"pixels_in_image": 0, "pixels_total": 0}
    spans = _spans(tri_uv, canvas)
    return {"pixels_in_image": _union_size(*spans, (0, 0, width, height)),
            "pixels_total": _union_size(*spans, canvas)}

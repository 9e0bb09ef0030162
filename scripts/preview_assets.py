"""Contact sheet of the procedural assets, drawn by a tiny numpy/OpenCV rasteriser.

Orthographic 3/4 view from front-right-above, flat shading (face normal · light), material
colours from the catalogue plus each instance's overrides, z-buffered, 2× supersampled.

    python scripts/preview_assets.py --out /tmp/assets_preview.png [--seeds 3] [--types car bus]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from fogsim.colour import linear_to_srgb
from fogsim.scene.assets import ASSET_TYPES, asset_extent, build_asset, sample_asset
from fogsim.scene.materials import material

LIGHT = np.array([0.45, 0.55, 0.7]) / np.linalg.norm([0.45, 0.55, 0.7])


def view_axes(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, forward) unit vectors of a camera looking at the origin from ``azimuth``
    (degrees from +y toward +x) and ``elevation`` (degrees above the ground)."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    forward = -np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward), forward


def to_srgb(rgb) -> np.ndarray:
    """Linear colours → sRGB-encoded float64 in [0, 1] (clipped at white)."""
    return linear_to_srgb(np.clip(np.asarray(rgb, float), 0.0, 1.0), np.float64)


def triangles(spec: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(vertices F×3×3, unit normals F×3, linear colours F×3, emissive F) of an asset."""
    tris, normals, colours, glow = [], [], [], []
    for mesh, slot in build_asset(spec):
        m = material(slot, **spec.get("materials", {}).get(slot, {}))
        tris.append(np.asarray(mesh.vertices)[mesh.faces])
        normals.append(np.asarray(mesh.face_normals))
        colours.append(np.tile(m["color"], (len(mesh.faces), 1)))
        glow.append(np.full(len(mesh.faces), m.get("emission", 0.0) > 0))
    return tuple(np.concatenate(a) for a in (tris, normals, colours, glow))


def zbuffer(img: np.ndarray, xy: np.ndarray, depth: np.ndarray, colour: np.ndarray) -> None:
    """Fill triangles (F×3×2 pixel coordinates, F×3 depths, F×3 colours) nearest-first per pixel."""
    h, w = img.shape[:2]
    zbuf = np.full((h, w), np.inf)
    for (a, b, c), (za, zb, zc), col in zip(xy, depth, colour):
        x0, y0 = np.maximum(np.floor(np.minimum(np.minimum(a, b), c)).astype(int), 0)
        x1, y1 = np.minimum(np.ceil(np.maximum(np.maximum(a, b), c)).astype(int), [w - 1, h - 1])
        if x1 < x0 or y1 < y0:
            continue
        px, py = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
        area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        if abs(area) < 1e-9:
            continue
        wa = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) / area
        wb = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) / area
        wc = 1.0 - wa - wb
        z = wa * za + wb * zb + wc * zc
        inside = (wa >= 0) & (wb >= 0) & (wc >= 0) & (z < zbuf[y0:y1 + 1, x0:x1 + 1])
        zbuf[y0:y1 + 1, x0:x1 + 1][inside] = z[inside]
        img[y0:y1 + 1, x0:x1 + 1][inside] = col


def render(spec: dict, size: int, azimuth: float, elevation: float, ss: int = 2) -> np.ndarray:
    """BGR uint8 tile of one asset, scaled to fit, over a 1 m ground grid."""
    right, up, forward = view_axes(azimuth, elevation)
    tris, normals, colours, glow = triangles(spec)
    ext = np.array(asset_extent(spec))
    lo, hi = tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    sx, sy = corners @ right, -(corners @ up)
    S = size * ss
    scale = 0.82 * S / max(np.ptp(sx), np.ptp(sy))
    off = np.array([S / 2 - scale * (sx.min() + sx.max()) / 2, S * 0.52 - scale * (sy.min() + sy.max()) / 2])

    def project(p):
        return np.stack([p @ right, -(p @ up)], -1) * scale + off
    img = np.full((S, S, 3), 235, np.uint8)
    g = np.arange(np.floor(lo[:2].min()) - 1, np.ceil(hi[:2].max()) + 2)
    for a in g:
        for p0, p1 in (([a, g[0], 0], [a, g[-1], 0]), ([g[0], a, 0], [g[-1], a, 0])):
            q = project(np.array([p0, p1], float)).astype(np.int32)
            cv2.line(img, tuple(q[0]), tuple(q[1]), (205, 205, 205), ss)
    visible = normals @ forward < 0
    tris, normals, colours, glow = tris[visible], normals[visible], colours[visible], glow[visible]
    shade = np.where(glow, 1.4, 0.3 + 0.7 * np.clip(normals @ LIGHT, 0, 1))
    rgb = (to_srgb(colours * shade[:, None]) * 255).astype(np.uint8)[:, ::-1]
    zbuffer(img, project(tris), tris @ forward, rgb)
    img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
    label = f"{spec['type']} {ext[0]:.1f}x{ext[1]:.1f}x{ext[2]:.1f}m"
    cv2.putText(img, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (40, 40, 40), 1, cv2.LINE_AA)
    return img


def contact_sheet(types, seeds: int, tile: int, cols: int, azimuth: float, elevation: float) -> np.ndarray:
    tiles = [render(sample_asset(t, np.random.default_rng(s)), tile, azimuth, elevation)
             for t in types for s in range(seeds)]
    rows = -(-len(tiles) // cols)
    sheet = np.full((rows * tile, cols * tile, 3), 255, np.uint8)
    for k, img in enumerate(tiles):
        r, c = divmod(k, cols)
        sheet[r * tile:(r + 1) * tile, c * tile:(c + 1) * tile] = img
        cv2.rectangle(sheet, (c * tile, r * tile), ((c + 1) * tile - 1, (r + 1) * tile - 1), (180, 180, 180), 1)
    return sheet


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("/tmp/assets_preview.png"))
    ap.add_argument("--types", nargs="+", default=list(ASSET_TYPES), choices=ASSET_TYPES)
    ap.add_argument("--seeds", type=int, default=3, help="instances per type (seeds 0..n-1)")
    ap.add_argument("--tile", type=int, default=300, help="tile size, pixels")
    ap.add_argument("--cols", type=int, default=6)
    ap.add_argument("--azimuth", type=float, default=35.0, help="degrees from the front (+y) toward +x")
    ap.add_argument("--elevation", type=float, default=20.0, help="degrees above the ground")
    a = ap.parse_args()
    sheet = contact_sheet(a.types, a.seeds, a.tile, a.cols, a.azimuth, a.elevation)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(a.out), sheet)


if __name__ == "__main__":
    main()

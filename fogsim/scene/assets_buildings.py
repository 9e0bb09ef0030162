"""Buildings: a block with a window grid on its street facade, a ground floor and a cornice.

Local frame: metres, origin at the centre of the ground footprint, z up; the street facade is
the +y face. ``width`` runs along x (along the street once placed), ``depth`` along y. Windows
sit in openings recessed into the facade (piers and spandrels stand proud of the glass), so
the facade has real relief. The bounding box is exactly width × depth × height. At night
(:mod:`fogsim.scene.lights`) ``params.lit_windows = {"fraction", "seed"}`` lights a seeded
fraction of the panes (material ``window_lit``) without changing any triangle.
"""
from __future__ import annotations

import numpy as np

from fogsim.scene.assets_parts import Part, box, draw, draw_choice, pick_colour

FACADES = {
    "facade_brick": {"#9c4a32": 3, "#7e3426": 2, "#b5835a": 1, "#6e3b2c": 1, "#a8685a": 1},
    "facade_concrete": {"#9a9a96": 3, "#b4b2aa": 2, "#7e7f7d": 2, "#a59f92": 1},
    "facade_plaster": {"#e8dcc0": 3, "#d9c7a3": 2, "#e6e2da": 2, "#c9b08a": 1, "#b9c4c9": 1, "#d8b0a0": 1},
}
FRAMES = {"#f0f0ec": 4, "#3a3a3c": 2, "#5a4030": 1}
DOORS = {"#4a3020": 3, "#1e3a2a": 1, "#222226": 2, "#6a6a6e": 1}
MAX_WINDOWS = 80  # keeps a building under ~5k triangles


def sample_building(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """Plot size (``width``, ``depth``, ``height``, usually given by the layout), facade
    material and colour, floor heights, window grid and ground floor type."""
    for key, least in (("width", 2.0), ("depth", 2.0), ("height", 4.0)):
        if key in c and c[key] < least:
            raise ValueError(f"building {key} must be at least {least} m, got {c[key]}")
    facade = draw_choice(rng, c, "facade", tuple(FACADES), (0.35, 0.3, 0.35))
    p = {"width": draw(rng, c, "width", 8.0, 25.0), "depth": draw(rng, c, "depth", 8.0, 16.0),
         "height": draw(rng, c, "height", 7.0, 30.0), "facade": facade,
         "floor_height": draw(rng, c, "floor_height", 2.9, 3.4),
         "ground_height": draw(rng, c, "ground_height", 3.3, 4.2),
         "bay": draw(rng, c, "bay", 2.3, 3.3), "window_width": draw(rng, c, "window_width", 0.45, 0.65),
         "window_height": draw(rng, c, "window_height", 1.3, 1.7), "recess": draw(rng, c, "recess", 0.12, 0.25),
         "roof_height": draw(rng, c, "roof_height", 0.5, 0.9),
         "shopfront": draw_choice(rng, c, "shopfront", (True, False), (0.5, 0.5)),
         "door_bay": draw(rng, c, "door_bay", 0.0, 1.0)}
    top = p["height"] - p["roof_height"]
    upper = top - 1.0 - p["window_height"]  # the highest ground floor with a window row above it
    if upper >= 2.8:  # low buildings get a lower ground floor rather than a blank upper facade
        p["ground_height"] = min(p["ground_height"], upper)
    p["ground_height"] = min(p["ground_height"], top - 0.5)
    mats = {facade: {"color": pick_colour(rng, FACADES[facade], 0.08)},
            "window_frame": {"color": pick_colour(rng, FRAMES)}, "door": {"color": pick_colour(rng, DOORS)}}
    return p, mats


def _grid(p: dict) -> tuple[np.ndarray, list[float]]:
    """Bay centres (x) and upper-floor bottoms (z), at most :data:`MAX_WINDOWS` windows."""
    W, top = p["width"], p["height"] - p["roof_height"]
    last = top - 1.0 - p["window_height"]  # highest floor whose window row fits under the cornice
    floors = [float(z) for z in np.arange(p["ground_height"], last + 1e-6, p["floor_height"])]
    bays = max(1, int(round(W / p["bay"])))
    while bays > 1 and bays * len(floors) > MAX_WINDOWS:
        bays -= 1
    return -W / 2 + (np.arange(bays) + 0.5) * W / bays, floors


def _skin(slot: str, y: tuple[float, float], x: tuple[float, float], z: tuple[float, float], holes) -> list[Part]:
    """Facade boxes filling the band x × z except the ``holes`` [(x0, x1, z0, z1)], which all
    span the same z range when there are several (a window row)."""
    hz0, hz1 = holes[0][2], holes[0][3]
    cells = [(x[0], x[1], z[0], hz0), (x[0], x[1], hz1, z[1])]
    edges = [x[0]] + [e for h in holes for e in h[:2]] + [x[1]]
    cells += [(a, b, hz0, hz1) for a, b in zip(edges[::2], edges[1::2])]
    return [box(slot, [a, y[0], c], [b, y[1], d]) for a, b, c, d in cells if b - a > 1e-3 and d - c > 1e-3]


def _window(x0: float, x1: float, z0: float, z1: float, y: float) -> list[Part]:
    """Frame, glass and (for wide windows) a mullion in an opening whose back is at ``y``."""
    parts = [box("window_frame", [x0, y, z0], [x1, y + 0.03, z1]),
             box("window", [x0 + 0.06, y + 0.03, z0 + 0.06], [x1 - 0.06, y + 0.05, z1 - 0.06])]
    if x1 - x0 > 1.1:
        xm = (x0 + x1) / 2
        parts.append(box("window_frame", [xm - 0.03, y + 0.03, z0 + 0.06], [xm + 0.03, y + 0.07, z1 - 0.06]))
    return parts


def _ground_floor(p: dict, xs: np.ndarray, bay: float, y_back: float, y_front: float) -> list[Part]:
    """Shop windows or ordinary windows per bay, and a door in one bay."""
    slot, gh = p["facade"], p["ground_height"]
    door = min(int(p["door_bay"] * len(xs)), len(xs) - 1)
    parts = []
    for i, xc in enumerate(xs):
        cell = (xc - bay / 2, xc + bay / 2)
        if i == door:
            hole = (xc - 0.6, xc + 0.6, 0.0, 2.4)
            parts.append(box("door", [hole[0], y_back, 0.0], [hole[1], y_back + 0.06, 2.4]))
        else:
            half = bay / 2 - 0.3 if p["shopfront"] else p["window_width"] * bay / 2
            z0, z1 = (0.45, gh - 0.5) if p["shopfront"] else (1.0, min(1.0 + p["window_height"], gh - 0.3))
            hole = (xc - half, xc + half, z0, z1)
            parts += _window(hole[0], hole[1], z0, z1, y_back)
        parts += _skin(slot, (y_back, y_front), cell, (0.0, gh), [hole])
    return parts


def building_parts(p: dict) -> list[Part]:
    """Core block, recessed window grid on the +y facade, ground floor, cornice and parapet."""
    W, D, H, slot = p["width"], p["depth"], p["height"], p["facade"]
    top = H - p["roof_height"]
    y_front = D / 2 - 0.06
    y_back = y_front - p["recess"]
    xs, floors = _grid(p)
    bay = W / len(xs)
    parts = [box(slot, [-W / 2, -D / 2, 0.0], [W / 2, y_back + 0.01, top]),
             box(slot, [-W / 2, -D / 2, top], [W / 2, D / 2, top + 0.2]),
             box("roof", [-W / 2, -D / 2, top + 0.2], [W / 2, D / 2 - 0.06, H])]
    parts += _ground_floor(p, xs, bay, y_back, y_front)
    half = p["window_width"] * bay / 2
    z_prev = p["ground_height"]
    for z in floors:
        z0, z1 = z + 0.8, z + 0.8 + p["window_height"]
        holes = [(xc - half, xc + half, z0, z1) for xc in xs]
        parts += _skin(slot, (y_back, y_front), (-W / 2, W / 2), (z_prev, z1), holes)
        parts += [w for h in holes for w in _window(*h, y_back)]
        z_prev = z1
    parts.append(box(slot, [-W / 2, y_back, z_prev], [W / 2, y_front, top]))
    return _light_windows(parts, p["lit_windows"]) if "lit_windows" in p else parts


def _light_windows(parts: list[Part], lit: dict) -> list[Part]:
    """Night: a seeded ``lit["fraction"]`` of the window panes become ``window_lit`` (same boxes,
    so the geometry is unchanged; only the material differs). ``lit["seed"]`` draws which."""
    rng = np.random.default_rng(lit["seed"])
    return [q._replace(slot="window_lit") if q.slot == "window" and rng.random() < lit["fraction"] else q
            for q in parts]


SAMPLERS = {"building": sample_building}
BUILDERS = {"building": building_parts}

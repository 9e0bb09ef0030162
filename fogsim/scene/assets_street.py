"""Street furniture and trees: traffic lights, signs, street lamps, trees.

Local frame: metres, origin at the foot of the post/trunk (centre of its ground footprint),
z up, the working side (lamps, sign face, lamp arm) toward +y.
"""
from __future__ import annotations

import numpy as np

from fogsim.scene.assets_parts import Part, blob, box, cylinder, draw, draw_choice, loft, pick_colour, srgb, tube

LIT = {"red": "#ff2a10", "amber": "#ffa000", "green": "#10ff70"}
SIGN_SCHEMES = {  # shape: [(border hex, face hex, weight)]
    "circle": [("#c8102e", "#f4f4f2", 5), ("#f4f4f2", "#1f4fa0", 3), ("#c8102e", "#c8102e", 1)],
    "triangle": [("#c8102e", "#f4f4f2", 5), ("#c8102e", "#f2c200", 1)],
    "rectangle": [("#f4f4f2", "#1f4fa0", 4), ("#141414", "#f4f4f2", 2), ("#f4f4f2", "#1f7a3a", 1)],
}


# --------------------------------------------------------------------------- traffic light
def sample_traffic_light(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A post-mounted three-lamp signal with exactly one lamp lit."""
    state = draw_choice(rng, c, "state", ("red", "amber", "green"), (0.45, 0.1, 0.45))
    p = {"state": state, "pole_height": draw(rng, c, "pole_height", 2.2, 2.8),
         "backplate": draw_choice(rng, c, "backplate", (True, False), (0.6, 0.4))}
    return p, {f"signal_{state}": {"color": srgb(LIT[state]), "emission": 25.0}}


def traffic_light_parts(p: dict) -> list[Part]:
    """Pole, housing facing +y, three lamps (red on top) with visors, optional backplate."""
    z0 = p["pole_height"]
    parts = [cylinder("pole_metal", [0, 0, 0], [0, 0, z0 + 0.1], 0.06),
             cylinder("pole_metal", [0, 0, 0], [0, 0, 0.3], 0.1),
             box("signal_housing", [-0.16, -0.125, z0], [0.16, 0.125, z0 + 0.95])]
    for i, colour in enumerate(("red", "amber", "green")):
        zc = z0 + 0.95 - 0.16 - 0.315 * i
        parts += [cylinder(f"signal_{colour}", [0, 0.12, zc], [0, 0.14, zc], 0.1, n=16),
                  box("signal_housing", [-0.125, 0.125, zc + 0.105], [0.125, 0.26, zc + 0.125]),
                  box("signal_housing", [-0.125, 0.125, zc - 0.02], [-0.11, 0.22, zc + 0.105]),
                  box("signal_housing", [0.11, 0.125, zc - 0.02], [0.125, 0.22, zc + 0.105])]
    if p["backplate"]:
        parts.append(box("signal_housing", [-0.3, -0.15, z0 - 0.08], [0.3, -0.125, z0 + 1.03]))
    return parts


# --------------------------------------------------------------------------- traffic sign
def sample_traffic_sign(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A sign plate (circle, triangle or rectangle) on a post, with a colour scheme per shape."""
    shape = draw_choice(rng, c, "shape", ("circle", "triangle", "rectangle"), (0.45, 0.3, 0.25))
    schemes = SIGN_SCHEMES[shape]
    weights = np.array([w for _, _, w in schemes], float)
    border, face, _ = schemes[int(rng.choice(len(schemes), p=weights / weights.sum()))]
    size = {"circle": (0.6, 0.75), "triangle": (0.7, 0.9), "rectangle": (0.5, 0.9)}[shape]
    p = {"shape": shape, "size": draw(rng, c, "size", *size), "aspect": draw(rng, c, "aspect", 0.7, 1.4),
         "post_height": draw(rng, c, "post_height", 2.0, 2.4),
         "inverted": draw_choice(rng, c, "inverted", (False, True), (0.75, 0.25)) if shape == "triangle" else False}
    return p, {"sign_border": {"color": srgb(border)}, "sign_face": {"color": srgb(face)}}


def _outline(p: dict) -> np.ndarray:
    """The plate outline in the x-z plane, centred on 0 (points (x, z), counter-clockwise)."""
    s = p["size"]
    if p["shape"] == "circle":
        t = 2 * np.pi * np.arange(24) / 24
        return 0.5 * s * np.column_stack([np.cos(t), np.sin(t)])
    if p["shape"] == "triangle":
        h = s * np.sqrt(3) / 2
        tri = np.array([[-s / 2, -h / 3], [s / 2, -h / 3], [0.0, 2 * h / 3]])
        return tri * [1, -1] if p["inverted"] else tri
    w, h = s, s / p["aspect"]
    return np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])


def _plate(slot: str, outline: np.ndarray, zc: float, y0: float, y1: float, scale: float = 1.0) -> Part:
    pts = outline * scale
    return loft(slot, [np.column_stack([pts[:, 0], np.full(len(pts), y), pts[:, 1] + zc]) for y in (y0, y1)])


def traffic_sign_parts(p: dict) -> list[Part]:
    """Post, grey back plate, coloured border plate and inset face, facing +y."""
    out = _outline(p)
    zc = p["post_height"] - out[:, 1].min()
    inset = 1.0 - 0.16 * (0.6 if p["shape"] == "rectangle" else 1.0)
    top = zc + out[:, 1].max()
    return [cylinder("pole_metal", [0, 0, 0], [0, 0, top - 0.05], 0.035),
            _plate("sign_back", out, zc, 0.035, 0.05), _plate("sign_border", out, zc, 0.05, 0.056),
            _plate("sign_face", out, zc, 0.056, 0.062, inset)]


# --------------------------------------------------------------------------- street lamp
def sample_pole(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A street lamp 6–9 m tall with one arm (toward +y) or two."""
    p = {"height": draw(rng, c, "height", 6.0, 9.0), "arm": draw(rng, c, "arm", 1.0, 2.0),
         "double": draw_choice(rng, c, "double", (False, True), (0.8, 0.2))}
    return p, {}


def pole_parts(p: dict) -> list[Part]:
    """Tapered pole on a base, curved arm(s) and a lamp head with a lens underneath."""
    h, arm = p["height"], p["arm"]
    parts = [tube("pole_metal", [[0, 0, 0], [0, 0, h - 0.4]], [0.09, 0.055], n=12),
             cylinder("pole_metal", [0, 0, 0], [0, 0, 0.6], 0.13, n=12)]
    for s in ((1, -1) if p["double"] else (1,)):
        arm_path = [[0, 0, h - 0.7], [0, s * 0.35, h - 0.18], [0, s * (arm - 0.1), h - 0.1]]
        parts += [tube("pole_metal", arm_path, 0.04, n=8),
                  box("pole_metal", [-0.17, s * (arm - 0.4), h - 0.14], [0.17, s * (arm + 0.15), h]),
                  box("street_lamp", [-0.13, s * (arm - 0.35), h - 0.16], [0.13, s * (arm + 0.1), h - 0.14])]
    return parts


# --------------------------------------------------------------------------- tree
def sample_tree(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A broadleaf (clustered blobs) or conifer (stacked cones) street tree."""
    kind = draw_choice(rng, c, "kind", ("broadleaf", "conifer"), (0.8, 0.2))
    p = {"kind": kind, "trunk_height": draw(rng, c, "trunk_height", 1.8, 3.2),
         "trunk_radius": draw(rng, c, "trunk_radius", 0.1, 0.2), "crown_radius": draw(rng, c, "crown_radius", 1.4, 2.8),
         "lobes": int(draw(rng, c, "lobes", 3, 6)), "seed": int(rng.integers(0, 2 ** 31))}
    green = pick_colour(rng, {"#3f5f22": 3, "#2f4a1c": 2, "#56702a": 2, "#6b6a2a": 1}, 0.15)
    return p, {"foliage": {"color": green}, "bark": {"color": pick_colour(rng, {"#4a3a2c": 2, "#6a5e52": 1}, 0.15)}}


def tree_parts(p: dict) -> list[Part]:
    """Trunk with a few branches under a crown of jittered lobes (or cones for a conifer)."""
    rng = np.random.default_rng(p["seed"])
    th, tr, R = p["trunk_height"], p["trunk_radius"], p["crown_radius"]
    if p["kind"] == "conifer":
        parts = [tube("bark", [[0, 0, 0], [0, 0, th + 1.5 * R]], [tr * 1.2, tr * 0.5], n=10)]
        for i, f in enumerate((1.0, 0.75, 0.5)):
            z = th + i * 0.9 * R
            parts.append(tube("foliage", [[0, 0, z], [0, 0, z + 1.4 * R * f]], [R * f, 0.04], n=12))
        return parts
    zc = th + 0.8 * R
    parts = [tube("bark", [[0, 0, 0], [0, 0, 0.6 * th], [0, 0, zc]], [tr * 1.25, tr, tr * 0.6], n=10)]
    parts.append(blob("foliage", [0, 0, zc], [R, R, 0.8 * R], p["seed"], 0.12))
    for k in range(p["lobes"]):
        a = 2 * np.pi * (k + rng.uniform(-0.2, 0.2)) / p["lobes"]
        d, r = R * rng.uniform(0.45, 0.65), R * rng.uniform(0.5, 0.7)
        centre = [d * np.cos(a), d * np.sin(a), zc + R * rng.uniform(-0.25, 0.35)]
        parts.append(blob("foliage", centre, [r, r, 0.85 * r], p["seed"] + k + 1, 0.15))
        parts.append(tube("bark", [[0, 0, th * 0.9], [0.6 * centre[0], 0.6 * centre[1], centre[2] - 0.2 * R]],
                          [0.6 * tr, 0.3 * tr], n=6))
    return parts


SAMPLERS = {"traffic_light": sample_traffic_light, "traffic_sign": sample_traffic_sign,
            "pole": sample_pole, "tree": sample_tree}
BUILDERS = {"traffic_light": traffic_light_parts, "traffic_sign": traffic_sign_parts,
            "pole": pole_parts, "tree": tree_parts}

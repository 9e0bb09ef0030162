"""Cars, vans, trucks and buses as primitive parts.

Local frame: metres, origin at the centre of the ground footprint, z up, driving toward +y,
so the bounding box is x ∈ ±width/2, y ∈ ±length/2, z ∈ [0, height] and the tyres touch z = 0.
"""
from __future__ import annotations

import numpy as np

from fogsim.scene.assets_parts import Part, box, cylinder, draw, draw_choice, loft, pick_colour, prism, tube

#: body colours (sRGB hex: weight), roughly the world's car-colour shares
CAR_PALETTE = {"#f2f2f0": 25, "#e6e4dc": 4, "#101112": 20, "#5a5d61": 14, "#3b3e42": 5,
               "#a9adb1": 12, "#1d3a6e": 5, "#4f7fb3": 3, "#8c1515": 6, "#c62a1e": 3,
               "#6b4b32": 2, "#b8a888": 2, "#2f4f36": 2, "#e0b020": 1, "#d8661c": 1}
BUS_PALETTE = {"#f0c419": 3, "#c8201e": 3, "#f4f4f2": 3, "#2a5caa": 2, "#3a8a3a": 2, "#e2742a": 1}
CARGO_PALETTE = {"#f4f4f2": 6, "#c9ccce": 2, "#2a5caa": 1, "#c8201e": 1, "#3a8a3a": 1}
LIGHTS_ON = {"headlight": {"emission": 6.0}, "taillight": {"emission": 3.0}}


#: uniform ranges of the sampled parameters, metres; "width", "length", "height" are the bounding box
CAR = {"length": (4.2, 4.9), "width": (1.75, 1.9), "height": (1.4, 1.55), "clearance": (0.14, 0.19),
       "wheel_radius": (0.31, 0.34), "wheel_width": (0.2, 0.24), "front_overhang": (0.85, 0.95),
       "rear_overhang": (0.9, 1.05), "hood_height": (0.72, 0.82), "belt_height": (0.9, 0.98),
       "hood_length": (1.0, 1.25), "windshield_run": (0.7, 0.85)}
CAR_STYLES = {"sedan": {"rear_run": (0.5, 0.65), "deck_length": (0.75, 0.95)},
              "hatchback": {"rear_run": (0.3, 0.4), "deck_length": (0.12, 0.2)},
              "wagon": {"rear_run": (0.12, 0.18), "deck_length": (0.08, 0.12)}}
VAN = {"length": (5.0, 5.5), "width": (1.95, 2.05), "height": (2.0, 2.4), "clearance": (0.17, 0.22),
       "wheel_radius": (0.33, 0.36), "wheel_width": (0.21, 0.24), "front_overhang": (0.9, 1.0),
       "rear_overhang": (1.0, 1.2), "hood_height": (0.95, 1.05), "belt_height": (1.08, 1.18),
       "hood_length": (0.65, 0.85), "windshield_run": (0.55, 0.7)}
TRUCK = {"length": (7.0, 9.0), "width": (2.45, 2.55), "height": (3.0, 3.6), "cab_length": (1.9, 2.2),
         "cab_drop": (0.2, 0.5), "wheel_radius": (0.47, 0.52), "cargo_floor": (1.05, 1.2)}
BUS = {"length": (10.0, 12.0), "width": (2.5, 2.55), "height": (3.0, 3.2), "wheel_radius": (0.48, 0.52),
       "window_bottom": (1.15, 1.3)}


def _draw_all(rng: np.random.Generator, c: dict, ranges: dict) -> dict:
    return {k: draw(rng, c, k, lo, hi) for k, (lo, hi) in ranges.items()}


def _lights(rng, c: dict) -> dict:
    on = draw_choice(rng, c, "lights_on", (False, True), (0.6, 0.4))
    return {k: dict(v) for k, v in LIGHTS_ON.items()} if on else {}


# --------------------------------------------------------------------------- sampling
def sample_car(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A sedan, hatchback or wagon: 4.2–4.9 × 1.75–1.9 × 1.4–1.55 m."""
    style = draw_choice(rng, c, "style", tuple(CAR_STYLES), (0.45, 0.4, 0.15))
    p = {"style": style, **_draw_all(rng, c, CAR), **_draw_all(rng, c, CAR_STYLES[style]),
         "tumblehome": 0.15, "side_windows": 2}
    return p, {"body_paint": {"color": pick_colour(rng, CAR_PALETTE)}, **_lights(rng, c)}


def sample_van(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A panel van (one side window) or minibus: 5–5.5 × 1.95–2.05 × 2–2.4 m."""
    style = draw_choice(rng, c, "style", ("panel", "minibus"), (0.6, 0.4))
    p = {"style": style, **_draw_all(rng, c, VAN), "rear_run": 0.04, "deck_length": 0.0, "tumblehome": 0.06,
         "side_windows": 1 if style == "panel" else 3}
    palette = CARGO_PALETTE if style == "panel" else CAR_PALETTE
    return p, {"body_paint": {"color": pick_colour(rng, palette)}, **_lights(rng, c)}


def sample_truck(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A box truck: cab + cargo box, 7–9 × 2.45–2.55 × 3–3.6 m, three axles."""
    mats = {"body_paint": {"color": pick_colour(rng, CAR_PALETTE)},
            "cargo_box": {"color": pick_colour(rng, CARGO_PALETTE)}}
    return _draw_all(rng, c, TRUCK), {**mats, **_lights(rng, c)}


def sample_bus(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A city bus: 10–12 × 2.5–2.55 × 3–3.2 m, window band, three axles."""
    return _draw_all(rng, c, BUS), {"body_paint": {"color": pick_colour(rng, BUS_PALETTE)}, **_lights(rng, c)}


# --------------------------------------------------------------------------- building
def wheel(x_out: float, y: float, r: float, width: float, side: int) -> list[Part]:
    """Tyre (chamfered) and rim of a wheel touching z = 0, outer face at x = side·x_out."""
    xo, xi = side * (x_out - 0.012), side * (x_out - width)
    xs = [xi, xi + side * 0.03, xo - side * 0.03, xo]
    tyre = tube("tyre", [[x, y, r] for x in xs], [0.86 * r, r, r, 0.86 * r], n=24)
    rim = cylinder("rim", [side * (x_out - width + 0.04), y, r], [side * (x_out - 0.008), y, r], 0.58 * r, n=16)
    hub = cylinder("plastic_black", [side * (x_out - 0.02), y, r], [side * x_out, y, r], 0.16 * r, n=8)
    return [tyre, rim, hub]


def _axle(x_out: float, y: float, r: float, width: float) -> list[Part]:
    return wheel(x_out, y, r, width, 1) + wheel(x_out, y, r, width, -1)


def wheel_arches(hw: float, y: float, r: float, z0: float) -> list[Part]:
    """Dark wheel wells on both body sides (x = ±hw) around an axle at ``y``, from ``z0`` up."""
    R, t = 1.12 * r, np.linspace(0.0, np.pi, 9)
    profile = [(y + R, z0)] + [(y + R * np.cos(a), r + R * np.sin(a)) for a in t] + [(y - R, z0)]
    return [prism("plastic_black", profile, s * (hw - 0.15), s * (hw + 0.004)) for s in (1, -1)]


def panel(slot: str, quad, s: tuple[float, float], t: tuple[float, float], inside, depth=(0.004, 0.014)) -> Part:
    """A thin plate on the face ``quad`` (4 corners, in order), covering the fraction ranges
    ``s`` (along corner 0→1) and ``t`` (along 0→3), raised ``depth`` m away from ``inside``."""
    q = np.asarray(quad, float)

    def at(a, b):
        return (1 - a) * (1 - b) * q[0] + a * (1 - b) * q[1] + a * b * q[2] + (1 - a) * b * q[3]
    ring = np.array([at(s[0], t[0]), at(s[1], t[0]), at(s[1], t[1]), at(s[0], t[1])])
    n = np.cross(q[1] - q[0], q[3] - q[0])
    n /= np.linalg.norm(n)
    if n @ (q.mean(0) - np.asarray(inside, float)) < 0:
        n = -n
    return loft(slot, [ring + depth[0] * n, ring + depth[1] * n])


def _greenhouse(p: dict, yr: float, yf_ws: float, hw: float) -> list[Part]:
    """Cabin above the belt line, with windshield, side and rear windows."""
    H, zb = p["height"], p["belt_height"] - 0.03
    y0, y1 = yr + p["deck_length"], yf_ws
    top0, top1 = y0 + p["rear_run"], y1 - p["windshield_run"]
    xb, xt = hw - 0.02, hw - 0.02 - p["tumblehome"]
    ring_b = [[xb, y0, zb], [xb, y1, zb], [-xb, y1, zb], [-xb, y0, zb]]
    ring_t = [[xt, top0, H], [xt, top1, H], [-xt, top1, H], [-xt, top0, H]]
    inside = [0.0, (y0 + y1) / 2, (zb + H) / 2]
    parts = [loft("body_paint", [ring_b, ring_t])]
    tw = 0.1 / (H - zb)
    front = [[xb, y1, zb], [-xb, y1, zb], [-xt, top1, H], [xt, top1, H]]
    rear = [[-xb, y0, zb], [xb, y0, zb], [xt, top0, H], [-xt, top0, H]]
    parts += [panel("glass", front, (0.05, 0.95), (tw, 0.92), inside),
              panel("glass", rear, (0.08, 0.92), (max(tw, 0.12), 0.88), inside)]
    n = p["side_windows"]
    span = (0.72, 0.97) if n == 1 else (0.05, 0.95) if p["deck_length"] > 0.05 else (0.05, 0.97)
    edges = np.linspace(*span, n + 1)
    for side in (1, -1):
        quad = [[side * xb, y0, zb], [side * xb, y1, zb], [side * xt, top1, H], [side * xt, top0, H]]
        for a, b in zip(edges[:-1], edges[1:]):
            parts.append(panel("glass", quad, (a + 0.02, b - 0.02), (tw + 0.04, 0.9), inside))
    return parts


def passenger_parts(p: dict) -> list[Part]:
    """Car or van: lower body, greenhouse, bumpers, lights, plates and four wheels."""
    L, W, c, r = p["length"], p["width"], p["clearance"], p["wheel_radius"]
    hw, yf, yr = W / 2 - 0.04, L / 2 - 0.02, -L / 2 + 0.02
    hood, belt, rear_belt = p["hood_height"], p["belt_height"], p["belt_height"] + 0.03
    y_ws = yf - p["hood_length"]
    profile = [(yr + 0.08, c), (yf - 0.15, c), (yf, c + 0.15), (yf, hood - 0.12), (yf - 0.12, hood),
               (y_ws, belt), (yr + 0.1, rear_belt), (yr, rear_belt - 0.12), (yr, c + 0.12)]
    parts = [prism("body_paint", profile, -hw, hw)]
    parts += _greenhouse(p, yr, y_ws, hw)
    bumper_z = (c + 0.02, c + 0.2)
    parts += [box("plastic_black", [-hw + 0.02, yf - 0.1, bumper_z[0]], [hw - 0.02, L / 2, bumper_z[1]]),
              box("plastic_black", [-hw + 0.02, -L / 2, bumper_z[0]], [hw - 0.02, yr + 0.1, bumper_z[1]]),
              box("plastic_black", [-hw + 0.42, yf - 0.03, hood - 0.3], [hw - 0.42, yf + 0.006, hood - 0.15]),
              box("license_plate", [-0.26, yf - 0.02, c + 0.22], [0.26, yf + 0.008, c + 0.33]),
              box("license_plate", [-0.26, yr - 0.008, c + 0.3], [0.26, yr + 0.02, c + 0.41])]
    for s in (1, -1):
        x0, x1 = s * (hw - 0.06), s * (hw - 0.38)
        parts += [box("headlight", [x0, yf - 0.05, hood - 0.24], [x1, yf + 0.012, hood - 0.13]),
                  box("taillight", [x0, yr - 0.012, rear_belt - 0.27], [x1, yr + 0.05, rear_belt - 0.15]),
                  box("body_paint", [s * (hw - 0.05), y_ws - 0.25, belt + 0.06], [s * W / 2, y_ws - 0.1, belt + 0.2])]
    for y in (L / 2 - p["front_overhang"], -L / 2 + p["rear_overhang"]):
        parts += _axle(W / 2, y, r, p["wheel_width"]) + wheel_arches(hw, y, r, c)
    return parts


def truck_parts(p: dict) -> list[Part]:
    """Cab-over box truck: cab, cargo box on a chassis, one front and two rear axles."""
    L, W, H, r = p["length"], p["width"], p["height"], p["wheel_radius"]
    hw, cab_h, floor = W / 2, H - p["cab_drop"], p["cargo_floor"]
    yf, y_cab, cab_z = L / 2, L / 2 - p["cab_length"], r + 0.1
    cab = [(y_cab, cab_z), (yf - 0.05, cab_z), (yf, cab_z + 0.1), (yf - 0.06, cab_h - 0.2),
           (yf - 0.3, cab_h), (y_cab, cab_h)]
    parts = [prism("body_paint", cab, -hw + 0.03, hw - 0.03),
             box("cargo_box", [-hw, -L / 2, floor], [hw, y_cab - 0.12, H]),
             box("plastic_black", [-0.5, -L / 2 + 0.3, r - 0.05], [0.5, yf - 0.4, floor]),
             box("plastic_black", [-hw + 0.05, yf - 0.12, cab_z - 0.15], [hw - 0.05, yf, cab_z + 0.15]),
             box("plastic_black", [-hw + 0.05, -L / 2, r - 0.1], [hw - 0.05, -L / 2 + 0.15, r + 0.05])]
    wz = (cab_h - 1.25, cab_h - 0.28)  # windshield band on the (nearly vertical) cab front
    slope = 0.06 / (cab_h - 0.2 - cab_z - 0.1)
    wy = [yf - slope * (z - cab_z - 0.1) for z in wz]
    windshield = [[hw - 0.03, wy[0], wz[0]], [-hw + 0.03, wy[0], wz[0]],
                  [-hw + 0.03, wy[1], wz[1]], [hw - 0.03, wy[1], wz[1]]]
    parts.append(panel("glass", windshield, (0.05, 0.95), (0.0, 1.0), [0.0, (y_cab + yf) / 2, cab_h / 2]))
    for s in (1, -1):
        parts.append(box("glass", [s * (hw - 0.04), yf - 0.9, wz[0]], [s * (hw - 0.015), yf - 0.25, wz[1]]))
        x0, x1 = s * (hw - 0.1), s * (hw - 0.35)
        parts += [box("headlight", [x0, yf - 0.13, cab_z - 0.05], [x1, yf, cab_z + 0.08]),
                  box("taillight", [x0, -L / 2, r + 0.1], [x1, -L / 2 + 0.16, r + 0.25])]
    parts += _axle(hw - 0.05, yf - 1.25, r, 0.3)
    for dy in (-0.68, 0.68):
        parts += _axle(hw - 0.05, -L / 2 + 1.9 + dy, r, 0.5)
    return parts


def _bus_sides(p: dict, hw: float, zb: float) -> list[Part]:
    """Side window band split by pillars; on the kerb side (+x) a front and a middle door."""
    L, H, wb = p["length"], p["height"], p["window_bottom"]
    edges = np.linspace(-L / 2 + 0.3, L / 2 - 0.25, max(5, int(round((L - 0.55) / 1.6))) + 1)
    middle = int(np.argmin(np.abs((edges[:-1] + edges[1:]) / 2)))
    parts = []
    for s in (1, -1):
        for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            door = s > 0 and i in (middle, len(edges) - 2)
            lo = [s * hw, a + 0.06, zb + 0.05 if door else wb]
            parts.append(box("glass", lo, [s * (hw + 0.012), b - 0.06, H - 0.35]))
    return parts


def bus_parts(p: dict) -> list[Part]:
    """City bus: rounded box body, window band with pillars, doors, three axles."""
    L, W, H, r = p["length"], p["width"], p["height"], p["wheel_radius"]
    hw, y0, y1, zb = W / 2 - 0.015, -L / 2 + 0.015, L / 2 - 0.015, 0.3
    wb = p["window_bottom"]
    profile = [(y0, zb), (y1 - 0.1, zb), (y1, zb + 0.15), (y1, H - 0.25), (y1 - 0.2, H),
               (y0 + 0.15, H), (y0, H - 0.15)]
    parts = [prism("body_paint", profile, -hw, hw),
             box("plastic_black", [-hw - 0.01, y0 + 0.05, zb], [hw + 0.01, y1 - 0.1, zb + 0.22])]
    inside = [0.0, 0.0, H / 2]
    front = [[hw, y1, wb - 0.25], [-hw, y1, wb - 0.25], [-hw, y1, H - 0.25], [hw, y1, H - 0.25]]
    rear = [[-hw, y0, wb], [hw, y0, wb], [hw, y0, H - 0.2], [-hw, y0, H - 0.2]]
    parts += [panel("glass", front, (0.03, 0.97), (0.0, 0.92), inside, depth=(0.0, 0.012)),
              panel("glass", rear, (0.1, 0.9), (0.05, 0.8), inside, depth=(0.0, 0.012))]
    parts += _bus_sides(p, hw, zb)
    for s in (1, -1):
        x0, x1 = s * (hw - 0.1), s * (hw - 0.4)
        parts += [box("headlight", [x0, y1 - 0.02, zb + 0.3], [x1, y1 + 0.012, zb + 0.45]),
                  box("taillight", [x0, y0 - 0.012, zb + 0.4], [x1, y0 + 0.02, zb + 0.8])]
    parts += _axle(hw + 0.01, y1 - 2.6, r, 0.3)
    for dy in (-0.7, 0.7):
        parts += _axle(hw + 0.01, y0 + 3.0 + dy, r, 0.45)
    return parts


SAMPLERS = {"car": sample_car, "van": sample_van, "truck": sample_truck, "bus": sample_bus}
BUILDERS = {"car": passenger_parts, "van": passenger_parts, "truck": truck_parts, "bus": bus_parts}

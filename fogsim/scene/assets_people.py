"""Pedestrians and cyclists as primitive parts.

Local frame: metres, origin at the centre of the ground footprint, z up, facing +y. Body
proportions scale with the standing height ``H`` (top of the hair); limbs are tapered tubes
posed by forward kinematics (walking) or two-bone IK (riding).
"""
from __future__ import annotations

import numpy as np

from fogsim.scene.assets_parts import (
    Part,
    blob,
    box,
    cylinder,
    draw,
    draw_choice,
    ellipse,
    loft,
    pick_colour,
    torus,
    tube,
)

SKIN = {"#f1c7a8": 3, "#e0ac8a": 3, "#c68863": 2, "#8d5a3c": 2, "#5c3a26": 1}
HAIR = {"#1a1410": 4, "#3b2618": 3, "#6b4a2b": 2, "#b08850": 1, "#8a8a88": 1}
TOPS = {"#1c1c1e": 4, "#2b3a55": 3, "#6e6e70": 2, "#e8e8e4": 2, "#7a1f24": 1, "#2f5a3a": 1,
        "#c9a36b": 1, "#3e6fb0": 1, "#d8c23a": 1, "#b3542d": 1}
BOTTOMS = {"#22304f": 4, "#151517": 4, "#4a4a4c": 2, "#8b7a5a": 1, "#3c4a34": 1}
#: standing proportions, fractions of the height: sole→ankle, thigh, shin, hip→neck, neck→top
ANKLE, THIGH, SHIN, NECK, HEAD_TOP = 0.045, 0.245, 0.23, 0.29, 0.19
SHOES = {"#141414": 4, "#e8e8e6": 2, "#4a3222": 2, "#5a5a5e": 1}
BIKES = {"#111213": 3, "#c8c8c6": 2, "#8c1515": 2, "#1d3a6e": 2, "#2f4f36": 1, "#e0b020": 1}


def sample_person(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """Body, hair, sleeves and clothing colours shared by pedestrians and riders."""
    height = float(np.clip(rng.normal(1.71, 0.1), 1.5, 1.95))
    p = {"height": float(c.pop("height")) if "height" in c else height,
         "shoulder": draw(rng, c, "shoulder", 0.2, 0.23), "hips": draw(rng, c, "hips", 0.3, 0.37),
         "hair": draw_choice(rng, c, "hair", ("short", "long", "bald"), (0.6, 0.3, 0.1)),
         "sleeves": draw_choice(rng, c, "sleeves", ("long", "short"), (0.7, 0.3)),
         "seed": int(rng.integers(0, 2 ** 31))}
    mats = {"skin": {"color": pick_colour(rng, SKIN)}, "hair": {"color": pick_colour(rng, HAIR)},
            "cloth_top": {"color": pick_colour(rng, TOPS, 0.15)},
            "cloth_bottom": {"color": pick_colour(rng, BOTTOMS, 0.1)},
            "shoe": {"color": pick_colour(rng, SHOES)}}
    return p, mats


def sample_pedestrian(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A person 1.5–1.95 m tall, standing or mid-stride (``stride`` degrees, 0–22)."""
    p, mats = sample_person(rng, c)
    walking, given = rng.random() < 0.75, "stride" in c
    stride = draw(rng, c, "stride", 8.0, 22.0)
    p["stride"] = stride if walking or given else 0.0
    p["lead"] = int(draw_choice(rng, c, "lead", (1, -1)))
    return p, mats


def sample_cyclist(rng: np.random.Generator, c: dict) -> tuple[dict, dict]:
    """A bicycle (wheel radius 0.33–0.35 m, wheelbase 1–1.1 m) with a seated rider."""
    p, mats = sample_person(rng, c)
    p.update(wheel_radius=draw(rng, c, "wheel_radius", 0.33, 0.35), wheelbase=draw(rng, c, "wheelbase", 1.0, 1.1),
             crank=draw(rng, c, "crank", 0.0, 360.0))
    mats["bike_frame"] = {"color": pick_colour(rng, BIKES)}
    return p, mats


# --------------------------------------------------------------------------- body parts
def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _down(angle_deg: float, out: float = 0.0) -> np.ndarray:
    """Unit vector hanging down, swung forward (+y) by ``angle_deg`` and out (x) by ``out``."""
    a = np.radians(angle_deg)
    return _unit([out, np.sin(a), -np.cos(a)])


def two_bone(root, target, l1: float, l2: float, pole) -> tuple[np.ndarray, np.ndarray]:
    """(joint, end) of a two-segment limb from ``root`` reaching toward ``target``, bending
    toward ``pole``; the end stops short when the target is out of reach."""
    root, d = np.asarray(root, float), np.asarray(target, float) - root
    dist = float(np.clip(np.linalg.norm(d), abs(l1 - l2) + 1e-3, 0.995 * (l1 + l2)))
    dn = _unit(d)
    a = (l1 ** 2 + dist ** 2 - l2 ** 2) / (2 * dist)
    p = np.asarray(pole, float) - (np.asarray(pole, float) @ dn) * dn
    return root + a * dn + np.sqrt(max(l1 ** 2 - a ** 2, 0.0)) * _unit(p), root + dist * dn


def _tilt(points: np.ndarray, origin, lean_deg: float) -> np.ndarray:
    """Rotate points about the x axis through ``origin`` so that +z leans toward +y."""
    a = np.radians(lean_deg)
    R = np.array([[1, 0, 0], [0, np.cos(a), np.sin(a)], [0, -np.sin(a), np.cos(a)]])
    return (points - origin) @ R.T + origin


def torso(p: dict, pelvis, lean: float) -> tuple[list[Part], np.ndarray, np.ndarray]:
    """Hips (cloth_bottom) and chest (cloth_top) around an axis leaning ``lean`` degrees
    forward from ``pelvis``; returns the parts, the two shoulder joints and the neck base."""
    H, sw, hw = p["height"], p["shoulder"], p["hips"] / 2
    pelvis = np.asarray(pelvis, float)

    def rings(spec):
        return [_tilt(ellipse(pelvis + [0, 0, u * H], a, b * H), pelvis, lean) for u, a, b in spec]
    bottom = rings([(-0.05, 0.75 * hw, 0.045), (0.0, hw, 0.06), (0.1, 0.9 * hw, 0.056)])
    top = rings([(0.08, 0.9 * hw, 0.056), (0.19, sw - 0.02 * H, 0.066), (0.262, sw - 0.01 * H, 0.06),
                 (0.295, 0.5 * sw, 0.042)])
    joints = _tilt(np.array([[s * (sw - 0.022 * H), 0.0, 0.262 * H] for s in (1, -1)]) + pelvis, pelvis, lean)
    neck = _tilt(pelvis[None] + [0, 0, NECK * H], pelvis, lean)[0]
    return [loft("cloth_bottom", bottom), loft("cloth_top", top)], joints, neck


def head(p: dict, neck) -> list[Part]:
    """Neck, upright head and hair above the neck base, the top ``HEAD_TOP``·H above it; face +y."""
    H, seed = p["height"], p["seed"]
    top_z = neck[2] + HEAD_TOP * H
    r = np.array([0.046, 0.056, 0.064]) * H
    hair_r, hair_dz = r * [1.1, 1.05, 1.04], 0.012 * H
    c = np.array([neck[0], neck[1] + 0.012 * H, top_z - (hair_dz + hair_r[2] if p["hair"] != "bald" else r[2])])
    parts = [cylinder("skin", neck - [0, 0, 0.01 * H], c - [0, 0.01 * H, 0.03 * H], 0.024 * H, n=8),
             blob("skin", c, r, seed)]
    if p["hair"] != "bald":
        parts.append(blob("hair", c + [0, -0.012 * H, hair_dz], hair_r, seed + 1, 0.04))
    if p["hair"] == "long":
        parts.append(blob("hair", c + [0, -0.03 * H, -0.07 * H], [0.045 * H, 0.03 * H, 0.08 * H], seed + 2, 0.05, 1))
    return parts


def arm(p: dict, shoulder, elbow, wrist) -> list[Part]:
    """Sleeved upper arm, forearm (sleeve or skin) and hand."""
    H = p["height"]
    fore = "cloth_top" if p["sleeves"] == "long" else "skin"
    hand = wrist + 0.032 * H * _unit(wrist - elbow)
    return [tube("cloth_top", [shoulder, elbow], [0.032 * H, 0.026 * H], n=10),
            tube(fore, [elbow, wrist], [0.025 * H, 0.019 * H], n=10),
            blob("skin", hand, [0.017 * H, 0.024 * H, 0.03 * H], p["seed"] + 3, 0.0, 1)]


def leg(p: dict, hip, knee, ankle, planted: bool) -> list[Part]:
    """Trouser leg and a shoe whose sole is flat (at z = 0 when ``planted``)."""
    H = p["height"]
    sole = 0.0 if planted else ankle[2] - 0.045 * H
    shoe = box("shoe", [ankle[0] - 0.028 * H, ankle[1] - 0.04 * H, sole],
               [ankle[0] + 0.028 * H, ankle[1] + 0.11 * H, ankle[2] + 0.012 * H])
    return [tube("cloth_bottom", [hip, knee, ankle], [0.047 * H, 0.031 * H, 0.022 * H], n=10), shoe]


# --------------------------------------------------------------------------- assets


def pedestrian_parts(p: dict) -> list[Part]:
    """A walking (or standing) person: legs swing ±stride, arms counter-swing."""
    H, theta, lead = p["height"], p["stride"], p["lead"]
    T, S = THIGH * H, SHIN * H
    angles = {s: ((theta, theta) if s == lead else (-0.6 * theta, -1.3 * theta)) for s in (1, -1)}
    drops = {s: T * np.cos(np.radians(a)) + S * np.cos(np.radians(b)) for s, (a, b) in angles.items()}
    hip_z = ANKLE * H + max(drops.values())
    parts, hip_x = [], p["hips"] / 2 - 0.048 * H
    for s, (a, b) in angles.items():
        hip = np.array([s * hip_x, 0.0, hip_z])
        knee = hip + T * _down(a)
        ankle = knee + S * _down(b)
        parts += leg(p, hip, knee, ankle, planted=drops[s] == max(drops.values()))
    body, shoulders, neck = torso(p, [0.0, 0.0, hip_z], 3.0)
    parts += body + head(p, neck)
    for s, sh in zip((1, -1), shoulders):
        swing = 0.9 * theta * (-1 if s == lead else 1)
        elbow = sh + 0.17 * H * _down(swing, 0.12 * s)
        parts += arm(p, sh, elbow, elbow + 0.155 * H * _down(swing + 15.0, 0.05 * s))
    return parts


def bicycle(p: dict, saddle_dist: float) -> tuple[list[Part], dict]:
    """Bicycle frame, wheels, saddle, bars and cranks; returns the parts and the contact
    points (saddle top, grips, pedals) the rider is posed against."""
    rw, wb = p["wheel_radius"], p["wheelbase"]
    R, F = np.array([0.0, -wb / 2, rw]), np.array([0.0, wb / 2, rw])
    bb = np.array([0.0, -wb / 2 + 0.43, 0.29])
    st = np.array([0.0, -np.cos(np.radians(73)), np.sin(np.radians(73))])
    seat, saddle = bb + 0.5 * st, bb + saddle_dist * st
    hb = F + 0.42 * np.array([0.0, -np.cos(np.radians(72)), np.sin(np.radians(72))])
    ht = hb + 0.16 * np.array([0.0, -np.cos(np.radians(72)), np.sin(np.radians(72))])
    bar = ht + [0.0, -0.05, 0.16]
    parts = [cylinder("bike_frame", a, b, r, n=8) for a, b, r in
             [(bb, seat, 0.018), (seat, ht, 0.017), (bb, hb, 0.02), (hb, ht, 0.022), (hb, F, 0.014)]]
    for x in (0.045, -0.045):
        parts += [cylinder("bike_frame", bb + [x * 0.5, 0, 0], R + [x, 0, 0], 0.011, n=8),
                  cylinder("bike_frame", seat + [x * 0.4, 0, 0], R + [x, 0, 0], 0.01, n=8)]
    parts += [cylinder("rim", seat, saddle - [0, 0, 0.03], 0.013, n=8), cylinder("rim", ht, bar, 0.014, n=8),
              cylinder("rim", bar + [-0.23, 0, 0], bar + [0.23, 0, 0], 0.012, n=8),
              box("plastic_black", saddle + [-0.075, -0.15, -0.05], saddle + [0.075, 0.11, 0.0])]
    for x in (0.23, -0.23):
        parts.append(cylinder("plastic_black", bar + [0.75 * x, 0, 0], bar + [x * 1.06, 0, 0], 0.018, n=8))
    for hub in (R, F):
        parts += [torus("tyre", hub, [1, 0, 0], rw - 0.018, 0.018, 24, 6),
                  torus("rim", hub, [1, 0, 0], rw - 0.045, 0.01, 24, 4),
                  cylinder("rim", hub - [0.05, 0, 0], hub + [0.05, 0, 0], 0.025, n=8)]
    a = np.radians(p["crank"])
    pedals = []
    for s, sign in ((1, 1), (-1, -1)):
        tip = bb + sign * 0.17 * np.array([0.0, np.cos(a), np.sin(a)]) + [s * 0.09, 0, 0]
        parts += [cylinder("rim", bb + [s * 0.06, 0, 0], tip, 0.012, n=6),
                  box("plastic_black", tip + [s * 0.01, -0.05, -0.012], tip + [s * 0.11, 0.05, 0.012])]
        pedals.append(tip + [s * 0.05, 0.0, 0.0])
    parts.append(cylinder("rim", bb + [0.04, 0, 0], bb + [0.055, 0, 0], 0.1, n=16))
    grips = [bar + [s * 0.2, 0, 0] for s in (1, -1)]
    return parts, {"saddle": saddle, "grips": grips, "pedals": pedals}


def cyclist_parts(p: dict) -> list[Part]:
    """Bicycle plus a rider seated on the saddle, hands on the grips, feet on the pedals."""
    H = p["height"]
    T, S = THIGH * H, SHIN * H
    saddle_dist = 0.96 * (T + S) - 0.17 - 0.06
    parts, touch = bicycle(p, saddle_dist)
    pelvis = touch["saddle"] + [0.0, 0.02, 0.06]
    reach = 0.93 * 0.325 * H
    mid_grip = (touch["grips"][0] + touch["grips"][1]) / 2
    leans = np.arange(5.0, 70.0, 0.5)
    shoulder_mid = [_tilt(pelvis[None] + [0, 0, 0.262 * H], pelvis, a)[0] for a in leans]
    lean = float(leans[int(np.argmin([abs(np.linalg.norm(mid_grip - s) - reach) for s in shoulder_mid]))])
    body, shoulders, neck = torso(p, pelvis, lean)
    parts += body + head(p, neck)
    for sh, grip in zip(shoulders, touch["grips"]):
        elbow, wrist = two_bone(sh, grip - [0, 0.03 * H, 0], 0.17 * H, 0.155 * H, [0, -0.3, -1])
        parts += arm(p, sh, elbow, wrist)
    for s, pedal in zip((1, -1), touch["pedals"]):
        hip = pelvis + [s * (p["hips"] / 2 - 0.048 * H), 0, 0]
        knee, ankle = two_bone(hip, pedal + [0, -0.03, 0.05], T, S, [0, 1, 0.2])
        parts += leg(p, hip, knee, ankle, planted=False)
    return parts


SAMPLERS = {"pedestrian": sample_pedestrian, "cyclist": sample_cyclist}
BUILDERS = {"pedestrian": pedestrian_parts, "cyclist": cyclist_parts}

"""Seeded street layouts: where the road, buildings, vehicles and people go.

:func:`sample_scene` returns the JSON scene description the renderer builds (see
:mod:`fogsim.scene.geometry` for the object record). All randomness comes from the
``numpy.random.Generator`` passed in. The street runs along +y with right-hand traffic:
our lanes at x > 0 heading +y, oncoming lanes at x < 0 heading −y, then parking, curb,
sidewalk (top at :data:`SIDEWALK_HEIGHT`) and buildings on each side.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.camera import Intrinsics
from fogsim.scene.assets import asset_extent, sample_asset
from fogsim.scene.lights import apply_night, night_settings
from fogsim.scene.pose import camera_to_world, transform, world_to_camera
from fogsim.scene.sky import apply_sky
from fogsim.schema.presets import DAY_SKY_STRENGTH

SIDEWALK_HEIGHT = 0.15
VERSION = 1


class _Occupancy:
    """Axis-aligned footprints already taken (x0, x1, y0, y1), for rejection sampling."""

    def __init__(self):
        self.boxes: list[tuple[float, float, float, float]] = []

    def free(self, box, margin: float = 0.3) -> bool:
        x0, x1, y0, y1 = box
        return all(x1 + margin <= a or b <= x0 - margin or y1 + margin <= c or d <= y0 - margin
                   for a, b, c, d in self.boxes)

    def take(self, box) -> None:
        self.boxes.append(box)


def _footprint(spec: dict, x: float, y: float, yaw_deg: float, extent=None):
    """Axis-aligned (x0, x1, y0, y1) of the asset's box turned by ``yaw_deg`` at (x, y)."""
    sx, sy, _ = extent or asset_extent(spec)
    c, s = abs(math.cos(math.radians(yaw_deg))), abs(math.sin(math.radians(yaw_deg)))
    hx, hy = (sx * c + sy * s) / 2, (sx * s + sy * c) / 2
    return (x - hx, x + hx, y - hy, y + hy)


class _Builder:
    def __init__(self, rng: np.random.Generator, library=None):
        self.rng, self.objects, self.occupied, self.library = rng, [], _Occupancy(), library
        self._last: tuple[dict | None, tuple] = (None, ())  # (spec, extent): retries reuse it

    def asset(self, cls: str) -> dict:
        """A model of ``cls``: one of the asset library's (:mod:`fogsim.scene.library`), else procedural."""
        picked = self.library.pick(cls, self.rng) if self.library is not None else None
        return picked or sample_asset(cls, self.rng)

    def add(self, cls: str, asset: dict, x: float, y: float, z: float = 0.0, yaw: float = 0.0) -> dict:
        obj = {"id": len(self.objects) + 1, "class": cls, "asset": asset,
               "transform": transform([x, y, z], yaw).tolist()}
        self.objects.append(obj)
        return obj

    def place(self, cls: str, spec: dict, x: float, y: float, z: float, yaw: float,
              margin: float = 0.3) -> bool:
        """Add ``spec`` at (x, y, z) turned by ``yaw`` if its footprint is free."""
        if self._last[0] is not spec:
            self._last = (spec, asset_extent(spec))
        box = _footprint(spec, x, y, yaw, self._last[1])
        if not self.occupied.free(box, margin):
            return False
        self.occupied.take(box)
        self.add(cls, spec, x, y, z, yaw)
        return True


def _uniform(rng, lo_hi) -> float:
    lo, hi = lo_hi
    return float(rng.uniform(lo, hi))


def _count(rng, lo_hi) -> int:
    lo, hi = lo_hi
    return int(rng.integers(lo, hi + 1))


def _boxes(material: str, boxes: list) -> dict:
    return {"type": "boxes", "params": {"material": material, "boxes": [[float(v) for v in b] for b in boxes]}}


def street_geometry(b: _Builder, st: dict) -> None:
    """Road, terrain, curbs, sidewalks and lane markings (one object per kind)."""
    L, n, lw = st["length"], st["lanes"], st["lane_width"]
    curb, sw = st["curb_x"], st["sidewalk_width"]
    y0, y1 = -30.0, L + 30.0
    cy, ly = (y0 + y1) / 2, y1 - y0
    b.add("road", _boxes("asphalt", [[0, cy, -0.3, 2 * curb, ly, 0.3]]), 0, 0)
    b.add("sidewalk", _boxes("sidewalk", [[s * (curb + sw / 2), cy, 0, sw, ly, SIDEWALK_HEIGHT]
                                          for s in (-1, 1)]
                                + [[s * (curb + sw + 30.0), cy, -0.3, 60.0, ly, 0.3 + SIDEWALK_HEIGHT - 0.02]
                                   for s in (-1, 1)]), 0, 0)
    b.add("curb", _boxes("curb", [[s * (curb + 0.1), cy, 0, 0.2, ly, SIDEWALK_HEIGHT + 0.01]
                                  for s in (-1, 1)]), 0, 0)
    marks = []
    for side in (-1, 1):
        marks.append([side * 0.12, cy, 0, 0.12, ly, 0.005])                 # double centre line
        marks.append([side * (n * lw - 0.1), cy, 0, 0.15, ly, 0.005])        # edge line
        for i in range(1, n):                                                # dashed lane lines
            for ys in np.arange(y0, y1, 12.0):
                marks.append([side * i * lw, ys + 1.5, 0, 0.15, 3.0, 0.005])
    for yc in st["crosswalks"]:
        for xs in np.arange(-n * lw + 0.5, n * lw, 1.0):
            marks.append([xs, yc, 0, 0.5, 4.0, 0.005])
    b.add("lane_marking", _boxes("lane_paint", marks), 0, 0)


def buildings(b: _Builder, st: dict, style: dict) -> None:
    rng = b.rng
    for side in (-1, 1):
        y = -25.0
        while y < st["length"] + 20:
            width = _uniform(rng, style["building_width"])
            if rng.random() < style["building_gap"]:
                y += width * 0.6
                continue
            depth = _uniform(rng, style["building_depth"])
            height = _uniform(rng, style["building_height"])
            spec = sample_asset("building", rng, width=width, depth=depth, height=height)
            x = side * (st["curb_x"] + st["sidewalk_width"] + _uniform(rng, style["setback"]) + depth / 2)
            b.add("building", spec, x, y + width / 2, SIDEWALK_HEIGHT - 0.02, 90.0 * side)
            y += width + float(rng.uniform(0.0, 0.6))


def vehicles(b: _Builder, st: dict, style: dict) -> None:
    rng, n, lw = b.rng, st["lanes"], st["lane_width"]
    kinds = list(style["vehicle_mix"])
    probs = np.array([style["vehicle_mix"][k] for k in kinds], float)
    probs /= probs.sum()
    if st["parking_width"] > 0:
        for side in (-1, 1):
            y = float(rng.uniform(-5, 2))
            while y < st["length"]:
                kind = str(rng.choice(["car", "car", "car", "van"]))
                spec = b.asset(kind)
                length = asset_extent(spec)[1]
                if rng.random() < style["parked_probability"]:
                    x = side * (n * lw + st["parking_width"] / 2) + float(rng.normal(0, 0.1))
                    b.place(kind, spec, x, y + length / 2, 0.0, 0.0 if side > 0 else 180.0)
                y += length + float(rng.uniform(0.8, 3.0))
    for _ in range(_count(rng, style["driving"])):
        kind = str(rng.choice(kinds, p=probs))
        spec = b.asset(kind)
        for _try in range(20):
            lane = int(rng.integers(0, 2 * n))
            side = 1 if lane < n else -1
            x = side * (lw * (lane % n + 0.5)) + float(rng.normal(0, 0.15))
            y = float(rng.uniform(-8, st["length"]))
            if abs(x - st["camera_x"]) < lw / 2 and y < 9.0:
                continue  # keep the ego lane clear just ahead of the camera
            if b.place(kind, spec, x, y, 0.0, (0.0 if side > 0 else 180.0) + float(rng.normal(0, 1.5)), 1.5):
                break


def people(b: _Builder, st: dict, style: dict) -> None:
    rng, curb, sw = b.rng, st["curb_x"], st["sidewalk_width"]
    for _ in range(_count(rng, style["pedestrians"])):
        spec = b.asset("pedestrian")
        for _try in range(20):
            if st["crosswalks"] and rng.random() < 0.2:  # crossing the street
                x = float(rng.uniform(-curb + 0.5, curb - 0.5))
                y, z, yaw = st["crosswalks"][0] + float(rng.uniform(-1.5, 1.5)), 0.0, float(rng.choice([90.0, -90.0]))
            else:
                side = float(rng.choice([-1.0, 1.0]))
                x = side * (curb + float(rng.uniform(0.5, sw - 0.5)))
                y, z = float(rng.uniform(0, st["length"] * 0.8)), SIDEWALK_HEIGHT
                yaw = float(rng.choice([0.0, 180.0])) + float(rng.normal(0, 15))
            if b.place("pedestrian", spec, x, y, z, yaw, 0.2):
                break
    n, lw = st["lanes"], st["lane_width"]
    for _ in range(_count(rng, style["cyclists"])):
        spec = b.asset("cyclist")
        side = float(rng.choice([-1.0, 1.0]))
        x, y = side * (n * lw - 0.9), float(rng.uniform(6, st["length"] * 0.7))
        b.place("cyclist", spec, x, y, 0.0, 0.0 if side > 0 else 180.0, 0.5)


def street_furniture(b: _Builder, st: dict, style: dict) -> None:
    rng, curb = b.rng, st["curb_x"]
    for side in (-1, 1):
        yaw_to_road = 90.0 * side
        if style["pole_spacing"] > 0:
            for y in np.arange(float(rng.uniform(0, style["pole_spacing"])), st["length"], style["pole_spacing"]):
                b.place("pole", sample_asset("pole", rng), side * (curb + 0.5), float(y), SIDEWALK_HEIGHT,
                        yaw_to_road, 0.1)
        if style["tree_spacing"] > 0:
            for y in np.arange(float(rng.uniform(0, style["tree_spacing"])), st["length"], style["tree_spacing"]):
                x = side * (curb + st["sidewalk_width"] - 1.0)
                b.place("tree", sample_asset("tree", rng), x, float(y) + float(rng.normal(0, 1)), SIDEWALK_HEIGHT,
                        float(rng.uniform(0, 360)), 0.2)
        for yc in st["crosswalks"]:
            b.place("traffic_light", b.asset("traffic_light"), side * (curb + 0.6),
                    yc - side * 3.0, SIDEWALK_HEIGHT, 0.0 if side < 0 else 180.0, 0.1)
    for _ in range(_count(rng, style["signs"])):
        side = float(rng.choice([-1.0, 1.0]))
        y = float(rng.uniform(8, st["length"] * 0.7))
        b.place("traffic_sign", b.asset("traffic_sign"), side * (curb + 0.4), y, SIDEWALK_HEIGHT,
                180.0 if side > 0 else 0.0, 0.1)


def camera_intrinsics(camera: dict, resolution: tuple[int, int] | None = None) -> Intrinsics:
    """Intrinsics of a camera preset (``fx`` or ``hfov_deg``) at ``resolution`` (W, H).

    The horizontal field of view is kept and pixels stay square (a renderer needs them), so
    a resolution of another aspect ratio crops or extends the image vertically around the
    centre (640×426 from 1920×1280 differs by 2/3 of a row).
    """
    w, h = resolution or (camera["width"], camera["height"])
    fx = camera["fx"] * w / camera["width"] if "fx" in camera else Intrinsics.from_hfov(camera["hfov_deg"], w, h).fx
    return Intrinsics(fx, fx, (w - 1) / 2, (h - 1) / 2, w, h)


def sample_scene(rng: np.random.Generator, style: dict, camera: dict,
                 resolution: tuple[int, int] | None = None, seed: int | None = None,
                 lighting: dict | None = None, library=None) -> dict:
    """A random street of ``style`` seen from ``camera`` (presets as dicts); JSON-serialisable.

    ``library``: the run's :class:`fogsim.scene.library.AssetLibrary` (the user's models), or None.

    ``lighting``: the preset's lighting object; ``{"time_of_day": "night"}`` adds street lamps,
    vehicle lights and lit windows to the same street (:func:`fogsim.scene.lights.apply_night`),
    day (the default) leaves the description as it always was.
    """
    n, lw = style["lanes_per_direction"], style["lane_width"]
    pw = style["parking_width"]
    st = {"length": float(style["street_length"]), "lanes": n, "lane_width": lw, "parking_width": pw,
          "curb_x": n * lw + pw, "sidewalk_width": _uniform(rng, style["sidewalk_width"])}
    ego_lane = int(rng.integers(0, n))
    st["camera_x"] = lw * (ego_lane + 0.5) + float(rng.normal(0, 0.2))
    st["crosswalks"] = ([float(rng.uniform(15, 60))] if rng.random() < style["crosswalk_probability"] else [])
    b = _Builder(rng, library)
    street_geometry(b, st)
    buildings(b, st, style)
    street_furniture(b, st, style)
    vehicles(b, st, style)
    people(b, st, style)
    K = camera_intrinsics(camera, resolution)
    yaw, pitch, roll = (_uniform(rng, camera[k]) for k in ("yaw_deg", "pitch_deg", "roll_deg"))
    position = [st["camera_x"], 0.0, camera["height_m"]]
    c2w = camera_to_world(position, yaw, pitch, roll)
    elevation = _uniform(rng, style["sun_elevation_deg"])
    desc = {
        "version": VERSION, "seed": seed, "style": style["name"], "street": st,
        "camera": {"preset": camera["name"], "intrinsics": K.to_dict(), "position": position,
                   "yaw_deg": yaw, "pitch_deg": pitch, "roll_deg": roll,
                   "world_to_camera": world_to_camera(c2w).tolist(),
                   "convention": "OpenCV: x right, y down, z forward; world z up, metres"},
        "lighting": {"sun_elevation_deg": elevation, "sun_azimuth_deg": float(rng.uniform(0, 360)),
                     "sun_strength": 3.0 + 2.0 * math.sin(math.radians(elevation)),
                     "sky_strength": DAY_SKY_STRENGTH},
        "objects": b.objects,
    }
    if night_settings(lighting):
        return apply_night(desc, lighting, rng)
    return apply_sky(desc, lighting, rng)  # a day sky other than the default: HDRI, overcast (fogsim.scene.sky)

"""A synthetic LiDAR sweep of a rendered frame: rays cast against exactly the triangles the renderer drew.

The frame's geometry (:class:`Geometry`) is every triangle of the meshes the renderer builds (procedural:
:attr:`fogsim.render.frame.DescribedFrame.meshes`, world metres; scene mode: the realised meshes of the
user's scene, :mod:`fogsim.render.blender.realise`), each with the mask id of its object (0 = background)
and a reflectivity. :func:`sweep` casts one ray per beam and azimuth step of a spinning sensor
(:class:`fogsim.lidar.sensors.LidarSensor`) from its pose in the world, with Intel Embree (``embreex``:
131 k rays in ≈ 30 ms on one core, against ≈ 0.4 s for Blender's ``BVHTree.ray_cast`` in a Python loop —
``fogsim bench render`` measures both), and returns the points the sensor reports in clear air.

Conventions: the sensor frame is x forward, y left, z up (metres); azimuth φ is measured from x towards y,
the beams' inclinations from the horizontal plane (up positive). A ray starts at its laser (the sensor's
origin, or — a sensor with ``vertical_offsets_m``, KITTI's HDL-64E — h·(−sin θ cos φ, −sin θ sin φ, cos θ):
:meth:`~fogsim.lidar.sensors.LidarSensor.beam_origins`); its range R is its distance from there to the first
triangle it hits; the point is p = o + R·d in the sensor frame, exactly on the surface. Per point: the range,
azimuth, beam (ring), the object it hit, the incidence angle θ between the ray and the surface normal, the
surface's reflectivity ρ, and the intensity the sensor reports for the Lambertian return of apparent
reflectivity ρ·cos θ at R (:meth:`~fogsim.lidar.sensors.LidarSensor.intensity_of`, in its intensity scale). A
ray is reported when it hits within [min range, max range] and its clear-air signal
(ρ·cos θ/ρ_ref)·(R_max/R)²·ξ(R) reaches the detection threshold (1): dark, grazing or far surfaces drop out as
on a real sensor. Every point of one sweep is taken at one instant (no rolling-shutter motion).

Reflectivity (at 905 nm, diffuse, Lambertian-equivalent): from the 905 nm table of
:mod:`fogsim.scene.reflectivity`, never from the visible colour — each material slot its entry, car paint by
the colour family of the instance's colour, every spread drawn once per object
(:func:`~fogsim.scene.reflectivity.instance_reflectivity`: frame seed, object id, slot), a library model's
materials by their names and kinds (``library:<name>`` slots, :func:`~fogsim.scene.reflectivity.material_entry`:
its own ``fogsim_reflectivity``, transmissive as glass, the name's keywords, a paint's colour; else the stated
fallback). In scene mode a ``fogsim_reflectivity`` custom property on the material or the
object wins (:mod:`fogsim.render.blender.realise`), then the material's name, then the fallback.

Speed (one core): each sensor builds its own Embree scene of only what its rays can meet — the parts within
its range (:meth:`Geometry.of_frame`'s ``within``), then the triangles not wholly above its top beam, below
its bottom one or outside its field of view (:meth:`Geometry.seen_from`, exact; :func:`sensor_caster`) —
Embree builds without its robust mode, rays stop at the maximum range, the surface normal comes from
Embree's hit record, the sweep's directions are computed once per sensor.
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import EmptyRays
from fogsim.lidar.scales import scale as scale_named
from fogsim.lidar.sensors import LidarSensor
from fogsim.scene.library import LIBRARY_SLOT
from fogsim.scene.materials import MATERIALS
from fogsim.scene.reflectivity import instance_reflectivity, material_entry, slot_entry


def surface_reflectivity(name: str | None, transmission: float = 0.0, colour=None) -> tuple[float, str]:
    """(ρ at 905 nm, the rule) of a user's material (scene mode) known by its name, transmission and base
    colour (linear RGB; a paint's family): :func:`~fogsim.scene.reflectivity.material_entry`'s median."""
    entry, rule = material_entry(name, transmission, colour)
    return entry.rho, rule


def _salt(slot: str) -> int:
    return zlib.crc32(slot.encode())


def slot_reflectivity(obj: dict, slot: str, seed: int = 0) -> float:
    """ρ (905 nm) of one material slot of a procedural object: the table's entry (``body_paint``: the family
    of the instance's colour; a ``library:<name>`` slot: by its material's name, transmission, colour or own
    value, :func:`~fogsim.scene.reflectivity.material_entry`, as the asset's ``materials[slot]`` records them),
    its spread drawn for this object (``seed``: the frame's)."""
    if slot == LIBRARY_SLOT or slot.startswith(LIBRARY_SLOT + ":"):  # what the model's file said of it
        info = obj.get("asset", {}).get("materials", {}).get(slot, {})
        entry, _ = material_entry(slot[len(LIBRARY_SLOT) + 1:] or None, float(info.get("transmission", 0.0)),
                                  info.get("color"), info.get("reflectivity"))
    else:
        override = obj.get("asset", {}).get("materials", {}).get(slot, {})
        colour = override.get("color", MATERIALS[slot]["color"]) if slot in MATERIALS else None
        entry = slot_entry(slot, colour)
    return instance_reflectivity(entry, seed, int(obj.get("id", 0)), _salt(slot))


@dataclass(frozen=True)
class Geometry:
    """The frame's triangles in the world (metres): ``vertices`` V×3 float32, ``faces`` F×3 int32, and
    per face the mask id of its object (``face_id``, 0 = background) and its reflectivity (``face_rho``)."""

    vertices: np.ndarray
    faces: np.ndarray
    face_id: np.ndarray
    face_rho: np.ndarray

    @classmethod
    def from_parts(cls, parts) -> "Geometry":
        """From ``(vertices N×3, faces F×3, object id, reflectivity: a number or one per face)`` parts."""
        parts = [(np.asarray(v, np.float32).reshape(-1, 3), np.asarray(f).reshape(-1, 3), oid, rho)
                 for v, f, oid, rho in parts]
        parts = [p for p in parts if len(p[1])]
        if not parts:
            return cls(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros(0, np.int32),
                       np.zeros(0, np.float32))
        nv = np.array([len(p[0]) for p in parts], np.int64)
        nf = np.array([len(p[1]) for p in parts], np.int64)
        offset = np.repeat(np.concatenate([[0], np.cumsum(nv)[:-1]]), nf).astype(np.int32)
        faces = np.concatenate([p[1] for p in parts]).astype(np.int32) + offset[:, None]
        ids = np.repeat(np.array([int(p[2]) for p in parts], np.int32), nf)
        if all(np.ndim(p[3]) == 0 for p in parts):
            rho = np.repeat(np.array([float(p[3]) for p in parts], np.float32), nf)
        else:
            rho = np.concatenate([np.broadcast_to(np.asarray(p[3], np.float32), (len(p[1]),)) for p in parts])
        return cls(np.concatenate([p[0] for p in parts]), faces, ids, rho)

    @classmethod
    def of_frame(cls, desc: dict, meshes: dict, within: tuple | None = None) -> "Geometry":
        """The procedural frame's geometry: every object's world parts (:func:`fogsim.render.frame.scene_meshes`),
        each slot's reflectivity from the 905 nm table (:func:`slot_reflectivity`, the frame's seed).
        ``within`` = (origin xyz, radius m): only the parts whose bounding sphere reaches that close (a ray
        from the origin that hits nothing of them within the radius hits nothing there at all)."""
        by_id = {o["id"]: o for o in desc["objects"]}
        seed = int(desc.get("seed") or 0)
        rho: dict = {}  # (object, slot) → ρ: an object's parts of one slot share its draw
        parts = []
        for oid, obj_parts in meshes.items():
            for v, f, slot in obj_parts:
                if len(v) and len(f):
                    if (oid, slot) not in rho:
                        rho[oid, slot] = slot_reflectivity(by_id[oid], slot, seed)
                    parts.append((v, f, oid, rho[oid, slot]))
        if within is not None and parts:  # each part's bounding box, all at once
            vertices = np.concatenate([np.asarray(p[0], np.float64).reshape(-1, 3) for p in parts])
            starts = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
            lo, hi = np.minimum.reduceat(vertices, starts), np.maximum.reduceat(vertices, starts)
            centre = (lo + hi) / 2
            gap = (np.sqrt(((centre - np.asarray(within[0], np.float64)) ** 2).sum(-1))
                   - np.sqrt(((hi - centre) ** 2).sum(-1)))
            parts = [p for p, g in zip(parts, gap) if g <= within[1]]
        return cls.from_parts(parts)

    def subset(self, keep: np.ndarray) -> "Geometry":
        """The faces where ``keep`` (F bool) holds, with only the vertices they use."""
        faces = self.faces[keep]
        used = np.zeros(len(self.vertices), bool)
        used[faces.reshape(-1)] = True
        remap = (np.cumsum(used, dtype=np.int32) - 1).astype(np.int32)
        return Geometry(self.vertices[used], remap[faces], self.face_id[keep], self.face_rho[keep])

    def seen_from(self, pose: np.ndarray, elevation_deg: tuple | None = None, azimuth_deg: tuple | None = None,
                  max_range_m: float | None = None, margin_deg: float = 0.05,
                  heights_m: tuple[float, float] = (0.0, 0.0)) -> "Geometry":
        """Only the triangles a sensor at ``pose`` (sensor → world, 4×4; x forward, y left, z up) can meet with
        rays of inclination within ``elevation_deg`` (lo, hi), azimuth within ``azimuth_deg`` (lo, hi; None:
        360°) that stop at ``max_range_m``, each widened by ``margin_deg``. Exact (no triangle a ray meets is
        dropped): a triangle is dropped when its three corners lie in one convex region no ray enters — above
        the top beam's cone (hi ≥ 0: {z ≥ tan(hi)·ρ + b_hi} is convex), below the bottom one's (lo ≤ 0,
        {z ≤ tan(lo)·ρ + b_lo}), beyond one side of a wedge narrower than 180°, or farther than the range (a
        corner's distance less the longest edge). ``heights_m`` (b_lo, b_hi): the lowest and highest height at
        which the rays' lines cross the sensor's axis — 0 when every ray starts at the origin; a laser whose
        line passes h from it at inclination θ (``vertical_offsets_m``) crosses at h/cos θ and runs
        z = tan θ·ρ + h/cos θ in its azimuth's half-plane (to within h·|sin θ| of the axis)."""
        if not len(self.faces):
            return self
        T = np.asarray(pose, np.float64)
        v = (self.vertices.astype(np.float64) - T[:3, 3]) @ T[:3, :3]  # sensor frame
        code = np.zeros(len(v), np.uint8)  # one bit per region no ray enters; a face is out when its corners share one
        if elevation_deg is not None:
            lo, hi = elevation_deg[0] - margin_deg, elevation_deg[1] + margin_deg
            rho = np.hypot(v[:, 0], v[:, 1])
            if hi >= 0:
                code |= (v[:, 2] - heights_m[1] > math.tan(math.radians(hi)) * rho).view(np.uint8)
            if lo <= 0:
                code |= (v[:, 2] - heights_m[0] < math.tan(math.radians(lo)) * rho).view(np.uint8) << 1
        if azimuth_deg is not None and azimuth_deg[1] - azimuth_deg[0] + 2 * margin_deg < 180:
            a0, a1 = math.radians(azimuth_deg[0] - margin_deg), math.radians(azimuth_deg[1] + margin_deg)
            code |= (-math.sin(a0) * v[:, 0] + math.cos(a0) * v[:, 1] < 0).view(np.uint8) << 2  # clockwise of a0
            code |= (-math.sin(a1) * v[:, 0] + math.cos(a1) * v[:, 1] > 0).view(np.uint8) << 3  # beyond a1
        corners = code[self.faces]
        drop = (corners[:, 0] & corners[:, 1] & corners[:, 2]) != 0
        if max_range_m is not None:  # |p| ≥ |corner| − longest edge for every point p of the face
            tri = v[self.faces[~drop]]
            edge = np.sqrt(np.max([((tri[:, i] - tri[:, (i + 1) % 3]) ** 2).sum(-1) for i in range(3)], axis=0))
            near = np.sqrt((tri[:, 0] ** 2).sum(-1)) - edge <= max_range_m * (1 + 1e-6) + 1e-3
            drop[np.flatnonzero(~drop)[~near]] = True
        return self.subset(~drop) if drop.any() else self


class RayCaster:
    """First hits of many rays against a :class:`Geometry` (Embree, through ``embreex``; built once per
    frame, without Embree's robust mode). :meth:`cast` gives per ray the distance to the first triangle
    (+inf: none within ``max_distance``), its index and its unit normal."""

    def __init__(self, geometry: Geometry):
        from fogsim.deps import require

        rtcs = require("embreex.rtcore_scene", "blender")
        mesh_construction = require("embreex.mesh_construction", "blender")
        self.geometry = geometry
        self.scene = None
        if len(geometry.faces):
            used = np.zeros(len(geometry.vertices), bool)  # embreex copies vertex by vertex: only the used ones
            used[geometry.faces.reshape(-1)] = True
            if not used.all():
                remap = (np.cumsum(used, dtype=np.int32) - 1).astype(np.int32)
                vertices, faces = geometry.vertices[used], remap[geometry.faces]
            else:
                vertices, faces = geometry.vertices, geometry.faces
            self.scene = rtcs.EmbreeScene(robust=False)
            mesh_construction.TriangleMesh(self.scene, np.ascontiguousarray(vertices, np.float32),
                                           np.ascontiguousarray(faces, np.int32))  # indexed: no copies

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_distance: float = np.inf
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distance N float64, +inf on a miss; triangle index N int64, −1 on a miss; unit geometric normal
        N×3 float64, zero on a miss) of unit-length rays, looking no farther than ``max_distance``."""
        n = len(directions)
        if self.scene is None or not n:
            return np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((n, 3))
        far = float(min(max_distance, 1e37))
        out = self.scene.run(np.ascontiguousarray(origins, np.float32), np.ascontiguousarray(directions, np.float32),
                             dists=np.full(n, far, np.float32), output=1)
        prim = np.asarray(out["primID"], np.int64)
        t = np.where(prim >= 0, np.asarray(out["tfar"], np.float64), np.inf)
        ng = np.asarray(out["Ng"], np.float64)
        ng /= np.maximum(np.sqrt(np.einsum("ij,ij->i", ng, ng)), 1e-30)[:, None]
        return t, np.where(prim >= 0, prim, -1), ng

    def normals(self, prim: np.ndarray) -> np.ndarray:
        """Unit normals of the triangles ``prim`` (N×3 float64)."""
        tri = self.geometry.vertices[self.geometry.faces[prim]].astype(np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def sensor_caster(geometry: Geometry, pose: np.ndarray, sensor: LidarSensor, ranged: bool = False) -> RayCaster:
    """The ray caster of ``sensor`` at ``pose`` (sensor → world): ``geometry`` less every triangle none of its
    rays can meet (:meth:`Geometry.seen_from`: above its top beam, below its bottom one, beyond its horizontal
    field of view, and — unless ``ranged``: already cut to the range — beyond its range): the same first hits,
    a smaller Embree scene. Each laser's own origin (``vertical_offsets_m``) is allowed for."""
    incl = sensor.inclinations_deg
    fov = sensor.horizontal_fov_deg
    heights = (0.0,) if sensor.vertical_offsets_m is None else \
        np.asarray(sensor.vertical_offsets_m) / np.cos(sensor.inclinations_rad)  # each laser's line at ρ = 0
    return RayCaster(geometry.seen_from(pose, (min(incl), max(incl)), None if fov >= 360 else (-fov / 2, fov / 2),
                                        None if ranged else sensor.reach_m,
                                        heights_m=(float(np.min(heights)), float(np.max(heights)))))


def sweep_directions(sensor: LidarSensor) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(unit directions N×3 in the sensor frame, beam N int16, azimuth N radians) of one sweep: for each
    azimuth step (360°: from 0 towards +y; a narrower field of view: centred on +x), every beam, top
    beam first as the sensor lists them. Computed once per sensor geometry (read-only arrays)."""
    return _directions(sensor.inclinations_deg, sensor.steps_per_sweep, sensor.horizontal_fov_deg)


@lru_cache(maxsize=8)
def _directions(inclinations_deg: tuple, steps: int, fov_deg: float):
    incl = np.radians(np.asarray(inclinations_deg, np.float64))
    fov = np.radians(fov_deg)
    az = np.arange(steps) * (fov / steps) if fov_deg >= 360 else -fov / 2 + (np.arange(steps) + 0.5) * (fov / steps)
    a, i = np.meshgrid(az, incl, indexing="ij")
    d = np.stack([np.cos(i) * np.cos(a), np.cos(i) * np.sin(a), np.sin(i)], -1).reshape(-1, 3)
    beam = np.broadcast_to(np.arange(len(incl), dtype=np.int16), a.shape).reshape(-1).copy()
    az = a.reshape(-1).copy()
    for arr in (d, beam, az):
        arr.flags.writeable = False
    return d, beam, az


@dataclass(frozen=True)
class SyntheticScan:
    """One sweep's reported points: ``cloud`` (sensor frame; intensity in the sensor's scale, ring = beam,
    ``index`` = the ray's number in the sweep) and per point ``object_id`` (mask id, 0 = background),
    ``azimuth`` (rad), ``incidence_deg``, ``reflectivity`` (ρ of the surface), ``normal`` (the surface's unit
    normal in the sensor frame, towards the sensor); ``rays`` cast, ``hits`` within range; ``empty`` the
    rays without a reported point (:class:`~fogsim.lidar.rays.EmptyRays`: their directions, beams, and the
    range of what each hit, +inf for nothing), which the fog model gives fog clutter."""

    cloud: PointCloud
    object_id: np.ndarray
    azimuth: np.ndarray
    incidence_deg: np.ndarray
    reflectivity: np.ndarray
    normal: np.ndarray
    rays: int
    hits: int
    empty: EmptyRays | None = None

    def record(self) -> dict:
        return {"rays": self.rays, "hits_in_range": self.hits, "points": len(self.cloud),
                "below_threshold": self.hits - len(self.cloud),
                "empty_rays": 0 if self.empty is None else len(self.empty)}


def sweep(caster: RayCaster, lidar_to_world: np.ndarray, sensor: LidarSensor, source: str) -> SyntheticScan:
    """The clear-air sweep of ``sensor`` at the pose ``lidar_to_world`` (4×4, sensor → world) over the
    caster's geometry (see the module docstring); ``source`` names the scan in messages."""
    d, beam, az = sweep_directions(sensor)
    T = np.asarray(lidar_to_world, np.float64)
    dirs_world = d @ T[:3, :3].T
    start = sensor.beam_origins(beam, az)  # each laser's line, its vertical offset off the axis (if any)
    origin = start @ T[:3, :3].T + T[:3, 3]
    t, prim, normal = caster.cast(origin, dirs_world, sensor.max_range_m)
    hit = np.isfinite(t) & (t >= sensor.min_range_m) & (t <= sensor.max_range_m)
    idx = np.flatnonzero(hit)
    r, p = t[idx], prim[idx]
    n_world = normal[idx]
    facing = np.einsum("ij,ij->i", n_world, dirs_world[idx])
    cos_i = np.abs(facing)
    n_world *= -np.sign(facing)[:, None]  # towards the sensor
    rho = caster.geometry.face_rho[p].astype(np.float64)
    apparent = rho * cos_i
    seen = sensor.clear_signal(apparent, r) >= 1.0
    keep = idx[seen]
    r, p, apparent, cos_i, rho, n_world = r[seen], p[seen], apparent[seen], cos_i[seen], rho[seen], n_world[seen]
    _, raw = scale_named(sensor.intensity_scale).from_linear(sensor.intensity_of(apparent, r))
    xyz = (start[keep] + d[keep] * r[:, None]).astype(np.float32)
    cloud = PointCloud.from_raw(xyz, raw, sensor.intensity_scale, source, ring=beam[keep], index=keep,
                                allow_empty=True)
    unreported = np.ones(len(d), bool)
    unreported[keep] = False
    empty = EmptyRays(d[unreported], beam[unreported], np.maximum(t[unreported], 1e-6),
                      None if sensor.vertical_offsets_m is None else start[unreported]) if unreported.any() else None
    return SyntheticScan(cloud, caster.geometry.face_id[p], az[keep].astype(np.float32),
                         np.degrees(np.arccos(np.clip(cos_i, 0.0, 1.0))).astype(np.float32), rho.astype(np.float32),
                         (n_world @ T[:3, :3]).astype(np.float32), rays=len(d), hits=int(hit.sum()), empty=empty)

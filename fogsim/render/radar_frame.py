"""A rendered frame's radar: its clear sweep, each fog level's detections in the camera's fog, the detected
objects and the files (pure Python; :func:`fogsim.render.frame.commit_frame` calls it).

Per frame with a radar (preset key ``radar``, ``fogsim render --radar SENSOR``):

* the sweep (:func:`fogsim.render.radar_scan.radar_sweep`) over the frame's geometry — the LiDAR's triangles,
  less those outside the radar's field of view and range (:meth:`~fogsim.render.lidar_scan.Geometry.seen_from`)
  — from the sensor's pose (``desc["radar"]["radar_to_world"]``: procedural streets, the sensor's ``mount``
  on the ego vehicle, :func:`fogsim.render.lidar_rig.mounted_pose`; scene mode, an object marked
  ``fogsim_radar`` or the camera plus :data:`RADAR_CAMERA_OFFSET`), with the objects' and the ego's
  velocities of :func:`fogsim.scene.motion.frame_motion` (the preset's ``sensor.motion_blur`` speeds, or
  their defaults without one: the radar always sees the traffic move; a user's scene stands still);
  noise, clutter and false alarms drawn from ``numpy.random.default_rng([frame seed, RADAR_STREAM])``;
* each fog level's detections from the radar fog model with that level's β (the camera's) through the run's
  fog record (:meth:`fogsim.fog.engine.FogSettings.radar_fogger`), its draws from
  ``default_rng([frame seed, level index, RADAR_STREAM])``;
* per labelled object and level the detections on it (``radar_detections``; seen: ≥ 1), the cross-sensor
  table's radar column; the objects' 3D boxes (``box3d``) as the LiDAR's stage gives them.

Files, per level ``L`` and frame ``F`` (before the frame's meta):

* ``radar/sweep/F.pcd`` — the clear sweep (nuScenes radar PCD, :mod:`fogsim.radar.formats`) and
  ``radar/sweep/F.npz`` — per detection its labels (:func:`write_labels`);
* ``radar/L/F.pcd`` — the detections the sensor reports at the level, ``radar/L/F.npz`` their labels, and
  ``radar/L/F.outcomes.npz`` every sweep detection's outcome, output row and SNR in the fog
  (:mod:`fogsim.radar.outcome_file`).
"""
from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from fogsim.dataset.layout import DatasetLayout
from fogsim.io.atomic import atomic_write_bytes
from fogsim.radar.detections import KINDS, OBJECT, RadarScan
from fogsim.radar.fog import FoggedRadar
from fogsim.radar.formats import write_radar
from fogsim.radar.outcome_file import write_radar_outcomes
from fogsim.radar.sensors import RadarSensor
from fogsim.render.boxes3d import box_record, object_box
from fogsim.render.lidar_scan import Geometry, RayCaster
from fogsim.render.radar_scan import Motion, SyntheticRadar, radar_sweep, ray_grid
from fogsim.scene.classes import is_labelled

#: the radar's generators: the sweep default_rng([frame seed, RADAR_STREAM]), level i [frame seed, i, RADAR_STREAM]
RADAR_STREAM = 0x2ADA2
#: a user's scene without a ``fogsim_radar`` object: the radar at the camera's centre plus this offset in the
#: level axes (forward, left, up; metres) — nuScenes' RADAR_FRONT relative to its CAM_FRONT (calibrated_sensor:
#: radar at [3.41, 0, 0.50], camera at [1.70, 0.02, 1.51] in the ego frame)
RADAR_CAMERA_OFFSET = (1.71, 0.0, -1.01)
#: the custom property that marks a user's object as the radar (scene mode)
RADAR_PROPERTY = "fogsim_radar"
#: the sweep's file format
RADAR_FORMAT = "nuscenes-radar"

__all__ = ["RADAR_CAMERA_OFFSET", "RADAR_FORMAT", "RADAR_PROPERTY", "RADAR_STREAM", "RadarFrame", "radar_scan",
           "radar_stage", "write_labels", "write_radar_files"]


@dataclass(frozen=True)
class RadarFrame:
    """What one frame's radar produced: the clear ``sweep`` (labels and all) and its ``scan`` record,
    ``fogged`` detections by level key, the ``pose`` (radar → world), the ``sensor`` and its ``spec``, the
    ``motion`` it saw, and the radar's ``objects`` (every labelled object it detects or the camera sees)."""

    sweep: SyntheticRadar
    scan: RadarScan
    fogged: dict[str, FoggedRadar]
    pose: np.ndarray
    sensor: RadarSensor
    spec: dict
    motion: dict | None
    objects: list


def radar_scan(sweep: SyntheticRadar, source: str) -> RadarScan:
    """The sweep as the radar record (:class:`fogsim.radar.detections.RadarScan`): velocities as vectors
    along the ray's horizontal direction, ``index`` the detection's row in the sweep."""
    along = np.stack([np.cos(sweep.azimuth_rad), np.sin(sweep.azimuth_rad)], 1).astype(np.float32)
    return RadarScan.checked(xyz=sweep.xyz, velocity=along * sweep.radial_velocity[:, None],
                             velocity_comp=along * sweep.radial_velocity_comp[:, None], rcs_dbsm=sweep.rcs_dbsm,
                             snr_db=sweep.snr_db, object_id=sweep.object_id, kind=sweep.kind,
                             index=np.arange(len(sweep), dtype=np.int64), source=source)


def _motion(config, desc: dict) -> dict | None:
    """The frame's velocities (the module docstring); None for a user's scene (no street, no traffic)."""
    from fogsim.scene.motion import frame_motion

    if "street" not in desc:
        return None
    return frame_motion(dict((config.sensor or {}).get("motion_blur") or {}), desc, int(desc.get("seed") or 0))


def radar_stage(config, desc: dict, meshes: dict, records: list[dict], seed: int,
                geometry: Geometry | None = None, caster: RayCaster | None = None) -> RadarFrame:
    """The frame's sweep, fogged detections and per-object counts (into ``records``: ``radar_detections``
    and, where the LiDAR gave none, ``box3d``); ``caster``: the frame's ray caster (the LiDAR's), if built."""
    from fogsim.render.fog_settings import fog_settings

    sensor = config.radar_sensor
    pose = np.asarray(desc["radar"]["radar_to_world"], np.float64)
    if caster is None:  # its own Embree scene: the triangles its rays can reach (field of view, range)
        _, az, el, _, _ = ray_grid(sensor)
        if geometry is None:
            geometry = Geometry.of_frame(desc, meshes, within=(pose[:3, 3], sensor.max_range_m))
        caster = RayCaster(geometry.seen_from(pose, tuple(np.degrees([el.min(), el.max()])),
                                              tuple(np.degrees([az.min(), az.max()])), sensor.max_range_m))
    classes = {int(o["id"]): o["class"] for o in desc["objects"]}
    boxes = {}
    for o in desc["objects"]:
        if is_labelled(o["class"]):
            box = object_box(meshes.get(o["id"], []), o["transform"], o.get("forward", "+y"))
            if box is not None:
                boxes[int(o["id"])] = box
    headings = {i: b.axes[:, 0] for i, b in boxes.items()}
    motion = _motion(config, desc)
    sweep = radar_sweep(caster, pose, sensor, classes, headings, Motion.of(motion),
                        np.random.default_rng([seed, RADAR_STREAM]))
    scan = radar_scan(sweep, f"frame {desc.get('seed')} radar")
    fogger = fog_settings(config).radar_fogger(scan, sensor)
    fogged = {lv.key: fogger(lv.beta, np.random.default_rng([seed, i, RADAR_STREAM]))
              for i, lv in enumerate(config.levels)}
    on = sweep.object_id[sweep.kind == OBJECT]
    seen = {r["id"] for r in records}
    objects = [{"id": o["id"], "class": o["class"]} for o in desc["objects"]
               if is_labelled(o["class"]) and (o["id"] in set(on.tolist()) or o["id"] in seen)]
    w2c = np.asarray(desc["camera"]["world_to_camera"], np.float64)
    l2w = (desc.get("lidar") or {}).get("lidar_to_world")
    w2l = np.linalg.inv(np.asarray(l2w, np.float64)) if l2w is not None else None
    counts = {}
    for key, f in fogged.items():
        rows = np.flatnonzero(f.output_index >= 0)
        reported = sweep.object_id[rows][sweep.kind[rows] == OBJECT]
        ids, n = np.unique(reported, return_counts=True)
        counts[key] = dict(zip(ids.tolist(), n.tolist()))
    for rec in objects:
        rec["radar_detections"] = {k: int(c.get(rec["id"], 0)) for k, c in counts.items()}
        if rec["id"] in boxes:
            rec["box3d"] = box_record(boxes[rec["id"]], w2c, w2l)
    per_id = {r["id"]: r for r in objects}
    for rec in records:  # the camera's records: the same counts, and a box where the LiDAR gave none
        if rec["id"] in per_id:
            rec["radar_detections"] = per_id[rec["id"]]["radar_detections"]
            if "box3d" not in rec and "box3d" in per_id[rec["id"]]:
                rec["box3d"] = per_id[rec["id"]]["box3d"]
    return RadarFrame(sweep, scan, fogged, pose, sensor, dict(config.radar), motion, objects)


def write_labels(path, sweep: SyntheticRadar, rows: np.ndarray, snr_db: np.ndarray | None = None) -> None:
    """The labels of the detections ``rows`` of ``sweep`` (in that order: the file's detections), as an
    ``.npz`` read with ``numpy.load(allow_pickle=False)``: ``object_id`` (mask id, −1 none), ``kind`` (0 object,
    1 ghost, 2 clutter, 3 false alarm; ``kind_names``), ``source_id`` (a ghost's mirrored object), ``sweep_row``
    (the row in the clear sweep), ``range_m``, ``azimuth_rad``, ``elevation_rad``, ``radial_velocity_mps`` and
    ``radial_velocity_comp_mps`` (+ receding), ``rcs_dbsm``, ``snr_db`` (the level's; clear air for the sweep),
    ``scan`` (0 far, 1 near) and ``x_true``, ``y_true``, ``z_true`` (the scattering centre before the
    measurement noise, sensor frame, m); atomic."""
    rows = np.asarray(rows, np.int64)
    buf = io.BytesIO()
    true = sweep.xyz_true[rows]
    np.savez(buf, object_id=sweep.object_id[rows], kind=sweep.kind[rows], source_id=sweep.source_id[rows],
             x_true=true[:, 0], y_true=true[:, 1], z_true=true[:, 2],
             sweep_row=rows, range_m=sweep.range_m[rows], azimuth_rad=sweep.azimuth_rad[rows],
             elevation_rad=sweep.elevation_rad[rows], radial_velocity_mps=sweep.radial_velocity[rows],
             radial_velocity_comp_mps=sweep.radial_velocity_comp[rows], rcs_dbsm=sweep.rcs_dbsm[rows],
             snr_db=(sweep.snr_db[rows] if snr_db is None else np.asarray(snr_db, np.float32)),
             scan=sweep.scan[rows], kind_names=np.array([KINDS[k] for k in sorted(k for k in KINDS if k >= 0)]))
    atomic_write_bytes(path, buf.getvalue())


def write_radar_files(layout: DatasetLayout, name: str, radar: RadarFrame) -> dict:
    """Write the frame's radar files (the module docstring) and return ``meta["radar"]``."""
    sweep_file, sweep_labels = layout.radar_sweep(name, ".pcd"), layout.radar_sweep(name, ".npz")
    write_radar(sweep_file, radar.scan, RADAR_FORMAT)
    write_labels(sweep_labels, radar.sweep, np.arange(len(radar.sweep)))
    levels = {}
    for key, fogged in radar.fogged.items():
        scan, labels, outcomes = (layout.radar(key, name, ".pcd"), layout.radar(key, name, ".npz"),
                                  layout.radar(key, name, ".outcomes.npz"))
        write_radar(scan, fogged.scan, RADAR_FORMAT)
        order = np.flatnonzero(fogged.output_index >= 0)
        order = order[np.argsort(fogged.output_index[order])]
        write_labels(labels, radar.sweep, order, np.asarray(fogged.snr_fog_db)[order])
        write_radar_outcomes(outcomes, fogged)
        kinds = np.bincount(radar.sweep.kind[order].astype(np.int64), minlength=len(KINDS) - 1)
        levels[key] = {**fogged.record(), "file": layout.relative(scan), "labels": layout.relative(labels),
                       "kinds": {KINDS[k]: int(kinds[k]) for k in range(len(KINDS) - 1)},
                       "outcome_file": layout.relative(outcomes)}
    return {"format": RADAR_FORMAT, "levels": levels,
            "input": {"file": layout.relative(sweep_file), "labels": layout.relative(sweep_labels),
                      "format": RADAR_FORMAT},
            "sweep": radar.sweep.record(), "objects": radar.objects, "sensor_spec": radar.spec,
            "sensor": radar.sensor.name, "radar_to_world": radar.pose.tolist(), "motion": radar.motion,
            "noise_seed_rule": "sweep: numpy default_rng([frame seed, 0x2ADA2]); level i's fog: "
                               "default_rng([frame seed, level index, 0x2ADA2])",
            "frame": "sensor: x forward, y left, z up (m); detections in the sensor frame; radial velocity "
                     "+ receding (m/s)",
            "timing": "one instant per sweep"}

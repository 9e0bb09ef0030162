"""A rendered frame's LiDAR: its clear sweep, each fog level's scan in the camera's fog, the objects' 3D
boxes and points, and the files (pure Python; :func:`fogsim.render.frame.commit_frame` calls it).

Per frame with a LiDAR (preset key ``lidar``, ``fogsim render --lidar SENSOR``):

* the sweep (:func:`fogsim.render.lidar_scan.sweep`) over the frame's geometry from the sensor's pose
  (``desc["lidar"]["lidar_to_world"]``, :mod:`fogsim.render.lidar_rig`);
* every labelled object's oriented 3D box (:mod:`fogsim.render.boxes3d`) in its record (``box3d``: world,
  camera as KITTI writes it, LiDAR frame), and in ``meta["lidar"]["objects"]`` for every labelled object the
  sweep hits (360°: behind the camera too);
* each fog level's scan from the LiDAR fog model with that level's β — the camera's, also in volumetric
  renders, whose medium has that β — for every ray of the sweep (the rays without a clear return: sky,
  dark or far surfaces, gain fog clutter when their fog echo is detected) through the run's fog record
  (:meth:`fogsim.fog.engine.FogSettings.lidar_fogger`), range noise seeded by
  ``numpy.random.default_rng([frame seed, level index, LIDAR_STREAM])``;
* per object and level the points in its box (``lidar_points``), the cross-sensor table's input.

Files, per level ``L`` and frame ``F`` (written before the frame's meta, which marks the frame done):

* ``lidar/sweep/F.bin`` — the clear sweep, and ``lidar/sweep/F.npz`` — per point what it hit (:func:`write_sweep`:
  object, range, azimuth, beam, incidence angle, reflectivity, normal);
* ``lidar/L/F.bin`` — the scan the sensor reports, in its own format (0–1 intensities: KITTI's
  4 × float32; 0–255: nuScenes' 5 × float32 with the ring, ``.pcd.bin``), ``lidar/L/F.outcomes.npz`` — every clear-sweep
  point's outcome and row (:mod:`fogsim.lidar.outcome_file`), ``lidar/L/F.label`` — SemanticKITTI labels,
  one uint32 per reported point: instance id << 16 | class (SemanticKITTI's own ids,
  :data:`fogsim.dataset.semantic_kitti.FOGSIM_TO_SEMANTIC_KITTI`, fog clutter
  :data:`~fogsim.dataset.semantic_kitti.FOG_ID`; the instance is the object's mask id for labelled
  objects, 0 for scenery and fog clutter), ``lidar/L/F.pcd`` — the scan with its label, instance and
  outcome per point for viewers (:mod:`fogsim.lidar.scan_pcd`);
* ``semantic_kitti/L/sequences/00/{velodyne,labels}/F`` — the level as a SemanticKITTI sequence
  (:mod:`fogsim.dataset.semantic_kitti`; its calib, poses and yaml at finalize);
* ``kitti/L/training/{image_2,velodyne,calib,label_2}/F`` — the level as a KITTI object tree
  (:class:`fogsim.dataset.kitti.KittiTree`): calib P0–P3 = the render's K | 0, R0_rect = I,
  Tr_velo_to_cam the LiDAR's pose in the camera, Tr_imu_to_velo = I; label_2 the kept objects of the KITTI
  types (:data:`KITTI_TYPES`) with the mask's 2D box, the 3D box, truncation and an occlusion level from the
  visible fraction (:func:`occlusion_level`); ignore regions as DontCare.
"""
from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from fogsim.camera import Intrinsics
from fogsim.dataset.kitti import KittiTree
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.lidar import box_record as lidar_box_record
from fogsim.dataset.semantic_kitti import FOG_ID, FOGSIM_TO_SEMANTIC_KITTI, SEQUENCE, SemanticKittiTree, semantic_id
from fogsim.io.atomic import atomic_write_bytes
from fogsim.lidar.boxes import Box3D
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.formats import FORMAT_SUFFIX, write_points
from fogsim.lidar.objects import attach_lidar_points, fogged_object_points
from fogsim.lidar.outcome_file import write_outcomes
from fogsim.lidar.outcomes import CLUTTER
from fogsim.lidar.scan_pcd import PCD_SUFFIX, write_level_pcd
from fogsim.lidar.sensors import LidarSensor
from fogsim.readers.kitti.calib import KittiCalib
from fogsim.render.boxes3d import box_record, object_box, transformed
from fogsim.render.lidar_scan import Geometry, RayCaster, SyntheticScan, sensor_caster, sweep
from fogsim.scene.classes import LABELLED, is_labelled

#: the LiDAR noise generator of level i: default_rng([frame seed, i, LIDAR_STREAM])
LIDAR_STREAM = 0x11DA2
#: fogsim classes as KITTI object types (the others have none and get no label line)
KITTI_TYPES = {"car": "Car", "van": "Van", "truck": "Truck", "bus": "Misc", "pedestrian": "Pedestrian",
               "cyclist": "Cyclist"}
#: the scan's point format by the sensor's intensity scale (:data:`fogsim.lidar.formats.FORMAT_SUFFIX`)
SCAN_FORMAT = {"0-1": "kitti", "0-255": "nuscenes", "tanh": "npy"}


def occlusion_level(visible_fraction: float) -> int:
    """KITTI's occlusion level from the visible fraction: 0 fully visible (≥ 0.8), 1 partly (≥ 0.4), 2 largely."""
    return 0 if visible_fraction >= 0.8 else 1 if visible_fraction >= 0.4 else 2


@dataclass(frozen=True)
class LidarFrame:
    """What one frame's LiDAR produced: the clear ``scan``, ``fogged`` scans by level key, the LiDAR-frame
    ``boxes`` by object id, the ``pose`` (LiDAR → world), the ``sensor`` and its ``spec``, and the LiDAR's
    ``objects`` (360°: also those the camera does not see)."""

    scan: SyntheticScan
    fogged: dict[str, FoggedScan]
    boxes: dict[int, Box3D]
    pose: np.ndarray
    sensor: LidarSensor
    spec: dict  # the sensor's block as the preset gave it (LidarSensor.from_dict rebuilds the sensor)
    objects: list  # every labelled object the sweep hits or the camera sees: id, class, box3d, lidar_points


def lidar_stage(config, desc: dict, meshes: dict, records: list[dict], seed: int,
                geometry: Geometry | None = None, caster: RayCaster | None = None) -> LidarFrame:
    """The frame's sweep, 3D boxes (into ``records``: ``box3d``, ``lidar_points``) and fogged scans
    (``caster``: the frame's ray caster when another sensor built it already)."""
    from fogsim.render.fog_settings import fog_settings

    sensor = config.lidar_sensor
    pose = np.asarray(desc["lidar"]["lidar_to_world"], np.float64)
    if caster is None:  # its own Embree scene: only the triangles the sensor's rays can reach
        ranged = geometry is None
        if ranged:
            geometry = Geometry.of_frame(desc, meshes, within=(pose[:3, 3], sensor.reach_m))
        caster = sensor_caster(geometry, pose, sensor, ranged)
    scan = sweep(caster, pose, sensor, f"frame {desc.get('seed')}")
    w2c, w2l = np.asarray(desc["camera"]["world_to_camera"], np.float64), np.linalg.inv(pose)
    by_id = {o["id"]: o for o in desc["objects"]}
    hit = set(np.flatnonzero(np.bincount(scan.object_id.astype(np.int64))).tolist())
    seen = {r["id"] for r in records}  # the camera's records; the LiDAR's objects: every labelled one it hits
    objects = [{"id": o["id"], "class": o["class"]} for o in desc["objects"]
               if is_labelled(o["class"]) and (o["id"] in hit or o["id"] in seen)]
    boxes: dict[int, Box3D] = {}
    box3d: dict[int, dict] = {}
    for rec in objects:
        obj = by_id[rec["id"]]
        box = object_box(meshes.get(rec["id"], []), obj["transform"], obj.get("forward", "+y"))
        if box is not None:
            box3d[rec["id"]] = rec["box3d"] = box_record(box, w2c, w2l)
            boxes[rec["id"]] = transformed(box, w2l)
            rec["lidar_box"] = lidar_box_record(boxes[rec["id"]])
    fogger = fog_settings(config).lidar_fogger(scan.cloud, sensor, scan.empty)  # every ray: the empty ones' fog too
    fogged = {lv.key: fogger(lv.beta, np.random.default_rng([seed, i, LIDAR_STREAM]))
              for i, lv in enumerate(config.levels)}
    clouds = {k: f.cloud for k, f in fogged.items()}
    in_boxes = [boxes.get(r["id"]) for r in objects]
    attach_lidar_points(objects, clouds, in_boxes, fogged_object_points(scan.cloud, fogged, in_boxes))
    points = {r["id"]: r["lidar_points"] for r in objects if "lidar_points" in r}
    for rec in records:  # the camera's records get the same box and counts
        if rec["id"] in box3d:
            rec["box3d"], rec["lidar_points"] = box3d[rec["id"]], points[rec["id"]]
            rec["lidar_box"] = lidar_box_record(boxes[rec["id"]])
    return LidarFrame(scan, fogged, boxes, pose, sensor, dict(config.lidar), objects)


def semantic_labels(scan: SyntheticScan, fogged: FoggedScan, classes: dict[int, str]) -> np.ndarray:
    """The uint32 label of every point of ``fogged`` (instance << 16 | SemanticKITTI class; fog clutter:
    :data:`~fogsim.dataset.semantic_kitti.FOG_ID`, instance 0); ``classes``: object id → fogsim class."""
    cls = np.array([semantic_id(classes.get(int(i))) for i in range(int(scan.object_id.max(initial=0)) + 1)],
                   np.uint32)
    oid = scan.object_id.astype(np.int64)
    thing = np.isin(oid, [i for i, c in classes.items() if c in LABELLED])
    clear = ((np.where(thing, oid, 0).astype(np.uint32) << np.uint32(16)) | cls[oid]).astype(np.uint32)
    out = np.full(len(fogged.cloud), FOG_ID, np.uint32)  # the empty rays' clutter, after the points
    rows = np.flatnonzero(fogged.output_index >= 0)
    out[fogged.output_index[rows]] = np.where(fogged.outcome[rows] == CLUTTER, np.uint32(FOG_ID),
                                              clear[rows])
    return out


def kitti_calib(K: Intrinsics, lidar_to_camera: np.ndarray, source: str) -> KittiCalib:
    """The KITTI calibration of a render: P0–P3 = K | 0, R0_rect = I, Tr_velo_to_cam, Tr_imu_to_velo = I."""
    P = np.hstack([np.array([[K.fx, 0, K.cx], [0, K.fy, K.cy], [0, 0, 1]], np.float64), np.zeros((3, 1))])
    return KittiCalib((P, P, P, P), np.eye(3), np.asarray(lidar_to_camera, np.float64), np.eye(4), source)


def kitti_records(records: list[dict]) -> list[dict]:
    """The KITTI label records (:func:`fogsim.readers.kitti.labels.format_label_line`'s fields) of a frame's
    records: kept objects of :data:`KITTI_TYPES` with a 3D box; every ignore region as DontCare."""
    out = []
    for r in records:
        x0, y0, x1, y1 = r["bbox"]
        box = [float(x0), float(y0), float(x1 - 1), float(y1 - 1)]  # KITTI: inclusive pixel-centre corners
        if r["kept"] and r["class"] in KITTI_TYPES and "box3d" in r:
            cam = r["box3d"]["camera"]
            out.append({"kitti_type": KITTI_TYPES[r["class"]], "truncation": r["truncation"],
                        "occlusion": occlusion_level(r["visible_fraction"]), "alpha": cam["alpha"],
                        "kitti_bbox": box, "dimensions_m": cam["dimensions_hwl_m"], "location_m": cam["location_m"],
                        "rotation_y": cam["rotation_y"]})
        elif not r["kept"]:
            out.append({"kitti_type": "DontCare", "truncation": -1, "occlusion": -1, "alpha": -10,
                        "kitti_bbox": box, "dimensions_m": [-1, -1, -1], "location_m": [-1000, -1000, -1000],
                        "rotation_y": -10})
    return out


def write_sweep(layout: DatasetLayout, name: str, scan: SyntheticScan, fmt: str) -> tuple[str, str]:
    """The clear sweep, ``lidar/sweep/F<ext>`` in the sensor's format (the scan every level's outcomes refer
    to), and beside it ``lidar/sweep/F.npz`` — per point what it hit: ``object_id`` (the mask id, scenery
    included; 0 = background), ``range_m``, ``azimuth_rad``, ``beam``, ``incidence_deg``, ``reflectivity``,
    ``normal`` (N×3, sensor frame, towards the sensor), read with ``numpy.load(allow_pickle=False)``; both
    atomic. Returns their paths relative to the root."""
    points, attributes = layout.lidar_sweep(name, FORMAT_SUFFIX[fmt]), layout.lidar_sweep(name, ".npz")
    write_points(points, scan.cloud, fmt)
    buf = io.BytesIO()
    np.savez(buf, object_id=scan.object_id.astype(np.uint16), range_m=scan.cloud.range_m.astype(np.float32),
             azimuth_rad=scan.azimuth, beam=scan.cloud.ring.astype(np.int16), incidence_deg=scan.incidence_deg,
             reflectivity=scan.reflectivity, normal=scan.normal)
    atomic_write_bytes(attributes, buf.getvalue())
    return layout.relative(points), layout.relative(attributes)


def write_lidar(layout: DatasetLayout, name: str, lidar: LidarFrame, images: dict, K: Intrinsics,
                w2c: np.ndarray, records: list[dict], classes: dict[int, str]) -> dict:
    """Write the frame's LiDAR files (the module docstring) and return ``meta["lidar"]`` — the frame record
    :mod:`fogsim.dataset.lidar` reads (``format``, per level ``file``, ``outcome_file``, ``outcomes``; the
    clear sweep as ``input``; ``kitti``), plus the sensor, the poses and the LiDAR's objects; ``images``:
    the final image of every level (what ``image_2`` holds): its written PNG file (linked) or the array."""
    fmt = SCAN_FORMAT[lidar.sensor.intensity_scale]
    l2c = np.asarray(w2c, np.float64) @ lidar.pose
    calib = kitti_calib(K, l2c, f"frame {name}")
    labels_2 = kitti_records(records)
    sweep_file, attributes_file = write_sweep(layout, name, lidar.scan, fmt)
    levels = {}
    for key, fogged in lidar.fogged.items():
        scan, outcomes, labels = (layout.lidar(key, name, FORMAT_SUFFIX[fmt]), layout.lidar_outcomes(key, name),
                                  layout.lidar_labels(key, name))
        pcd = layout.lidar(key, name, PCD_SUFFIX)
        write_points(scan, fogged.cloud, fmt)
        write_outcomes(outcomes, fogged)
        point_labels = semantic_labels(lidar.scan, fogged, classes)
        atomic_write_bytes(labels, point_labels.astype("<u4").tobytes())
        write_level_pcd(pcd, fogged, point_labels)
        SemanticKittiTree(layout.root, key).write_frame(name, fogged.cloud, point_labels,
                                                        scan if fmt == "kitti" else None)
        # image_2 and a KITTI-format velodyne: links to the level's files (fogsim.dataset.kitti)
        KittiTree(layout.root, key).write_frame(name, images[key], scan if fmt == "kitti" else fogged.cloud, calib,
                                                labels_2)
        levels[key] = {**fogged.record(), "file": layout.relative(scan), "outcome_file": layout.relative(outcomes),
                       "labels": layout.relative(labels), "pcd": layout.relative(pcd)}
    return {"format": fmt, "levels": levels, "input": {"file": sweep_file, "format": fmt},
            "kitti": {"id": name, "part": "training"}, "sweep": {**lidar.scan.record(), "attributes": attributes_file},
            "objects": lidar.objects, "sensor": lidar.sensor.to_dict(), "sensor_spec": lidar.spec,
            "lidar_to_world": lidar.pose.tolist(), "lidar_to_camera": l2c.tolist(),
            "semantic_classes": {c: FOGSIM_TO_SEMANTIC_KITTI[c] for c in sorted(FOGSIM_TO_SEMANTIC_KITTI)},
            "label_rule": "uint32 = instance << 16 | SemanticKITTI class (instance: the mask id of a labelled "
                          "object, else 0)",
            "semantic_kitti": {"levels": list(lidar.fogged), "sequence": SEQUENCE, "P": calib.P[0].tolist()},
            "noise_seed_rule": "numpy default_rng([frame seed, level index, 0x11DA2])",
            "frame": "sensor: x forward, y left, z up (m); points in the sensor frame",
            "timing": "one instant per sweep (no rolling-shutter motion)"}

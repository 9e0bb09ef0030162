"""One rendered frame → a committed dataset frame (pure Python; the renderer hands arrays in).

A frame is described first (:class:`DescribedFrame`: the scene, renderer-agnostic), a renderer
turns it into :class:`FramePasses` (and, for volumetric fog, :class:`FogRenders`), and
:func:`commit_frame` makes the rest: sRGB image from the scene-linear render, ray distance from
the planar depth, boxes and visibility from the instance mask and the unoccluded silhouettes,
the fogged image at every level, then ``meta/<frame>.json`` last — its presence marks the frame
done.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from fogsim._version import __version__
from fogsim.camera import Intrinsics, StereoCamera, encode_disparity_png, planar_to_ray
from fogsim.colour import linear_to_srgb8
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.writer import frame_split, write_frame_labels
from fogsim.depth.stereo import SGBMParams, hole_fraction, sgbm_disparity
from fogsim.errors import InputError
from fogsim.fog.scatter_optics import up_from_world_to_camera
from fogsim.fog.visibility import attach_visibility
from fogsim.io.depth_files import write_depth
from fogsim.io.documents import write_json
from fogsim.io.images import write_image
from fogsim.render.fog_settings import fog_settings
from fogsim.render.labels import object_records
from fogsim.render.lidar_frame import lidar_stage, write_lidar
from fogsim.render.lidar_rig import mounted_pose
from fogsim.render.lidar_scan import Geometry
from fogsim.render.preset import RenderConfig
from fogsim.render.radar_frame import radar_stage, write_radar_files
from fogsim.render.silhouette import silhouette_areas
from fogsim.runs import frame_seed
from fogsim.scene.classes import is_labelled
from fogsim.scene.geometry import world_parts
from fogsim.scene.layout import sample_scene


def frame_name(index: int) -> str:
    return f"{index:06d}"


def describe_frame(config: RenderConfig, index: int, library=None) -> dict:
    """The scene description of frame ``index`` (same config, library and index → same scene);
    ``library``: the run's :class:`fogsim.scene.library.AssetLibrary` (``config.assets`` imported).
    With a LiDAR, ``desc["lidar"]`` holds its pose on the ego vehicle (:mod:`fogsim.render.lidar_rig`); with a
    radar, ``desc["radar"]`` likewise (``radar_to_world``)."""
    s = frame_seed(config.seed, index)
    desc = sample_scene(np.random.default_rng(s), config.style, config.camera, config.resolution, seed=s,
                        lighting=config.lighting, library=library)
    if config.lidar_sensor is not None:
        sensor = config.lidar_sensor
        desc["lidar"] = {"sensor": sensor.name, "mount": "ego vehicle (the sensor's mount)",
                         "lidar_to_world": mounted_pose(desc["camera"]["world_to_camera"], sensor.mount_pose).tolist()}
    if config.radar_sensor is not None:
        radar = config.radar_sensor
        desc["radar"] = {"sensor": radar.name, "mount": "ego vehicle (the sensor's mount)",
                         "radar_to_world": mounted_pose(desc["camera"]["world_to_camera"], radar.mount_pose).tolist()}
    return desc


def check_scene(config: RenderConfig, index: int = 0, library=None) -> None:
    """Describe frame ``index`` before any output is written: a preset the scene layout cannot
    use is a setup error naming the preset (exit 2), not a failure of every frame after the
    dataset folder was claimed. (:func:`fogsim.render.preset.load_render_preset` checks every
    key already; this is the net under it.)"""
    try:
        describe_frame(config, index, library)
    except Exception as exc:  # whatever the layout trips over is the preset's problem
        raise InputError(config.source, f"cannot build a scene from this preset "
                                        f"({type(exc).__name__}: {exc})") from None


def scene_meshes(desc: dict, library=None) -> dict[int, list]:
    """World-space (vertices, faces, slot) parts of every object, built once per frame (library
    models: the imported mesh, so silhouettes are the model's own)."""
    return {obj["id"]: world_parts(obj, library) for obj in desc["objects"]}


@dataclass(frozen=True)
class DescribedFrame:
    """Frame ``index`` before it is rendered: its scene description ``desc``
    (:func:`describe_frame`) and the world-space ``meshes`` of its objects (:func:`scene_meshes`),
    which the renderer builds and the ground truth projects."""

    index: int
    desc: dict
    meshes: dict

    @classmethod
    def of(cls, config: RenderConfig, index: int, library=None) -> "DescribedFrame":
        desc = describe_frame(config, index, library)
        return cls(index, desc, scene_meshes(desc, library))


@dataclass(frozen=True)
class FramePasses:
    """What a renderer hands over for one frame (the clear render): ``rgb_linear`` H×W×3 float32
    scene-linear; ``depth`` H×W float32 planar Z in metres, +inf where nothing was hit; ``mask``
    H×W uint16 instance ids (the object pass index, 0 = background); ``right_linear`` the right
    view of a stereo pair (H×W×3 float32 scene-linear) or None; ``geometry`` the triangles a LiDAR
    sweeps (:class:`fogsim.render.lidar_scan.Geometry`; None: from the frame's meshes)."""

    rgb_linear: np.ndarray
    depth: np.ndarray
    mask: np.ndarray
    right_linear: np.ndarray | None = None
    geometry: Geometry | None = None  # what a LiDAR sees (None: the frame's meshes, procedural streets)


@dataclass(frozen=True)
class FogRenders:
    """Fog rendered by the renderer itself (volumetric): ``foggy`` level key → 8-bit sRGB H×W×3
    image, one per level of the preset; ``info`` replaces the Koschmieder parameters in
    ``meta["fog"]`` (its ``levels`` stay)."""

    foggy: dict
    info: dict


def write_stereo(layout: DatasetLayout, config: RenderConfig, name: str, K: Intrinsics,
                 left: np.ndarray, right: np.ndarray) -> dict:
    """SGBM disparity of the clear pair, written with the pair and camera in Cityscapes' tree."""
    cam = StereoCamera(config.stereo_baseline, K)
    params = SGBMParams()
    disparity = sgbm_disparity(left, right, cam, params)
    split = frame_split(name, seed=config.seed)
    write_image(layout.cityscapes("leftImg8bit", name, split), left)
    write_image(layout.cityscapes("rightImg8bit", name, split), right)
    write_image(layout.cityscapes("disparity", name, split), encode_disparity_png(disparity))
    write_json(layout.cityscapes("camera", name, split), cam.to_cityscapes_json())
    return {"baseline_m": cam.baseline, "split": split, "hole_fraction": round(hole_fraction(disparity), 6),
            "matcher": {"method": "OpenCV StereoSGBM (3-way)", **asdict(params)}}


#: the noise generator of level i of a frame: default_rng([frame seed, i, SENSOR_STREAM])
SENSOR_STREAM = 0x5E7502


def camera_model(config: RenderConfig, desc: dict, K: Intrinsics, foggy: dict, mask: np.ndarray,
                 depth: np.ndarray, ray: np.ndarray, records: list[dict]) -> tuple:
    """The preset's ``sensor`` (:mod:`fogsim.sensor`) applied to every level's image; with lens
    distortion the mask and depth are resampled through it (nearest neighbour: exact values) and
    the records re-measured on the distorted mask. Returns (foggy, mask, depth, records, meta)."""
    from fogsim.render.labels import relabel_distorted
    from fogsim.sensor import Sensor, apply_sensor, distort_nearest

    sensor = Sensor.from_dict(config.sensor)
    seed = int(desc.get("seed") or 0)
    foggy = {lv.key: apply_sensor(foggy[lv.key], K, sensor, np.random.default_rng([seed, i, SENSOR_STREAM]))
             for i, lv in enumerate(config.levels)}
    if sensor.distorts:
        lab = config.label_settings
        mask = distort_nearest(mask, K, sensor.distortion, 0)
        depth = distort_nearest(depth, K, sensor.distortion, np.inf)
        records = relabel_distorted(records, mask, distort_nearest(ray, K, sensor.distortion, np.inf),
                                    min_pixels=lab.min_pixels, min_visible_fraction=lab.min_visible_fraction)
    meta = {"settings": config.sensor, "order": "distortion, vignetting, exposure, noise (linear light), "
            "8-bit sRGB, JPEG; after the fog", "vignetting_law": "cos(theta)^a",
            "distortion": {"model": "opencv", "coefficients": list(sensor.distortion), "K": K.to_dict(),
                           "masks_and_depth": "resampled nearest-neighbour into the distorted image; "
                                              "outside the render: mask 0, depth inf"} if sensor.distorts else None,
            "noise": {"full_well_e": sensor.full_well_e, "read_noise_e": sensor.read_noise_e,
                      "seed_rule": "numpy default_rng([frame seed, level index, 0x5E7502])"}
            if sensor.full_well_e else None, "jpeg_quality": sensor.jpeg_quality}
    return foggy, mask, depth, records, meta


def commit_frame(layout: DatasetLayout, config: RenderConfig, frame: DescribedFrame, passes: FramePasses,
                 fog: FogRenders | None = None, *, timings: dict | None = None,
                 render_info: dict | None = None) -> dict:
    """Ground truth, fog and every file of one frame; returns the frame record (meta).

    ``passes.right_linear`` (a stereo pair, if the preset asks for one) is matched with SGBM and
    written with the left view in Cityscapes' layout. ``fog``: None = Koschmieder fog computed
    here from the clear render. ``timings`` (seconds by stage) and ``render_info`` (the
    renderer's settings) are recorded in the meta as given.
    """
    t0 = time.perf_counter()
    index, desc, meshes = frame.index, frame.desc, frame.meshes
    rgb_linear, depth, mask, right_linear = passes.rgb_linear, passes.depth, passes.mask, passes.right_linear
    name = frame_name(index)
    K = Intrinsics.from_dict(desc["camera"]["intrinsics"])
    h, w = mask.shape
    rgb = linear_to_srgb8(rgb_linear, config.exposure)
    ray = planar_to_ray(depth, K)
    cls = {o["id"]: o["class"] for o in desc["objects"]}
    labelled = {oid: [(v, f) for v, f, _ in parts] for oid, parts in meshes.items() if is_labelled(cls[oid])}
    sil = silhouette_areas(labelled, K, np.asarray(desc["camera"]["world_to_camera"]))
    lab = config.label_settings
    records = object_records(mask, ray, desc["objects"], sil, min_pixels=lab.min_pixels,
                             min_visible_fraction=lab.min_visible_fraction)
    lidar, t_truth, c_truth = None, time.perf_counter(), time.process_time()
    # each sensor its own Embree scene of what its rays can reach (a shared one of the whole frame costs more)
    if config.lidar_sensor is not None:  # the sweep, 3D boxes, fogged scans (records gain box3d, lidar_points)
        lidar = lidar_stage(config, desc, meshes, records, int(desc["seed"] or 0), passes.geometry)
    t_lidar, c_lidar = time.perf_counter(), time.process_time()
    radar = None
    if config.radar_sensor is not None:  # detections, fogged levels (records gain radar_detections)
        radar = radar_stage(config, desc, meshes, records, int(desc["seed"] or 0), passes.geometry)
    t1 = time.perf_counter()
    if fog is None:  # post-process fog (Koschmieder, scatter) from the clear render
        fs = fog_settings(config)
        w2c = desc["camera"].get("world_to_camera")
        up = up_from_world_to_camera(w2c) if w2c is not None and fs.kind == "scatter" else None
        fogger = fs.fogger(rgb, ray, K, up)
        foggy = {lv.key: fogger(lv.beta) for lv in config.levels}
        fog_meta = {**fs.record(), "distance": "planar→ray"}
    else:
        foggy = fog.foggy
        if {lv.key for lv in config.levels} - set(foggy):
            raise ValueError(f"foggy images lack levels {sorted({lv.key for lv in config.levels} - set(foggy))}")
        fog_meta = dict(fog.info)
    attach_visibility(records, rgb, foggy, {lv.key: lv.beta for lv in config.levels}, mask)  # per object, level
    sensor = None
    if config.sensor:  # the camera sees the fogged scene: lens, exposure, noise, JPEG after the fog
        foggy, mask, depth, records, sensor = camera_model(config, desc, K, foggy, mask, depth, ray, records)
    t2 = time.perf_counter()
    for lv in config.levels:
        write_image(layout.image(lv.key, name), foggy[lv.key])
    write_frame_labels(layout, name, config.levels, records, w, h)
    write_depth(layout.depth(name), depth)
    write_image(layout.mask(name), mask)
    stereo = None if right_linear is None else write_stereo(layout, config, name, K, rgb,
                                                             linear_to_srgb8(right_linear, config.exposure))
    w2c = desc["camera"]["world_to_camera"]
    written = {lv.key: layout.image(lv.key, name) for lv in config.levels}  # the KITTI tree links them
    lidar_meta = None if lidar is None else write_lidar(layout, name, lidar, written, K, w2c, records, cls)
    radar_meta = None if radar is None else write_radar_files(layout, name, radar)
    t3 = time.perf_counter()
    timings = dict(timings or {}, ground_truth=t_truth - t0, fog=t2 - t1, write=t3 - t2)
    if lidar is not None:
        timings["lidar"] = t_lidar - t_truth  # sweep, boxes and fogged scans (their files: in write)
        timings["lidar_cpu"] = c_lidar - c_truth  # the same stage's CPU seconds (the process: every thread)
    if radar is not None:
        timings["radar"] = t1 - t_lidar  # sweep, clusters and fogged levels (their files: in write)
    meta = {"frame": name, "index": index, "seed": desc["seed"], "width": w, "height": h,
            "camera": desc["camera"], "objects": records,
            "fog": {"levels": [lv.to_dict() for lv in config.levels], **fog_meta},
            "depth": {"file": str(layout.depth(name).relative_to(layout.root)), "kind": "planar Z, metres",
                      "no_hit": "inf"},
            "stereo": stereo, "sensor": sensor, **({"lidar": lidar_meta} if lidar_meta else {}),
            **({"radar": radar_meta} if radar_meta else {}),
            "render": render_info or {}, "timings_s": {k: round(v, 4) for k, v in timings.items()},
            "scene": desc, "fogsim_version": __version__}
    write_json(layout.meta(name), meta)
    return meta

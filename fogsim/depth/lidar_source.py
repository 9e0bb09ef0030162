"""LiDAR points as a sample's depth: ``fogsim fog --waymo … --depth-from lidar[:METHOD]``.

:class:`LidarDepth` is a picklable :attr:`fogsim.readers.base.DepthSpec.reader` (kind
``ray``): it ignores the image's pixels (except ILA, which predicts from them), asks its
points source for the image's LiDAR points, holds a deterministic fraction out, completes
the rest into dense ray distance (:func:`fogsim.depth.complete.complete`) and reports a
per-image record (points, coverage, completion) through ``read_with_record``, which
:func:`fogsim.fog.depth_input.sample_distance` puts into every fog sidecar under
``depth_record``.

Held-out points are written per image to ``<holdout_path>`` (``OUT/lidar_holdout/<key>.npz``:
``u``, ``v`` float32 pixel coordinates (integer = pixel centre), ``ray`` float32 metres,
``width``, ``height``, and ``fx, fy, cx, cy`` when the camera is known; read with
:func:`read_holdout`, ``np.load(allow_pickle=False)``) and, beside them, the dense completion
made *without* them to ``<depth_path>`` (``OUT/lidar_depth/<key>.exr``, ray distance,
+inf = sky), so ``fogsim depth score --pred OUT/lidar_depth --pred-kind ray --holdout OUT``
scores it. Both are written atomically.

A points source is any picklable zero-argument callable returning ``(uv N×2 float px,
ray N float32 m)`` for the sample's camera; it raises :class:`~fogsim.errors.InputError`
naming the frame when the frame has no LiDAR (the sample then fails, the run goes on).
For Waymo, :func:`waymo_points_source` wraps the decoder ``fogsim.readers.waymo.lidar``.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from functools import partial
from typing import Callable

import numpy as np

from fogsim.camera import Intrinsics, pixel_index, sparse_image
from fogsim.depth.complete import DEFAULT_METHOD, METHODS, SKY_RULES, complete, holdout_split
from fogsim.errors import InputError
from fogsim.schema.base import load_npz
from fogsim.schema.documents import Holdout as HoldoutFile

PointsSource = Callable[[], "tuple[np.ndarray, np.ndarray]"]
HOLDOUT_DIR, DEPTH_DIR = "lidar_holdout", "lidar_depth"
USAGE = f"--depth-from lidar[:METHOD] with METHOD one of {', '.join(m for m in METHODS if m != 'ila')} " \
        f"(default {DEFAULT_METHOD}) or ila:CHECKPOINT"


def parse_lidar(spec: str) -> tuple[str, str | None]:
    """``lidar``, ``lidar:ipbasic``, ``lidar:ila:CKPT`` → (method, checkpoint or None);
    anything else is a ``ValueError`` giving the usage."""
    kind, _, rest = spec.partition(":")
    if kind != "lidar":
        raise ValueError(f"not a LiDAR depth source: {spec!r} ({USAGE})")
    method, _, checkpoint = rest.partition(":")
    method = method or DEFAULT_METHOD
    if method not in METHODS:
        raise ValueError(f"unknown LiDAR completion method {method!r} in --depth-from {spec} ({USAGE})")
    if method == "ila" and not checkpoint:
        raise ValueError(f"--depth-from {spec}: the ILA alignment needs a checkpoint ({USAGE})")
    if method != "ila" and checkpoint:
        raise ValueError(f"--depth-from {spec}: method {method} takes no argument ({USAGE})")
    return method, checkpoint or None


def _points(source, uv, ray) -> tuple[np.ndarray, np.ndarray]:
    uv = np.asarray(uv, np.float64)
    ray = np.asarray(ray, np.float32).reshape(-1)
    if uv.ndim != 2 or uv.shape[1] != 2 or len(uv) != len(ray):
        raise InputError(source, f"LiDAR points: expected uv N×2 and ray N, got {uv.shape} and {ray.shape}")
    return uv, ray


@dataclass(frozen=True)
class LidarDepth:
    """Dense ray distance completed from a sample's LiDAR points (see the module doc).

    ``points``: the points source; ``camera``: the image's intrinsics (needed for ``ila`` and
    recorded in the hold-out file), ``method`` in :data:`~fogsim.depth.complete.METHODS`,
    ``holdout_fraction`` in [0, 1) with its ``seed`` (:func:`~fogsim.depth.complete.holdout_split`
    over the points that fall inside the image), ``holdout_path``/``depth_path``: where the
    held-out points and the completion are written when holding out (None: not written),
    ``checkpoint`` for ``ila``, ``sky`` rule, ``source`` named in messages.
    """

    points: PointsSource
    camera: Intrinsics | None = None
    method: str = DEFAULT_METHOD
    holdout_fraction: float = 0.0
    seed: int = 0
    holdout_path: str | None = None
    depth_path: str | None = None
    checkpoint: str | None = None
    sky: str = "above"
    source: str = "lidar"

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"unknown LiDAR completion method {self.method!r} (known: {', '.join(METHODS)})")
        if self.sky not in SKY_RULES:
            raise ValueError(f"unknown sky rule {self.sky!r} (known: {', '.join(SKY_RULES)})")
        holdout_split(0, self.holdout_fraction)  # validates the fraction

    @property
    def name(self) -> str:
        """What the fog sidecars record as the depth encoding: ``lidar:<method>``."""
        return f"lidar:{self.method}"

    def __call__(self, image: np.ndarray) -> tuple[np.ndarray, None]:
        ray, K, _ = self.read_with_record(image)
        return ray, K

    def read_with_record(self, image: np.ndarray) -> tuple[np.ndarray, None, dict]:
        """(dense ray distance H×W float32, None: no intrinsics needed, the per-image record)."""
        h, w = image.shape[:2]
        uv, ray = _points(self.source, *self.points())
        _, _, inside = pixel_index(uv, w, h)
        inside &= np.isfinite(ray) & (ray > 0)
        uv, ray = uv[inside], ray[inside]
        used, held = holdout_split(len(ray), self.holdout_fraction, self.seed)
        if len(held) and not len(used):
            raise InputError(self.source, f"every one of the {len(ray)} LiDAR points in the image is held out "
                                          f"(--lidar-holdout {self.holdout_fraction:g}): none is left to complete "
                                          "from; hold out a smaller fraction")
        try:
            done = complete(sparse_image(uv[used], ray[used], w, h), self.method, self.sky,
                            image=image, checkpoint=self.checkpoint, camera=self.camera)
        except ValueError as exc:
            raise InputError(self.source, str(exc)) from None
        record = {"points_in_image": int(len(ray)), "points_used": int(len(used)),
                  "points_held_out": int(len(held)), "holdout_fraction": self.holdout_fraction,
                  "holdout_seed": self.seed if len(held) else None, **done.record}
        if len(held) and self.holdout_path:
            write_holdout(self.holdout_path, uv[held], ray[held], w, h, self.camera)
            record["holdout_file"] = self.holdout_path
        if len(held) and self.depth_path:
            from fogsim.io.depth_files import write_depth

            write_depth(self.depth_path, done.ray)
            record["completion_file"] = self.depth_path
        return done.ray, None, record


# ----------------------------------------------------------------------------- hold-out files
def write_holdout(path, uv: np.ndarray, ray: np.ndarray, width: int, height: int,
                  camera: Intrinsics | None = None) -> None:
    """Write held-out points (see the module doc for the fields), atomically."""
    from fogsim.io.atomic import atomic_write_bytes

    fields = {"u": np.asarray(uv[:, 0], np.float32), "v": np.asarray(uv[:, 1], np.float32),
              "ray": np.asarray(ray, np.float32), "width": np.int64(width), "height": np.int64(height)}
    if camera is not None:
        K = camera if (camera.width, camera.height) == (width, height) else camera.scaled(width, height)
        fields |= {"fx": np.float64(K.fx), "fy": np.float64(K.fy), "cx": np.float64(K.cx), "cy": np.float64(K.cy)}
    buf = io.BytesIO()
    np.savez(buf, **fields)
    atomic_write_bytes(path, buf.getvalue())


@dataclass
class Holdout:
    """Held-out points of one image: ``uv`` N×2 px, ``ray`` N m, the image size, its camera (or None)."""

    uv: np.ndarray
    ray: np.ndarray
    width: int
    height: int
    camera: Intrinsics | None


def read_holdout(path) -> Holdout:
    """Read a hold-out file (never unpickling); any problem is an InputError naming it."""
    doc = load_npz(path, HoldoutFile)  # never unpickles; a truncated or non-zip file is one line
    u, v, ray = (np.asarray(x, np.float64) for x in (doc.u, doc.v, doc.ray))
    if not len(u) == len(v) == len(ray):
        raise InputError(path, f"LiDAR hold-out file: u, v, ray differ in length ({len(u)}, {len(v)}, {len(ray)})")
    width, height = doc.width, doc.height
    camera = None
    if None not in (doc.fx, doc.fy, doc.cx, doc.cy):
        try:
            camera = Intrinsics(doc.fx, doc.fy, doc.cx, doc.cy, width, height)
        except ValueError as exc:
            raise InputError(path, f"LiDAR hold-out file: unusable camera ({exc})") from None
    return Holdout(np.stack([u, v], 1), ray.astype(np.float32), width, height, camera)


# ----------------------------------------------------------------------------- Waymo wiring
def waymo_points_source(sample) -> PointsSource:
    """The points source of a Waymo sample: its frame's
    :class:`fogsim.readers.waymo.lidar.LidarPoints` (v1 record or v2 split folder and key),
    called with the sample's camera name."""
    from fogsim.readers.waymo.lidar import lidar_points_for_sample

    return partial(lidar_points_for_sample(sample), sample.meta.get("camera", "FRONT"))


def meta_points_source(sample) -> PointsSource:
    """The points source a reader put in ``sample.meta["lidar_points"]`` (KITTI and STF:
    :class:`fogsim.readers.kitti.samples.KittiPoints`): pass it as ``points_source`` to :func:`lidar_samples`
    (with ``has_lidar=None``: every KITTI frame has its scan)."""
    source = sample.meta.get("lidar_points")
    if source is None:
        raise InputError(sample.source, "this sample has no LiDAR points source (meta['lidar_points'])")
    return source


def waymo_has_lidar(sample) -> bool:
    """Whether a Waymo sample's frame has LiDAR data (:func:`fogsim.readers.waymo.lidar.frame_has_lidar`)."""
    from fogsim.readers.waymo.lidar import frame_has_lidar, lidar_points_for_sample

    return frame_has_lidar(lidar_points_for_sample(sample))


def lidar_samples(samples, depth_from: str, out: str | None, holdout: float = 0.0, seed: int = 0,
                  points_source: Callable = waymo_points_source, has_lidar: Callable | None = waymo_has_lidar,
                  dataset: str | None = None) -> list:
    """Every sample with :class:`LidarDepth` as its depth (``--depth-from lidar[:METHOD]``).

    Data in which no sample's frame has LiDAR (``has_lidar``; None: not checked) is a problem
    of the whole run: an :class:`InputError` naming ``dataset`` (default: the first sample),
    raised before anything is written; a frame without LiDAR among others fails on its own.

    ``holdout``: fraction of each image's points held out (seed per sample:
    :func:`fogsim.runs.sample_seed` of ``seed`` and the key); with ``out`` the held-out points
    and completions go to ``out/lidar_holdout/<key>.npz`` and ``out/lidar_depth/<key>.exr``.
    """
    from dataclasses import replace
    from pathlib import Path

    from fogsim.readers.base import DepthSpec
    from fogsim.runs import sample_seed

    method, checkpoint = parse_lidar(depth_from)
    if checkpoint is not None:
        from fogsim.depth.ila import cached_model

        given, checkpoint = checkpoint, str(Path(checkpoint).resolve())
        try:
            cached_model(checkpoint)  # checked once, before the output folder is claimed
        except InputError as exc:
            raise InputError(given, exc.problem) from None  # named as the user gave it
    if has_lidar is not None and samples and not any(has_lidar(s) for s in samples):
        raise InputError(dataset or samples[0].source,
                         f"no LiDAR in this data (none of its {len(samples)} images' frames has range images), "
                         "which --depth-from lidar completes: give depth maps with --depth-dir, or "
                         "--depth-from ila:CHECKPOINT")
    result = []
    for s in samples:
        held = out is not None and holdout > 0
        reader = LidarDepth(points_source(s), s.intrinsics, method, holdout, sample_seed(seed, s.key),
                            str(Path(out) / HOLDOUT_DIR / f"{s.key}.npz") if held else None,
                            str(Path(out) / DEPTH_DIR / f"{s.key}.exr") if held else None,
                            checkpoint, source=s.source)
        result.append(replace(s, depth=DepthSpec(f"{s.source} (LiDAR)", kind="ray", reader=reader)))
    return result

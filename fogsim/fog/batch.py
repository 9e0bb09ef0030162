"""Fog a dataset at several levels: shards, resume, worker processes, progress, summary.

Two output layouts:

* **images only** (``FogJob.labels`` False, ``fogsim fog --no-labels``, or a dataset without
  labels): ``OUT/<level key>/<sample key>.png`` and beside it ``<sample key>.json``, the sidecar
  with every parameter that made the image. The sidecars are written last, so they mark a
  finished output: a restarted run skips samples whose sidecars all exist.
* **labelled dataset** (``FogJob.labels`` True: the samples have :attr:`Sample.labels`): the
  layout a render writes (:mod:`fogsim.dataset.layout`), frame = :func:`frame_from_key` of the
  sample key: ``images/<level>/<frame>.png``, ``labels/<level>/<frame>.txt`` (YOLO, kept records
  only), then ``meta/<frame>.json`` last (it marks the frame done): the sidecar content (levels,
  airlight, depth source and coverage, camera) plus ``objects`` (every annotation, with
  ``distance_m`` and ``distance_source``), ``classes`` and ``source``. The dataset-wide files
  (COCO, split lists, data YAMLs, ``dataset.json``, contact sheet) are written by
  :func:`finalize_dataset`, once every shard is done. The label reader runs where the image is
  read (in the worker); its annotations are checked by :mod:`fogsim.fog.labelled`. Real
  annotations are kept as annotated; ``min_pixels`` > 0 turns kept records with fewer pixels
  into ignore regions.

With ``FogJob.lidar`` (``--lidar``) every sample with a scan source also gets each level's scan,
outcome file and, for KITTI-style sources, KITTI-tree frame (:mod:`fogsim.fog.lidar_levels`), written
before the level's sidecar or the frame's meta; per-object counts go into the meta's records and the
cross-sensor table into ``dataset.json`` at finalize (:mod:`fogsim.dataset.lidar`). :func:`run` also drives
a LiDAR-only job (:class:`fogsim.fog.points.PointsJob`).

``OUT/fogsim_run.json`` holds the run parameters (labels: ``"labels": {"classes", "min_pixels"}``;
no ``labels`` key = images only); a run into an OUT made with other parameters is refused
rather than mixed.
"""
from __future__ import annotations

import multiprocessing
import os
import signal
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fogsim._version import __version__
from fogsim.camera import Intrinsics
from fogsim.console import progress_bar
from fogsim.dataset.layout import DatasetLayout, frame_from_key
from fogsim.dataset.reader import frame_records
from fogsim.dataset.writer import check_train_fraction, finalize, write_frame_labels
from fogsim.errors import InputError, unexpected
from fogsim.fog.depth_input import check_aspect, check_sample, sample_distance
from fogsim.fog.engine import ESTIMATE, FogSettings
from fogsim.fog.labelled import SPLIT_BY, check_labelled, checked_records, key_folder
from fogsim.fog.levels import FogLevel
from fogsim.fog.lidar_levels import FrameLidar, LidarOutput, scan_source
from fogsim.fog.visibility import attach_visibility
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import read_json, write_json
from fogsim.io.images import TO_8BIT, encode_image, to_8bit
from fogsim.io.parts import remove_stale_parts
from fogsim.io.pixel_bound import MAX_PIXELS, pixel_bound, pixel_limit_problem
from fogsim.lidar.bounds import max_scan_points
from fogsim.lidar.objects import MIN_POINTS
from fogsim.readers.base import Sample
from fogsim.runs import claim_output, sample_seed
from fogsim.schema.base import load_json
from fogsim.schema.documents import FogFrameMeta, FogRunFile
from fogsim.schema.presets import TRAIN_FRACTION
from fogsim.schema.vocabulary import model_word

RUN_FILE = "fogsim_run.json"


@dataclass(frozen=True)
class FogJob:
    """What to do to every sample: the levels (β), the fog record (:class:`~fogsim.fog.engine.FogSettings`:
    model, airlight — RGB in 8-bit units or ``"estimate"`` —, blend space, kernel, heterogeneity,
    scatter parameters), how depth holes are filled and where it all goes."""

    levels: tuple[FogLevel, ...]
    out: str
    fog: FogSettings = FogSettings()
    fill: str = "none"
    seed: int = 0
    image_format: str = "png"
    inputs: dict = field(default_factory=dict, hash=False)  # what is read and how (see cli._inputs)
    labels: bool = False          # write the labelled dataset layout (see the module docstring)
    classes: tuple[str, ...] = ()  # the dataset's own class list (labels only)
    min_pixels: int = 0           # kept annotations with fewer pixels → ignore regions (labels only)
    max_pixels: int = MAX_PIXELS  # an image of more pixels fails (--max-pixels; not a run parameter)
    lidar: LidarOutput | None = None  # --lidar: each level's scan too (fogsim.fog.lidar_levels)

    def parameters(self) -> dict:
        """The run parameters recorded in ``fogsim_run.json`` and compared on resume (the fog record's
        keys, :meth:`FogSettings.record`, beside the levels and the inputs; ``lidar`` only with ``--lidar``,
        so a run without it resumes as before)."""
        return {"levels": [lv.to_dict() for lv in self.levels], **self.fog.record(),
                "airlight_units": "8-bit (255 = white)", "fill": self.fill, "seed": self.seed,
                "image_format": self.image_format, "inputs": self.inputs} \
            | ({"labels": {"classes": list(self.classes), "min_pixels": self.min_pixels}} if self.labels else {}) \
            | ({"lidar": self.lidar.parameters()} if self.lidar is not None else {})

    @property
    def layout(self) -> DatasetLayout:
        return DatasetLayout(self.out)

    def paths(self, sample: Sample, level: FogLevel) -> tuple[Path, Path]:
        """(image, sidecar) of one sample and level; labelled: (image, the frame's meta file)."""
        if self.labels:
            frame = frame_from_key(sample.key)
            return self.layout.image(level.key, frame), self.layout.meta(frame)
        base = Path(self.out) / level.key / sample.key
        return base.with_name(base.name + "." + self.image_format), base.with_name(base.name + ".json")

    def done(self, sample: Sample) -> bool:
        if self.labels:
            return self.layout.frame_done(frame_from_key(sample.key))
        return all(self.paths(sample, lv)[1].is_file() for lv in self.levels)

    # the interface :func:`run` drives (a LiDAR-only run's job, fogsim.fog.points.PointsJob, has it too)
    unit = "images"

    def check(self, samples: list[Sample]) -> None:
        """The run-wide checks (:func:`check_run_wide`), before the output folder is claimed."""
        if self.lidar is not None:
            max_scan_points()  # FOGSIM_MAX_SCAN_POINTS, when set, must be a bound
        with pixel_bound(self.max_pixels):
            check_run_wide(samples, self)

    def fog_one(self, sample: Sample) -> None:
        with pixel_bound(self.max_pixels):  # images and depth are refused by their headers, before decoding
            fog_sample(self, sample)


def fog_sample(job: FogJob, sample: Sample) -> None:
    """Fog one sample at every level of the job and write images + sidecars (labelled: images,
    YOLO labels, then the frame's meta)."""
    image = sample.read_image()
    h, w = image.shape[:2]
    if why := pixel_limit_problem(w, h, job.max_pixels, "fog"):
        raise InputError(sample.source, why)  # before its depth is read and its levels are made
    records = checked_records(sample, job.classes, job.min_pixels, w, h) if job.labels else None
    dist = sample_distance(sample, w, h, job.fill, image)
    seed = sample_seed(job.seed, sample.key)
    fog = job.fog
    density = fog.density((h, w), np.random.default_rng(seed))
    airlight = fog.airlight_for(image)
    K = dist.record.get("intrinsics") or (sample.intrinsics.to_dict() if sample.intrinsics else None)
    fogger = fog.fogger(image, dist.ray, Intrinsics.from_dict(K) if K else None, density=density, airlight=airlight)
    common = {"source": sample.source, "key": sample.key, **fog.record(),
              "airlight_rgb": [round(float(a), 3) for a in airlight],
              "airlight_method": "dark-channel estimate" if fog.airlight == ESTIMATE else "constant",
              **dist.record, "sample_seed": seed if fog.heterogeneity else None,
              "fogsim_version": __version__, "bit_depth": _bit_depth(image.dtype, job.image_format)}
    if not job.labels and (sample.meta or {}).get("labels_missing"):
        common["labels_missing"] = sample.meta["labels_missing"]  # why an images-only sidecar has no labels
    source = scan_source(sample) if job.lidar is not None else None
    lidar = None if source is None else FrameLidar(fog, job.lidar, source, job.out, job.seed, density, records)
    images = {}
    for level in job.levels:
        img_path, meta_path = job.paths(sample, level)
        foggy = fogger(level.beta)
        if job.image_format == "jpg":  # JPEG is 8-bit: 16-bit input is scaled, never saturated
            foggy = to_8bit(foggy)
        data = encode_image(foggy, "." + job.image_format)
        atomic_write_bytes(img_path, data)
        if lidar is not None:  # the level's scan, before the sidecar / meta that mark the sample done
            fogged = lidar.level(level)
            lidar.write_kitti(level, img_path if job.image_format == "png" else encode_image(foggy, ".png"), fogged)
        if job.labels:
            images[level.key] = foggy
        else:
            extra = {} if lidar is None else {"lidar": {"sensor": lidar.sensor.name, **lidar.levels[level.key]}}
            write_json(meta_path, {"level": level.to_dict(), **common, **extra})
    if job.labels:
        # per object and level: transmission, box-based contrast, visible (real data has no masks)
        attach_visibility(records, image, images, {lv.key: lv.beta for lv in job.levels})
        if lidar is not None:
            lidar.attach(records)
        frame = frame_from_key(sample.key)
        write_frame_labels(job.layout, frame, job.levels, records, w, h)
        coverage = None if dist.record.get("hole_fraction") is None else round(1 - dist.record["hole_fraction"], 6)
        write_json(job.layout.meta(frame), {
            "frame": frame, "width": w, "height": h, "source": sample.source, "classes": list(job.classes),
            "objects": records, "levels": [lv.to_dict() for lv in job.levels], **common,
            "depth_coverage": coverage, "camera": K, "sample": json_meta(sample.meta)}
            | ({"lidar": lidar.record()} if lidar is not None else {}))


def json_meta(meta: dict | None) -> dict | None:
    """A sample's meta as a frame record holds it: the JSON values only (a reader's picklable sources,
    such as the scan source under ``lidar_points``, are left out); None when nothing is left."""
    def plain(v) -> bool:
        if v is None or isinstance(v, (str, bool, int, float)):
            return True
        if isinstance(v, (list, tuple)):
            return all(plain(x) for x in v)
        return isinstance(v, dict) and all(isinstance(k, str) and plain(x) for k, x in v.items())
    out = {k: v for k, v in (meta or {}).items() if plain(v)}
    return out or None


def _bit_depth(dtype, image_format: str) -> dict:
    """Bits per channel of the input and of the written image, and the conversion between them."""
    bits = np.dtype(dtype).itemsize * 8
    out = 8 if image_format == "jpg" else bits
    return {"input": bits, "output": out} | ({"conversion": TO_8BIT} if out != bits else {})


@dataclass
class Summary:
    total: int = 0
    done: int = 0
    skipped: int = 0
    failed: list[tuple[str, str]] = field(default_factory=list)
    seconds: float = 0.0

    def line(self, job: FogJob) -> str:
        return (f"fogged {self.done} of {self.total} {job.unit} × {len(job.levels)} levels "
                f"({self.skipped} already done, {len(self.failed)} failed) in {self.seconds:.1f} s "
                f"→ {job.out}")


def upgrade_parameters(stored: dict) -> dict:
    """A ``fogsim_run.json``'s parameters in today's words (:mod:`fogsim.schema.vocabulary`): before
    fogsim 0.4 a Koschmieder run said ``"model": "standard"`` or ``"extended"``, a scatter run
    ``"model": "standard"`` beside ``"fog_model": "scatter"`` (with kernel and heterogeneity None); before 0.6
    a ``lidar_fog`` block had no ``hahner_variant`` and ``stf_beta_field`` (their defaults change nothing for
    the models it could name)."""
    p = dict(stored)
    if "fog_model" in p:
        p["model"] = model_word(p.pop("fog_model"))
        if p["model"] != "koschmieder":
            p.pop("kernel", None)
            p.pop("heterogeneity", None)
    elif isinstance(p.get("model"), str):
        p["model"] = model_word(p["model"])
    if isinstance(p.get("lidar_fog"), dict):  # before 0.6 the LiDAR fog block had no published models' options
        p["lidar_fog"] = {"hahner_variant": "batch", "stf_beta_field": "homogeneous", **p["lidar_fog"]}
    return p


def check_run_file(job: FogJob, environment: dict) -> None:
    """Claim ``OUT/fogsim_run.json`` for this job, or refuse a folder holding another run (one
    written by an older fogsim, in its words, resumes: :func:`upgrade_parameters`)."""
    claim_output(Path(job.out) / RUN_FILE, job.parameters(), environment, what="run", upgrade=upgrade_parameters)


def _worker(args):
    job, sample = args
    try:
        job.fog_one(sample)
        return sample.source, None
    except (InputError, ValueError, OSError) as exc:
        return sample.source, str(exc)
    except Exception as exc:  # keep going; report the unexpected with its type
        return sample.source, unexpected(exc)


def run(samples: list[Sample], job: FogJob, workers: int = 1, resume: bool = True,
        progress: bool = True, environment: dict | None = None) -> Summary:
    """Fog ``samples`` (already sharded) under ``job`` (a :class:`FogJob`, or any job with its ``check``,
    ``fog_one``, ``done``, ``parameters``, ``out``, ``levels`` and ``unit``); never raises for a single bad
    sample."""
    t0 = time.perf_counter()
    job.check(samples)  # before the folder is claimed: the corrected rerun must be accepted
    Path(job.out).mkdir(parents=True, exist_ok=True)
    check_run_file(job, environment or {})
    remove_stale_parts(job.out)  # a killed run's temporary files
    summary = Summary(total=len(samples))
    todo = [s for s in samples if not (resume and job.done(s))]
    summary.skipped = len(samples) - len(todo)
    bar = progress_bar(len(todo), "fog", "img" if job.unit == "images" else job.unit.rstrip("s"), not progress)
    results = map(_worker, ((job, s) for s in todo))
    pool = None
    if workers > 1 and len(todo) > 1:
        # spawn, not fork: a forked child inherits library thread pools (OpenEXR, OpenCV)
        # mid-state and can deadlock on its first EXR read
        # workers start with SIGINT ignored (inherited through exec, kept by Python), so a Ctrl-C
        # even during their start-up reaches the parent alone
        default_sigint = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            pool = ProcessPoolExecutor(max_workers=workers, initializer=_init_worker, initargs=(os.getpid(),),
                                       mp_context=multiprocessing.get_context("spawn"))
            results = pool.map(_worker, ((job, s) for s in todo), chunksize=1)
        finally:
            signal.signal(signal.SIGINT, default_sigint)
    try:
        for source, error in results:
            if error is None:
                summary.done += 1
            else:
                summary.failed.append((source, error))
                bar.write(f"error: {error}" if error.startswith(source) else f"error: {source}: {error}")
            bar.update(1)
    finally:
        bar.close()
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    summary.seconds = time.perf_counter() - t0
    return summary


def check_run_wide(samples: list[Sample], job: FogJob | None = None) -> None:
    """Problems of the whole run, raised as :class:`SetupError` (exit 2) before anything is
    written: a sample without depth, planar depth without a camera, and — on the first sample
    that has intrinsics — intrinsics of another aspect ratio than its image; for a labelled
    job, a sample without labels and two samples with one frame name. A bad file is
    not a run-wide problem: it is reported for its sample during the run."""
    for sample in samples:
        check_sample(sample)
    if job is not None and job.labels:
        check_labelled(samples, job.image_format)
    first = next((s for s in samples if s.intrinsics is not None), None)
    if first is None:
        return
    try:
        h, w = first.read_image().shape[:2]
    except InputError:
        return  # the sample's own problem: reported with it
    K = first.intrinsics
    if (K.width, K.height) != (w, h):
        check_aspect(K, w, h, first.source)


def finalize_dataset(out: str | Path, train_fraction: float | None = None, split_by: str | None = None) -> dict:
    """Write the dataset-wide files of a labelled ``fogsim fog`` run (COCO per level with the
    dataset's classes and ``distance_m`` per annotation, split lists, data YAMLs,
    ``dataset.json``, contact sheet) from its committed frames and ``fogsim_run.json``.
    ``train_fraction`` and ``split_by`` (one of :data:`~fogsim.fog.labelled.SPLIT_BY`): None = the run's own (its
    recorded inputs), else :data:`~fogsim.dataset.writer.TRAIN_FRACTION` and ``"frame"``.
    The split seed is the run's ``--seed``; ``split_by="folder"`` keeps the frames of one input
    folder (:func:`~fogsim.fog.labelled.key_folder`: a Waymo segment, a Cityscapes city) on one side of the split.
    Returns ``dataset.json``'s content (with ``absent_frames``, not written: how many of the
    run's samples have no frame yet, when the run file knows how many it has)."""
    run_file = Path(out) / RUN_FILE
    if not run_file.is_file():
        raise InputError(out, f"no {RUN_FILE} here: not a fogsim fog output to finalize")
    run = load_json(run_file, FogRunFile)
    params = upgrade_parameters(read_json(run_file)["parameters"])  # checked above; today's words for dataset.json
    if params.get("points"):
        raise InputError(run_file, "this run fogged scans alone (--points): there is no dataset to finalize")
    if run.parameters.labels is None:
        raise InputError(run_file, "this run wrote images without labels (--no-labels): there is no "
                                   "dataset to finalize")
    inputs = run.parameters.inputs
    if train_fraction is None:
        train_fraction = inputs.get("train_fraction", TRAIN_FRACTION)
    train_fraction = check_train_fraction(train_fraction, "--train-fraction")
    split_by = split_by or inputs.get("split_by", "frame")
    if split_by not in SPLIT_BY:
        raise ValueError(f"--split-by must be one of {', '.join(SPLIT_BY)}, got {split_by!r}")
    levels = [FogLevel(lv.key, lv.name, lv.beta) for lv in run.parameters.levels]
    classes = tuple(run.parameters.labels.classes)
    manifest = {"source": "fogsim fog", "fog": {k: v for k, v in params.items() if k != "inputs"},
                "inputs": inputs, "seed": run.parameters.seed}
    group = None if split_by == "frame" else ("the sample key's folder", lambda meta: key_folder(meta["key"]))
    records = frame_records(out, FogFrameMeta)
    lidar = params.get("lidar") or {}
    summary = finalize(DatasetLayout(out), levels, manifest, train_fraction, seed=run.parameters.seed,
                       classes=classes, split_group=group, records=records,
                       lidar_min_points=lidar.get("min_points", MIN_POINTS))
    if run.samples is not None and len(records.frames) < run.samples:
        summary["absent_frames"] = max(0, run.samples - len(records.frames) - len(records.skipped))
    return summary


def _init_worker(parent_pid: int):
    """A worker dies with its parent (SIGKILL/SIGTERM of the parent included) and leaves
    Ctrl-C to it: the parent stops the pool and exits 130."""
    import cv2

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent_pid)
    cv2.setNumThreads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")


def _die_with_parent(parent_pid: int) -> None:
    """Linux: the kernel sends SIGKILL when the parent dies (prctl PR_SET_PDEATHSIG); elsewhere
    a daemon thread polls the parent's pid."""
    import ctypes
    import threading

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        armed = libc.prctl(1, int(signal.SIGKILL), 0, 0, 0) == 0  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        armed = False
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)
    if armed:
        return

    def watch():
        while os.getppid() == parent_pid:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()

"""Fog-as-augmentation speed: images/s of each front end at 640×640 and 1920×1280, against
albumentations' ``RandomFog`` measured in the same run, and the cost fog adds to an Ultralytics
training sample against Ultralytics' own loading + augmentation of that sample.

Every CPU contender runs on one core (OpenCV and torch set to 1 thread; NumPy's elementwise
work is single-threaded); medians of interleaved repeats (:mod:`fogsim.bench.timing`).

  numpy            :func:`fogsim.augment.random_fog` (draw β, fog; the reference)
  albumentations   ``A.Compose([fogsim.augment.Fog()])`` (needs albumentations)
  torch CPU / CUDA :func:`fogsim.augment.fog_batch`, batches of 8, uint8 in and out (needs torch;
                   CUDA when a GPU is present, synchronised)
  RandomFog        albumentations' ``RandomFog`` (blurred random circles; no depth), the baseline

Ultralytics (needs the 'detect' extra): a folder of 1920×1280 PNG frames with depth, loaded at
``imgsz`` 640 by its ``YOLODataset`` with the default training augmentation (mosaic of 4 loads,
perspective, HSV, flip), one sample per call, against the same with
:func:`fogsim.detection.augmented.foggy_dataset` (every load fogged from its depth).

    fogsim bench augment [--repeat 5]
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from fogsim.augment import FogSpec, random_fog
from fogsim.bench.timing import median_ms
from fogsim.camera import planar_to_ray
from fogsim.dataset.reader import read_distance
from fogsim.fog.synthetic import demo_scene
from fogsim.io.depth_files import write_depth
from fogsim.io.documents import write_json
from fogsim.io.images import write_image

SIZES = ((640, 640), (1920, 1280))
BATCH = 8
ULTRALYTICS_FRAMES = 8


def _have(module: str) -> bool:
    import importlib.util
    return importlib.util.find_spec(module) is not None


def contenders(rgb: np.ndarray, ray: np.ndarray, rng: np.random.Generator) -> dict[str, tuple]:
    """name → (function, images per call) for one image size."""
    spec = FogSpec()
    out = {"numpy": (lambda: random_fog(rgb, ray, rng, spec), 1)}
    if _have("albumentations"):
        import albumentations as A

        from fogsim.augment import Fog
        ours = A.Compose([Fog(beta=(0, 0.12))], additional_targets={"depth": "mask"}, seed=0)
        theirs = A.Compose([A.RandomFog(fog_coef_range=(0.3, 1.0), p=1.0)], seed=0)
        out["albumentations"] = (lambda: ours(image=rgb, depth=ray), 1)
        out["RandomFog"] = (lambda: theirs(image=rgb), 1)
    if _have("torch"):
        from fogsim.augment.torch_fog import batch_timer, cuda_available
        for device in ["cpu", *(["cuda"] if cuda_available() else [])]:
            out[f"torch {device.upper()} ×{BATCH}"] = (batch_timer(rgb, ray, BATCH, device, rng, spec), BATCH)
    return out


def write_frames(root: Path, n: int) -> Path:
    """``n`` 1920×1280 frames in fogsim's layout (images/clear, labels/clear, depth, meta)."""
    rng = np.random.default_rng(1)
    for i in range(n):
        frame = f"{i:06d}"
        rgb, depth, K = demo_scene(rng, 1920, 1280)
        write_image(root / "images" / "clear" / f"{frame}.png", rgb)
        (root / "labels" / "clear").mkdir(parents=True, exist_ok=True)
        (root / "labels" / "clear" / f"{frame}.txt").write_text("0 0.5 0.6 0.1 0.1\n1 0.3 0.7 0.05 0.2\n")
        write_depth(root / "depth" / f"{frame}.exr", depth)
        write_json(root / "meta" / f"{frame}.json", {"frame": frame, "width": 1920, "height": 1280, "objects": [],
                                                     "camera": {"intrinsics": K.to_dict()},
                                                     "depth": {"file": f"depth/{frame}.exr", "kind": "planar Z"}})
    return root


def ultralytics_ms(repeat: int) -> dict[str, float] | None:
    """Median ms per training sample: Ultralytics' own, and with fog on every load."""
    if not (_have("ultralytics") and _have("torch")):
        return None
    from fogsim.detection.augmented import training_datasets
    from fogsim.detection.yolo import load_ultralytics

    os.environ.setdefault("YOLO_VERBOSE", "False")  # read on Ultralytics' first import: its log off

    with tempfile.TemporaryDirectory() as tmp:
        root = write_frames(Path(tmp) / "ds", ULTRALYTICS_FRAMES)
        load_ultralytics(Path(tmp) / "config")
        plain, foggy = training_datasets(root, "clear", FogSpec(), {0: "car", 1: "pedestrian"})
        counter = {"plain": 0, "foggy": 0}

        def sample(ds, name):
            def run():
                counter[name] += 1
                return ds[counter[name] % len(ds)]
            return run
        for i in range(len(foggy)):  # warm-up: every frame's depth in the cache (DEPTH_CACHE frames are kept)
            plain[i], foggy[i]
        ms = median_ms({"plain": sample(plain, "plain"), "foggy": sample(foggy, "foggy")}, repeat * 8)
        ms["depth read"] = median_ms({"read": lambda: read_distance(root, "000000")}, repeat)["read"]
        return ms


def run(repeat: int = 5) -> int:
    cv2.setNumThreads(1)
    rng = np.random.default_rng(0)
    rows = {}
    for w, h in SIZES:
        rgb, depth, K = demo_scene(np.random.default_rng(0), w, h)
        ray = planar_to_ray(depth, K)
        fns = contenders(rgb, ray, rng)
        slow = {k: v for k, v in fns.items() if k == "RandomFog"}
        ms = median_ms({k: f for k, (f, _) in fns.items() if k not in slow}, repeat)
        if slow:  # RandomFog takes seconds at 1920×1280: fewer repeats
            ms |= median_ms({k: f for k, (f, _) in slow.items()}, max(3, repeat // 2) if w < 1000 else 3)
        rows[(w, h)] = {k: fns[k][1] * 1e3 / ms[k] for k in fns}
    names = list(next(iter(rows.values())))
    print(f"bench augment: images/s, one core (OpenCV and torch CPU 1 thread), medians of {repeat} interleaved "
          "repeats")
    print(f"{'size':<11}" + "".join(f"{n:>17}" for n in names) + (f"{'numpy/RandomFog':>17}" if "RandomFog" in names
                                                                   else ""))
    for (w, h), r in rows.items():
        ratio = f"{r['numpy'] / r['RandomFog']:16.1f}×" if "RandomFog" in r else ""
        print(f"{w}×{h:<6}" + "".join(f"{r[n]:17.1f}" for n in names) + ratio)
    if "RandomFog" not in names:
        print("  (albumentations not installed: no RandomFog baseline, no albumentations row)")
    ul = ultralytics_ms(repeat)
    summary = f"bench augment: numpy {rows[SIZES[1]]['numpy']:.1f} images/s at 1920×1280"
    if "RandomFog" in names:
        summary += f" = {rows[SIZES[1]]['numpy'] / rows[SIZES[1]]['RandomFog']:.0f}× RandomFog"
    if ul is not None:
        added = ul["foggy"] - ul["plain"]
        print(f"Ultralytics training sample (1920×1280 PNG → imgsz 640, mosaic + default augmentation, one call): "
              f"{ul['plain']:.1f} ms; with fog on every load (FoggyDataset): {ul['foggy']:.1f} ms "
              f"→ fog adds {added:.1f} ms = {added / ul['plain']:.0%} of Ultralytics' own (depth cached; a frame "
              f"beyond the cache reads its 1920×1280 depth again: {ul['depth read']:.1f} ms)")
        summary += f"; fog adds {added / ul['plain']:.0%} to an Ultralytics training sample ({ul['plain']:.0f} ms)"
    else:
        print("  (Ultralytics not installed: no training-sample comparison)")
    print(summary)  # the summary line (--quiet)
    return 0

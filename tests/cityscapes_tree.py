"""A small Cityscapes tree with instance labels, built from the format's spec
(leftImg8bit/, disparity/, camera/, gtFine/*_gtFine_instanceIds.png), with every object's
mask, class and planar depth known, so labels and distances can be checked by hand.

Frame ``aachen_000000_000019`` (64×32, fx = fy = 50 px, u0 = 31.5, v0 = 15.5, baseline 0.2 m,
so d = 10/Z px), instanceIds values:

* car 26000: x 4..14, y 10..20 (box [4, 10, 15, 21)), Z = 10 m;
* car 26001: x 20..29, y 12..19 (box [20, 12, 30, 20)), Z = 20 + 0.5·(x − 20) m, disparity holes
  at x 20..23 (those pixels must not enter its distance);
* person 24000: x 40..43, y 8..21 (box [40, 8, 44, 22)), Z = 15 m;
* person 24001: x 60..61, y 2..3, every pixel a disparity hole → distance unknown;
* cargroup 26: x 48..57, y 20..25 → ignore region, class car;
* caravan 29000: x 2..9, y 24..29 → ignore region, class car;
* road 7 below y 16 elsewhere, building 11 above; background Z = 40 m.

Frame ``aachen_000001_000019`` is the same scene mirrored left-right.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fogsim.camera import encode_disparity_png
from fogsim.io.images import write_image

W, H = 64, 32
CAMERA = {"extrinsic": {"baseline": 0.2}, "intrinsic": {"fx": 50.0, "fy": 50.0, "u0": 31.5, "v0": 15.5}}
BASES = ("aachen_000000_000019", "aachen_000001_000019")


def scene() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(instanceIds uint16, planar depth Z metres, hole mask) of the first frame."""
    ids = np.full((H, W), 11, np.uint16)
    ids[16:] = 7
    z = np.full((H, W), 40.0)
    holes = np.zeros((H, W), bool)
    ids[10:21, 4:15], z[10:21, 4:15] = 26000, 10.0
    ids[12:20, 20:30] = 26001
    z[12:20, 20:30] = 20 + 0.5 * (np.arange(20, 30) - 20)[None, :]
    holes[12:20, 20:24] = True
    ids[8:22, 40:44], z[8:22, 40:44] = 24000, 15.0
    ids[2:4, 60:62], z[2:4, 60:62] = 24001, 12.0
    holes[2:4, 60:62] = True
    ids[20:26, 48:58], z[20:26, 48:58] = 26, 25.0
    ids[24:30, 2:10], z[24:30, 2:10] = 29000, 8.0
    return ids, z, holes


def make_tree(root: Path, split: str = "val", gt: bool = True) -> Path:
    """Write the two frames under ``root`` (with gtFine unless ``gt`` is False); returns root."""
    ids, z, holes = scene()
    rng = np.random.default_rng(4)
    for k, base in enumerate(BASES):
        flip = (lambda a: a[:, ::-1].copy()) if k else (lambda a: a)
        rgb = rng.integers(40, 200, (H, W, 3)).astype(np.uint8)
        for value, colour in ((26000, (200, 30, 30)), (26001, (30, 30, 200)), (24000, (30, 200, 30))):
            rgb[ids == value] = colour
        city = root / "leftImg8bit" / split / "aachen"
        write_image(city / f"{base}_leftImg8bit.png", flip(rgb))
        disp = encode_disparity_png(np.where(holes, 0.0, 0.2 * 50.0 / z))
        write_image(root / "disparity" / split / "aachen" / f"{base}_disparity.png", flip(disp))
        cam = root / "camera" / split / "aachen" / f"{base}_camera.json"
        cam.parent.mkdir(parents=True, exist_ok=True)
        cam.write_text(json.dumps(CAMERA))
        if gt:
            write_image(root / "gtFine" / split / "aachen" / f"{base}_gtFine_instanceIds.png", flip(ids))
    return root


def hand_distance(root: Path, base: str, value: int, split: str = "val") -> float | None:
    """Median ray distance over the pixels of instance ``value`` with valid disparity, computed
    from the files with numpy alone (d = (p − 1)/256, Z = B·fx/d, ℓ = Z·√(1 + x² + y²))."""
    import cv2

    ids = cv2.imread(str(root / "gtFine" / split / "aachen" / f"{base}_gtFine_instanceIds.png"), cv2.IMREAD_UNCHANGED)
    p = cv2.imread(str(root / "disparity" / split / "aachen" / f"{base}_disparity.png"), cv2.IMREAD_UNCHANGED)
    v, u = np.nonzero((ids == value) & (p > 0))
    if len(u) < 10:
        return None
    d = (p[v, u].astype(np.float64) - 1) / 256
    zz = 0.2 * 50.0 / d
    ray = zz * np.sqrt(1 + ((u - 31.5) / 50) ** 2 + ((v - 15.5) / 50) ** 2)
    return float(np.median(ray))

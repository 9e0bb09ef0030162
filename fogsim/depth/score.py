"""Scoring any depth against held-out LiDAR points or the exact depth of a rendered dataset.

``fogsim depth score``. The prediction is a folder of metric depth maps (EXR / ``.npy`` /
16-bit PNG × ``png_scale``, :func:`fogsim.io.depth_files.read_depth_file`; ≥ 1e9 = no hit = +inf), named
by the image's key (``<key><suffix><ext>``), **planar** Z (e.g. ``fogsim ila predict``) or
**ray** distance (e.g. ``OUT/lidar_depth`` of ``fogsim fog --depth-from lidar``). Ground truth:

* **held-out LiDAR points** (``OUT/lidar_holdout/<key>.npz`` of a fogged Waymo run): ray
  distances at sub-pixel positions; the prediction is read at each point's pixel (integer =
  pixel centre) and a planar one is converted to ray distance there with the hold-out file's
  camera (or ``intrinsics``);
* **exact rendered depth** (``depth/<frame>.exr`` of a fogsim dataset, planar Z): compared
  planar to planar, or, for a ray prediction, converted to ray distance with the frame's
  intrinsics (``meta/<frame>.json``).

Metrics (:func:`fogsim.depth.metrics.depth_metrics`, no cap) per ground-truth distance bin
[lo, hi) of :data:`BINS` and overall, pooled over all images by pixel/point count (means of
means weighted by count; RMSE as the root of the pooled mean square). ``missing`` counts
ground-truth pixels whose prediction is a hole (0, NaN) or +inf: they are not in the metrics.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fogsim.camera import NO_HIT_DEPTH, Intrinsics, planar_to_ray, ray_factor
from fogsim.depth.metrics import depth_metrics
from fogsim.errors import InputError

BINS = (("0-10", 0.0, 10.0), ("10-20", 10.0, 20.0), ("20-40", 20.0, 40.0), ("40-80", 40.0, 80.0),
        ("80+", 80.0, np.inf))
MEANS = ("abs_rel", "sq_rel", "mae", "delta1", "delta2", "delta3")
ROOT_MEANS = ("rmse", "rmse_log")
PRED_KINDS = ("planar", "ray")


def binned_metrics(pred: np.ndarray, gt: np.ndarray) -> dict[str, dict]:
    """``{bin name: metrics}`` and ``"all"`` for arrays of one shape (points or pixels), metres,
    one kind; each record has the :func:`depth_metrics` keys and ``missing``."""
    pred = np.asarray(pred, np.float32)
    gt = np.asarray(gt, np.float32)
    if pred.shape != gt.shape:
        raise ValueError(f"prediction {pred.shape} and ground truth {gt.shape} differ in shape")
    has_gt = np.isfinite(gt) & (gt > 0)
    pred_ok = np.isfinite(pred) & (pred > 0)
    out = {}
    for name, lo, hi in BINS + (("all", 0.0, np.inf),):
        m = has_gt & (gt >= lo) & (gt < hi)
        rec = depth_metrics(pred, gt, m, cap_m=np.inf)
        rec["missing"] = int((m & ~pred_ok).sum())
        out[name] = rec
    return out


def pool(records: list[dict[str, dict]]) -> dict[str, dict]:
    """Pool per-image :func:`binned_metrics` by count (see the module doc)."""
    out = {}
    for name in [b[0] for b in BINS] + ["all"]:
        recs = [r[name] for r in records]
        n = np.array([r["pixels"] for r in recs], np.float64)
        total = float(n.sum())
        pooled: dict = {"pixels": int(total), "missing": int(sum(r["missing"] for r in recs))}
        for k in MEANS:
            pooled[k] = float(sum(w * r[k] for w, r in zip(n, recs) if w)) / total if total else float("nan")
        for k in ROOT_MEANS:
            pooled[k] = (float(np.sqrt(sum(w * r[k] ** 2 for w, r in zip(n, recs) if w) / total))
                         if total else float("nan"))
        out[name] = pooled
    return out


# ----------------------------------------------------------------------------- reading
def _pred_dir(pred) -> Path:
    path = Path(pred)
    if not path.is_dir():
        raise InputError(pred, "prediction folder not found")
    return path


def read_prediction(pred_dir: Path, key: str, suffix: str = "", png_scale: float | None = None,
                    listings: dict | None = None) -> tuple[np.ndarray, Path]:
    """The prediction for ``key`` (metres, ≥ 1e9 → +inf) and its file; InputError naming the
    expected file when there is none, or the file when it holds NaN / negative values."""
    from fogsim.io.depth_files import DEPTH_SUFFIXES, read_depth_file
    from fogsim.readers.folder import find_depth

    found = find_depth(pred_dir, key, suffix, listings)
    if found is None:
        raise InputError(pred_dir / f"{key}{suffix}{DEPTH_SUFFIXES[0]}",
                         f"prediction not found (nor with {', '.join(DEPTH_SUFFIXES[1:])})")
    depth = read_depth_file(found, png_scale)
    if np.isnan(depth).any():
        raise InputError(found, f"prediction has {int(np.isnan(depth).sum())} NaN pixels")
    if (depth < 0).any():
        raise InputError(found, f"prediction has {int((depth < 0).sum())} negative pixels")
    return np.where(depth >= NO_HIT_DEPTH, np.float32(np.inf), depth), found


def _size_check(pred: np.ndarray, pred_file: Path, width: int, height: int, truth: Path) -> None:
    if pred.shape != (height, width):
        raise InputError(pred_file, f"prediction is {pred.shape[1]}×{pred.shape[0]} but {truth} is for a "
                                    f"{width}×{height} image")


def holdout_files(root) -> tuple[Path, list[str]]:
    """The hold-out folder (``root/lidar_holdout`` or ``root`` itself) and its keys, sorted."""
    from fogsim.depth.lidar_source import HOLDOUT_DIR

    root = Path(root)
    if not root.is_dir():
        raise InputError(root, "hold-out folder not found (the --out of `fogsim fog --depth-from lidar "
                               "--lidar-holdout F`)")
    folder = root / HOLDOUT_DIR if (root / HOLDOUT_DIR).is_dir() else root
    keys = sorted(p.relative_to(folder).with_suffix("").as_posix() for p in folder.rglob("*.npz"))
    if not keys:
        raise InputError(root, f"no LiDAR hold-out files ({HOLDOUT_DIR}/<key>.npz): fog with "
                               "--depth-from lidar --lidar-holdout 0.1 first")
    return folder, keys


# ----------------------------------------------------------------------------- scoring
def score_holdout(pred, holdout_root, pred_kind: str = "planar", suffix: str = "",
                  png_scale: float | None = None, intrinsics: Intrinsics | None = None) -> dict:
    """Score the prediction folder ``pred`` against every held-out point under ``holdout_root``
    (ray distance; a planar prediction is converted at the points)."""
    from fogsim.camera import pixel_index
    from fogsim.depth.lidar_source import read_holdout

    _check_kind(pred_kind)
    pred_dir = _pred_dir(pred)
    folder, keys = holdout_files(holdout_root)
    images, listings = [], {}
    for key in keys:
        hfile = folder / f"{key}.npz"
        held = read_holdout(hfile)
        depth, pfile = read_prediction(pred_dir, key, suffix, png_scale, listings)
        _size_check(depth, pfile, held.width, held.height, hfile)
        row, col, inside = pixel_index(held.uv, held.width, held.height)
        row, col, gt = row[inside], col[inside], held.ray[inside]
        values = depth[row, col]
        if pred_kind == "planar":
            K = _camera(intrinsics or held.camera, held.width, held.height, hfile)
            values = values * ray_factor(K)[row, col]
        images.append({"key": key, "pred_file": str(pfile), "truth_file": str(hfile),
                       "bins": binned_metrics(values, gt)})
    return _result("held-out LiDAR points (ray distance)", pred_dir, pred_kind, images)


def score_dataset(pred, dataset, pred_kind: str = "planar", suffix: str = "",
                  png_scale: float | None = None) -> dict:
    """Score the prediction folder ``pred`` against the exact depth of every frame of the
    rendered dataset ``dataset`` (:class:`fogsim.dataset.layout.DatasetLayout`)."""
    from fogsim.dataset.layout import DatasetLayout
    from fogsim.io.depth_files import read_depth_file
    from fogsim.schema.base import load_json
    from fogsim.schema.documents import FrameCamera

    _check_kind(pred_kind)
    pred_dir = _pred_dir(pred)
    layout = DatasetLayout(dataset)
    if not layout.root.is_dir():
        raise InputError(dataset, "dataset folder not found")
    frames = layout.done_frames()
    if not frames:
        raise InputError(dataset, "not a fogsim dataset: no frames (meta/<frame>.json)")
    images, listings = [], {}
    for frame in frames:
        gfile = layout.depth(frame)
        gt = read_depth_file(gfile)
        gt = np.where(gt >= NO_HIT_DEPTH, np.float32(np.inf), gt)
        depth, pfile = read_prediction(pred_dir, frame, suffix, png_scale, listings)
        _size_check(depth, pfile, gt.shape[1], gt.shape[0], gfile)
        if pred_kind == "ray":
            meta = load_json(layout.meta(frame), FrameCamera)
            K = Intrinsics.from_dict(meta.camera.intrinsics, str(layout.meta(frame)))
            gt = planar_to_ray(gt, _camera(K, gt.shape[1], gt.shape[0], layout.meta(frame)))
        images.append({"key": frame, "pred_file": str(pfile), "truth_file": str(gfile),
                       "bins": binned_metrics(depth, gt)})
    return _result(f"exact rendered depth ({'ray distance' if pred_kind == 'ray' else 'planar Z'})",
                   pred_dir, pred_kind, images)


def _check_kind(kind: str) -> None:
    if kind not in PRED_KINDS:
        raise ValueError(f"prediction kind must be one of {', '.join(PRED_KINDS)}, got {kind!r}")


def _camera(K: Intrinsics | None, width: int, height: int, source) -> Intrinsics:
    if K is None:
        raise InputError(source, "a planar prediction needs the camera to become ray distance, and this "
                                 "hold-out file has none: give --intrinsics FILE.json or --pred-kind ray")
    if (K.width, K.height) == (width, height):
        return K
    if abs(K.height * width / K.width - height) > 1.0:
        raise InputError(source, f"the intrinsics are for {K.width}×{K.height}, another aspect ratio than "
                                 f"the {width}×{height} image")
    return K.scaled(width, height)


def _result(against: str, pred_dir: Path, kind: str, images: list[dict]) -> dict:
    return {"against": against, "pred": str(pred_dir), "pred_kind": kind, "bins_m": [b[0] for b in BINS],
            "images": images, "overall": pool([im["bins"] for im in images])}


# ----------------------------------------------------------------------------- report
def table(overall: dict) -> str:
    """Markdown table: one row per bin and overall."""
    lines = ["| distance (m) | points / pixels | AbsRel | RMSE (m) | δ<1.25 | no prediction |",
             "|---|---:|---:|---:|---:|---:|"]
    for name in [b[0] for b in BINS] + ["all"]:
        r = overall[name]
        lines.append(f"| {name} | {r['pixels']} | {r['abs_rel']:.4f} | {r['rmse']:.3f} | {r['delta1']:.4f} | "
                     f"{r['missing']} |")
    return "\n".join(lines)


def chart(overall: dict, width: int = 720, height: int = 320) -> np.ndarray:
    """RGB bar chart: AbsRel and RMSE per distance bin (each panel scaled to its largest bar)."""
    import cv2

    img = np.full((height, width, 3), 255, np.uint8)
    names = [b[0] for b in BINS]
    panel_w = width // 2
    for p, (key, title, fmt) in enumerate((("abs_rel", "AbsRel", "{:.3f}"), ("rmse", "RMSE (m)", "{:.2f}"))):
        x0 = p * panel_w
        vals = [overall[n][key] for n in names]
        top = max([v for v in vals if np.isfinite(v)] + [1e-9])
        cv2.putText(img, f"{title} by distance bin", (x0 + 12, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (20, 20, 20),
                    1, cv2.LINE_AA)
        base, span = height - 40, height - 90
        bw = (panel_w - 40) // len(names)
        for i, (n, v) in enumerate(zip(names, vals)):
            bx = x0 + 20 + i * bw
            if np.isfinite(v):
                bh = int(round(span * v / top))
                cv2.rectangle(img, (bx + 6, base - bh), (bx + bw - 6, base), (70, 110, 200), -1)
                cv2.putText(img, fmt.format(v), (bx + 4, base - bh - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                            (20, 20, 20), 1, cv2.LINE_AA)
            else:
                cv2.putText(img, "n/a", (bx + 10, base - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (120, 120, 120), 1,
                            cv2.LINE_AA)
            cv2.putText(img, n, (bx + 8, base + 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (20, 20, 20), 1, cv2.LINE_AA)
        cv2.line(img, (x0 + 16, base), (x0 + panel_w - 16, base), (60, 60, 60), 1)
    return img


def write_report(result: dict, out) -> dict[str, Path]:
    """``out/score.json``, ``out/score.md`` and ``out/score.png`` (atomic); returns their paths."""
    from fogsim.io.atomic import atomic_write_bytes
    from fogsim.io.documents import write_json
    from fogsim.io.images import write_image

    out = Path(out)
    paths = {"json": out / "score.json", "md": out / "score.md", "png": out / "score.png"}
    md = [f"# Depth vs {result['against']}", "",
          f"Prediction: `{result['pred']}` ({result['pred_kind']}), {len(result['images'])} images.", "",
          table(result["overall"]), ""]
    write_json(paths["json"], result)
    atomic_write_bytes(paths["md"], "\n".join(md).encode())
    write_image(paths["png"], chart(result["overall"]))
    return paths

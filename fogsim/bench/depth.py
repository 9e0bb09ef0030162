"""Scoring depth completion against exact rendered depth, and what it does to the fog.

For one stereo frame of a fogsim dataset (``--stereo``): the SGBM disparity has holes; each
completion method fills them; every result is scored against the exact depth on the hole
pixels, on the SGBM-valid pixels and on all pixels (:mod:`fogsim.depth.metrics`), and the
frame is fogged at each level with the exact and with the completed depth to measure the
error a user would see in the foggy image (PSNR, mean absolute error in 8-bit levels).
Learned completions (ILA) plug in through :func:`fogsim.fog.fill.register_fill`.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from fogsim.camera import depth_to_disparity, disparity_to_depth, planar_to_ray
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.reader import StereoFrame, frame_count, read_stereo_frame, stereo_frames
from fogsim.depth.metrics import depth_metrics, laplacian_variance, reference_accuracy
from fogsim.depth.stereo import wls_disparity
from fogsim.fog.fill import fill_holes
from fogsim.fog.model import Fogger

CLASSICAL = ("sgbm", "inpaint", "ipbasic", "wls")


def complete(frame: StereoFrame, method: str) -> np.ndarray:
    """Planar depth with SGBM's holes handled by ``method`` (``sgbm`` leaves them: 0)."""
    if method == "sgbm":
        return frame.sgbm
    if method == "wls":
        d = wls_disparity(frame.left, frame.right, frame.camera)
        depth = disparity_to_depth(d, frame.camera.baseline, frame.camera.intrinsics.fx)
        return fill_holes(depth, "ipbasic")  # WLS leaves its left band and occlusions undefined
    return fill_holes(frame.sgbm, method, frame.left)  # classical or registered (ILA) fills


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def evaluate_frame(frame: StereoFrame, completions: dict[str, np.ndarray], levels,
                   cap_m: float = 80.0) -> dict:
    """Metrics per method on holes / SGBM-valid / all pixels, and foggy-image error per level."""
    holes = frame.sgbm == 0
    regions = {"holes": holes, "valid": ~holes, "all": None}
    K = frame.camera.intrinsics
    fog_exact = Fogger(frame.left, planar_to_ray(frame.exact, K))
    reference = {lv.key: fog_exact(lv.beta) for lv in levels if lv.beta > 0}
    out = {"frame": frame.name, "hole_fraction": float(holes.mean()), "methods": {}}
    b, fx = frame.camera.baseline, K.fx
    exact_disp, sgbm_disp = depth_to_disparity(frame.exact, b, fx), depth_to_disparity(frame.sgbm, b, fx)
    for method, depth in completions.items():
        rec = {r: depth_metrics(depth, frame.exact, m, cap_m) for r, m in regions.items()}
        disp = depth_to_disparity(depth, b, fx)
        rec["reference"] = {"accuracy_vs_sgbm": reference_accuracy(disp, sgbm_disp),
                            "accuracy_vs_exact": reference_accuracy(disp, exact_disp),
                            "laplacian_variance": laplacian_variance(disp)}
        if not (depth == 0).any():  # only dense depth can be fogged
            fogger = Fogger(frame.left, planar_to_ray(depth, K))
            rec["fog"] = {key: {"psnr": psnr(fogger(lv.beta), reference[key]),
                                "mae": float(np.mean(np.abs(fogger(lv.beta).astype(np.int16)
                                                            - reference[key])))}
                          for lv in levels if lv.beta > 0 for key in [lv.key]}
        out["methods"][method] = rec
    return out


def summarise(frames: list[dict]) -> dict:
    """Mean over frames of every number, per method, keeping the nesting (region → metric,
    fog → level → psnr/mae); non-finite values (no pixels, identical images) are skipped."""
    return _mean_tree([f["methods"] for f in frames])


def _mean_tree(trees: list):
    if isinstance(trees[0], dict):
        return {k: _mean_tree([t[k] for t in trees if k in t]) for k in trees[0]}
    vals = [float(v) for v in trees if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")


# ----------------------------------------------------------------------------- the ILA benchmark
def render_if_needed(out: Path, frames: int, resolution: str, samples: int) -> None:
    """Render the stereo dataset in a process of its own unless it already has ``frames`` frames."""
    if frame_count(out) >= frames:
        return
    code = subprocess.run([sys.executable, "-m", "fogsim", "render", "--preset", "cityscapes-stereo",
                           "--frames", str(frames), "--resolution", resolution, "--samples", str(samples),
                           "--out", str(out)]).returncode
    if code:  # the render said why, in its own one line
        raise SystemExit(code)


def table(summary: dict, region: str) -> str:
    cols = ("abs_rel", "sq_rel", "rmse", "rmse_log", "mae", "delta1", "delta2", "delta3")
    lines = [f"| method | {' | '.join(cols)} |", "|---" * (len(cols) + 1) + "|"]
    for method, rec in summary.items():
        lines.append(f"| {method} | " + " | ".join(f"{rec[region][c]:.3f}" for c in cols) + " |")
    return "\n".join(lines)


def fog_table(summary: dict) -> str:
    dense = {m: r["fog"] for m, r in summary.items() if "fog" in r}
    levels = list(next(iter(dense.values())))
    lines = ["| method | " + " | ".join(f"{k} PSNR / MAE" for k in levels) + " |", "|---" * (len(levels) + 1) + "|"]
    for m, fog in dense.items():
        lines.append(f"| {m} | " + " | ".join(f"{fog[k]['psnr']:.1f} dB / {fog[k]['mae']:.2f}" for k in levels) + " |")
    return "\n".join(lines)


def panel(frame, completions: dict):
    """Two rows: RGB, exact depth and each completion; below, each completion's relative error."""
    import numpy as np

    from fogsim.viz import colorize_depth, strip

    top = strip([frame.left, colorize_depth(frame.exact)] + [colorize_depth(d) for d in completions.values()],
                ["RGB", "exact depth"] + list(completions), width=256)
    errors = []
    for d in completions.values():
        with np.errstate(invalid="ignore", divide="ignore"):
            err = np.where((d > 0) & np.isfinite(frame.exact), np.abs(d - frame.exact) / frame.exact, 0)
        heat = (np.clip(err / 0.3, 0, 1) * 255).astype(np.uint8)
        errors.append(np.stack([heat, heat // 3, 255 - heat], -1))
    blank = np.full_like(frame.left, 255)
    bottom = strip([blank, blank] + errors, ["", "rel. error: blue 0, red 30%+"] + [f"{m} error" for m in completions],
                   width=256)
    return np.vstack([top, np.full((6, top.shape[1], 3), 255, np.uint8), bottom])


def train_ila(cityscapes: Path, out: Path, config) -> list[dict]:
    """Train ILA on the train split (never on the evaluated val frames); returns the round log."""
    from fogsim.depth.ila import load_stereo_set, train_rounds

    data = load_stereo_set(cityscapes, "train", config.size)
    print(f"ILA: {len(data.rgb)} training frames, {config}")
    return train_rounds(data, config, out)


def run_benchmark(out, frames: int = 12, resolution: str = "512x256", samples: int = 6, panels: int = 2,
                  ila_config=None) -> int:
    """Render (or reuse) ``OUT/dataset`` with the ``cityscapes-stereo`` preset, score every completion
    of SGBM's holes on the held-out frames against the exact depth, and write ``OUT/report.{json,md}``
    and ``OUT/panel_<frame>.png``. ``ila_config`` (an ``ILAConfig``) also trains ILA rounds on the
    train split and scores each round."""
    from fogsim.fog.levels import load_preset
    from fogsim.io.atomic import atomic_write_bytes
    from fogsim.io.documents import write_json
    from fogsim.io.images import write_image

    out = Path(out)
    data = out / "dataset"
    render_if_needed(data, frames, resolution, samples)
    layout = DatasetLayout(data)
    held_out = stereo_frames(layout, "val")
    names = held_out or layout.done_frames()
    levels = load_preset("paper")
    methods, ila_log = list(CLASSICAL), []
    if ila_config is not None:
        from fogsim.depth.ila import ila_fill
        from fogsim.fog.fill import register_fill

        ila_log = train_ila(layout.cityscapes_root(), out / "ila", ila_config)
        for entry in ila_log:
            register_fill(f"ila_round{entry['round']}", ila_fill(entry["checkpoint"]))
            methods.append(f"ila_round{entry['round']}")
    results = []
    for i, name in enumerate(names):
        frame = read_stereo_frame(layout, name)
        completions = {m: complete(frame, m) for m in methods}
        results.append(evaluate_frame(frame, completions, levels))
        if i < panels:
            write_image(out / f"panel_{name}.png", panel(frame, completions))
    summary = summarise(results)
    write_json(out / "report.json", {"frames": names, "held_out": bool(held_out), "summary": summary,
                                     "ila": ila_log, "per_frame": results})
    md = [f"# Depth completion vs exact depth ({len(names)} {'held-out ' if held_out else ''}frames, "
          f"{resolution}, ≤ 80 m)", "",
          f"Mean SGBM hole fraction: {sum(r['hole_fraction'] for r in results) / len(results):.3f}", ""]
    for region in ("holes", "valid", "all"):
        md += [f"## {region} pixels", "", table(summary, region), ""]
    md += ["## the reference's own scores", "",
           "| method | accuracy vs SGBM target (%) | accuracy vs exact (%) | Laplacian variance of disparity |",
           "|---|---|---|---|"]
    md += [f"| {m} | {r['reference']['accuracy_vs_sgbm']:.1f} | {r['reference']['accuracy_vs_exact']:.1f} | "
           f"{r['reference']['laplacian_variance']:.3f} |" for m, r in summary.items()] + [""]
    md += ["## foggy image vs fog from exact depth", "", fog_table(summary), ""]
    atomic_write_bytes(out / "report.md", "\n".join(md).encode())
    print("\n".join(md))
    best = min(summary, key=lambda m: np.nan_to_num(summary[m]["holes"]["abs_rel"], nan=np.inf))
    print(f"bench ila: best on the hole pixels of {len(names)} frames: {best} (AbsRel "
          f"{summary[best]['holes']['abs_rel']:.3f}, δ<1.25 {summary[best]['holes']['delta1']:.3f}) → "
          f"{out / 'report.md'}")  # the summary line (--quiet)
    return 0

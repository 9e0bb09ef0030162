#!/usr/bin/env python3
"""Depth completion scored against exact rendered depth, and its effect on the fog.

    python scripts/bench_ila.py --out bench/ila [--frames 12] [--resolution 512x256]

Renders (or reuses) a stereo dataset with the ``cityscapes-stereo`` preset, then for the
held-out (val) frames scores each completion of SGBM's holes — raw SGBM (holes left), OpenCV
inpainting, the IP-Basic-style fill, WLS — against the exact depth on hole pixels, SGBM-valid
pixels and all pixels (≤ 80 m), and fogs every frame at the paper's levels with exact and
completed depth (PSNR, MAE of the foggy image). Writes ``report.json``, ``report.md`` and
``panel_<frame>.png`` (RGB, exact depth, each completion, its error). ILA rows come from
``fogsim.ila`` once trained (issue #4); until then the classical methods are the baselines.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def render_if_needed(out: Path, frames: int, resolution: str, samples: int) -> None:
    if (out / "meta").is_dir() and len(list((out / "meta").glob("*.json"))) >= frames:
        return
    subprocess.run([sys.executable, str(ROOT / "scripts" / "render_batch.py"), "--preset", "cityscapes-stereo",
                    "--frames", str(frames), "--resolution", resolution, "--samples", str(samples),
                    "--out", str(out)], check=True)


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

    from fogsim.preview import colorize_depth, strip

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


def train_ila(cityscapes: Path, out: Path, args) -> list[dict]:
    """Train ILA on the train split (never on the evaluated val frames); returns the round log."""
    from fogsim.ila import ILAConfig, load_stereo_set, train_rounds

    config = ILAConfig(width=args.width, use_sparse=args.sparse, rounds=args.rounds, epochs=args.epochs,
                       loss=args.loss)
    data = load_stereo_set(cityscapes, "train", config.size)
    print(f"ILA: {len(data.rgb)} training frames, {config}")
    return train_rounds(data, config, out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "bench" / "ila"))
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--resolution", default="512x256")
    ap.add_argument("--samples", type=int, default=6)
    ap.add_argument("--panels", type=int, default=2, help="sample frames to draw")
    ap.add_argument("--rounds", type=int, default=2, help="ILA rounds (0: classical baselines only)")
    ap.add_argument("--epochs", type=int, default=40, help="ILA epochs per round")
    ap.add_argument("--width", type=int, default=16, help="U-Net width (16 ≈ 2 M parameters; 64 = reference)")
    ap.add_argument("--sparse", action="store_true", help="feed ILA the sparse disparity too")
    ap.add_argument("--loss", choices=("mse", "log_l1"), default="mse", help="ILA loss (mse = the reference's)")
    args = ap.parse_args()

    from fogsim.dataset_writer import DatasetLayout
    from fogsim.depth_bench import CLASSICAL, complete, evaluate_frame, load_stereo_frame, summarise
    from fogsim.fill import register_fill
    from fogsim.ila import ila_fill
    from fogsim.io import read_json, write_image, write_json, atomic_write_bytes
    from fogsim.levels import load_preset

    out = Path(args.out)
    data = out / "dataset"
    render_if_needed(data, args.frames, args.resolution, args.samples)
    layout = DatasetLayout(data)
    held_out = [f for f in layout.done_frames() if read_json(layout.meta(f))["stereo"]["split"] == "val"]
    frames = held_out or layout.done_frames()
    levels = load_preset("paper")
    methods, ila_log = list(CLASSICAL), []
    if args.rounds:
        ila_log = train_ila(data / "cityscapes", out / "ila", args)
        for entry in ila_log:
            register_fill(f"ila_round{entry['round']}", ila_fill(entry["checkpoint"]))
            methods.append(f"ila_round{entry['round']}")
    results = []
    for i, name in enumerate(frames):
        frame = load_stereo_frame(layout, name)
        completions = {m: complete(frame, m) for m in methods}
        results.append(evaluate_frame(frame, completions, levels))
        if i < args.panels:
            write_image(out / f"panel_{name}.png", panel(frame, completions))
    summary = summarise(results)
    write_json(out / "report.json", {"frames": frames, "held_out": bool(held_out), "summary": summary,
                                     "ila": ila_log, "per_frame": results})
    md = [f"# Depth completion vs exact depth ({len(frames)} {'held-out ' if held_out else ''}frames, "
          f"{args.resolution}, ≤ 80 m)", "",
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
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Render a labeled foggy dataset of procedural street scenes.

    blender -b -P scripts/render_batch.py -- --preset default --frames 200 --out OUT
    python scripts/render_batch.py --preset presets/default.json --frames 200 --out OUT   # bpy module

Each frame is rendered once (RGB, planar depth, object index) and fogged at every level of
the preset. A frame is committed atomically (``meta/<frame>.json`` last); a restarted run
skips committed frames, and ``--shard i/N`` renders frames i, i+N, … for a Slurm array or
a Kubernetes indexed job (run ``--finalize-only`` once after all shards to rebuild COCO,
YAMLs and the contact sheet over every frame).
Exit codes: 0 done, 1 some frames failed, 2 usage or configuration error.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bootstrap() -> None:
    """Make fogsim and its dependencies importable, also inside Debian's Blender binary."""
    sys.path.insert(0, str(ROOT))
    try:
        import numpy  # noqa: F401
        import cv2  # noqa: F401
        return
    except ImportError:
        pass
    candidates = [os.environ.get("FOGSIM_SITE_PACKAGES", "")]
    candidates += [str(p) for p in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages"))]
    for site in filter(None, candidates):
        if Path(site).is_dir():
            sys.path.insert(1, site)
            return
    sys.exit("fogsim: error: this Python lacks numpy/OpenCV; install the project (pip install -e .) "
             "into ./.venv or set FOGSIM_SITE_PACKAGES to a site-packages folder that has them")


def _argv() -> list[str]:
    """Arguments after ``--`` when run by Blender, else the usual ones."""
    if "--" in sys.argv:
        return sys.argv[sys.argv.index("--") + 1:]
    return [] if _inside_blender_binary() else sys.argv[1:]


def parse_args(argv):
    p = argparse.ArgumentParser(prog="render_batch.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", help="preset name (presets/<name>.json) or path; default: default")
    p.add_argument("--out", required=True, help="dataset folder")
    p.add_argument("--frames", type=int, help="number of frames (overrides the preset)")
    p.add_argument("--seed", type=int, help="dataset seed (overrides the preset)")
    p.add_argument("--resolution", help="WxH, e.g. 640x426 (intrinsics scale with it)")
    p.add_argument("--samples", type=int, help="Cycles samples (overrides the quality preset)")
    p.add_argument("--levels", help="fog levels: preset name or comma-separated β (overrides the preset)")
    p.add_argument("--stereo", action="store_true",
                   help="also render the right camera (preset baseline, else the camera's, else 0.209 m) "
                        "and write SGBM disparity in Cityscapes' layout under OUT/cityscapes/")
    p.add_argument("--train-fraction", type=float, help="share of frames in the train split (default: the "
                   "preset's, else 0.8; the paper's 8,100/4,800: 0.628); --finalize-only re-splits without rendering")
    p.add_argument("--shard", help="i/N: render frames i, i+N, … (0-based)")
    p.add_argument("--no-resume", action="store_true", help="re-render committed frames")
    p.add_argument("--gpu", action="store_true", help="render on the GPU when one is available")
    p.add_argument("--finalize-only", action="store_true", help="only rebuild COCO/YAML/manifest/contact sheet")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p.parse_args(argv)


def main() -> int:
    _bootstrap()
    args = parse_args(_argv())
    from fogsim.batch import parse_shard
    from fogsim.errors import FogsimError, InputError
    from fogsim.render_config import load_render_preset

    try:
        config = load_render_preset(args.preset, frames=args.frames, seed=args.seed, train_fraction=args.train_fraction,
                                    resolution=args.resolution, samples=args.samples, levels=args.levels,
                                    stereo=True if args.stereo else None)
        shard = parse_shard(args.shard)
        from blender_addon.pipeline import RUN_FILE, RenderJob

        if args.finalize_only and not (Path(args.out) / RUN_FILE).is_file():
            raise InputError(args.out, f"no {RUN_FILE} here: not a dataset to finalize")
        job = RenderJob(config, args.out, shard, resume=not args.no_resume, gpu=args.gpu)
    except (FogsimError, ValueError) as exc:
        print(f"fogsim: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"fogsim: error: {exc.filename or args.out}: {exc.strerror}", file=sys.stderr)
        return 2
    return run(job, args)


def run(job, args) -> int:
    from tqdm import tqdm

    failed = []
    t0 = time.perf_counter()
    if not args.finalize_only:
        bar = tqdm(total=len(job.todo), unit="frame", desc="render", disable=args.quiet)
        while job.todo:
            index = job.todo[0]
            try:
                meta = job.step()
            except Exception as exc:  # one bad frame must not stop a long run; it is reported
                if index in job.todo:
                    job.todo.remove(index)
                failed.append((index, f"{type(exc).__name__}: {exc}"))
                bar.write(f"error: frame {index}: {type(exc).__name__}: {exc}")
            else:
                if not args.quiet:  # the per-frame timing log (also kept in meta/<frame>.json)
                    stages = ", ".join(f"{k} {v:.2f}s" for k, v in meta["timings_s"].items())
                    bar.write(f"frame {meta['frame']}: {stages}; {sum(r['kept'] for r in meta['objects'])} boxes")
            bar.update(1)
        bar.close()
    sharded = args.shard and not args.shard.endswith("/1")
    if job.layout.done_frames() and (not sharded or args.finalize_only):
        try:
            job.finish()  # shards leave this to one --finalize-only run over all frames
        except (OSError, ValueError) as exc:
            print(f"fogsim: error: writing the dataset files of {args.out} failed: {exc}", file=sys.stderr)
            return 1
    elif args.finalize_only:
        print(f"fogsim: error: {args.out}: no committed frames to finalize", file=sys.stderr)
        return 2
    job.close()
    print(f"rendered {len(job.done)} frames ({job.skipped} already done, {len(failed)} failed) "
          f"in {time.perf_counter() - t0:.1f} s → {args.out}")
    for index, error in failed:
        print(f"  failed: frame {index}: {error}", file=sys.stderr)
    return 1 if failed else 0


def _inside_blender_binary() -> bool:
    return Path(sys.argv[0]).name.startswith("blender")


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    if _inside_blender_binary():
        os._exit(code)  # blender -b -P would otherwise exit 0 whatever the script returned
    sys.exit(code)

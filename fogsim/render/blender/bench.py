"""Renderer speed and memory: seconds per frame by stage, and RSS growth over many frames.

    fogsim bench render [--frames 100] [--preset default] [--baseline-frames 3]

Renders with the bpy module in this process (draft preset, 640×426 by default) and prints
the median seconds per frame for scene description, bpy build, Cycles render, ground truth,
fog and writing; the share of the frame spent outside Cycles; resident memory after frame
10 and after the last frame. The baseline, measured in the same run on the first frames'
scenes, is Blender's factory Cycles light-path and world settings at the same sample count,
so the ratio shows what fogsim's render settings buy. Targets (issue #3): draft ≤ 6 s per
frame; outside Cycles ≤ 15 %; RSS growth frame 10 → 100 ≤ 100 MB.
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import bpy

from fogsim.render.blender import build, cycles
from fogsim.render.frame import describe_frame, scene_meshes
from fogsim.runs import frame_seed

STAGES = ("scene", "bpy_build", "render", "ground_truth", "fog", "write")


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def factory_render_seconds(job, index: int) -> float:
    """Render frame ``index``'s scene with factory light paths and world sampling (baseline)."""
    desc = describe_frame(job.config, index)
    scene = bpy.data.scenes.new("baseline")
    cycles.configure(
        scene,
        {
            "samples": job.config.quality["samples"],
            "denoise": job.config.quality.get("denoise", True),
            "bounces": {"total": 12, "diffuse": 4, "glossy": 4, "transmission": 12, "transparent": 8},
        },
        frame_seed(job.config.seed, index),
    )
    scene.cycles.use_adaptive_sampling = True
    built = build.build(desc, scene, scene_meshes(desc))
    scene.world.cycles.sampling_method = "AUTOMATIC"
    t0 = time.perf_counter()
    cycles.render(scene)
    seconds = time.perf_counter() - t0
    build.clear(built)
    bpy.data.scenes.remove(scene)
    return seconds


def run(args) -> int:
    """``args``: frames, preset, resolution, baseline_frames, out (see ``fogsim bench render --help``)."""
    from fogsim.render.blender.job import RenderJob
    from fogsim.render.preset import load_render_preset

    out = args.out or tempfile.mkdtemp(prefix="fogsim_bench_")
    config = load_render_preset(args.preset, frames=args.frames, resolution=args.resolution)
    job = RenderJob(config, out, resume=False)
    times, rss = [], []
    for i in range(args.frames):
        meta = job.step()
        times.append(meta["timings_s"])
        rss.append(rss_mb())
        print(f"frame {i:4d}: {sum(meta['timings_s'].values()):5.2f} s  rss {rss[-1]:7.1f} MB", flush=True)
    base = [factory_render_seconds(job, i) for i in range(min(args.baseline_frames, args.frames))]
    job.close()

    med = {s: statistics.median(t[s] for t in times) for s in STAGES}
    total = statistics.median(sum(t[s] for s in STAGES) for t in times)
    ours = statistics.median(t["render"] for t in times[:len(base)])
    print(f"\nrender benchmark: preset {config.name}, {args.resolution}, quality {config.quality.get('name')}, "
          f"{config.quality['samples']} samples, {args.frames} frames (medians)")
    for s in STAGES:
        print(f"  {s:<14}{med[s]:8.3f} s  {100 * med[s] / total:5.1f} %")
    outside = total - med["render"]
    print(f"  {'frame':<14}{total:8.3f} s")
    print(f"  outside Cycles {outside:.3f} s = {100 * outside / total:.1f} % of the frame")
    print(f"  Cycles render vs factory light paths + world map (same scenes, {len(base)} frames): "
          f"{ours:.2f} s vs {statistics.median(base):.2f} s = {statistics.median(base) / ours:.2f}× faster")
    at10 = rss[min(9, len(rss) - 1)]
    print(f"  RSS after frame 10: {at10:.0f} MB, after frame {len(rss)}: {rss[-1]:.0f} MB, "
          f"growth {rss[-1] - at10:+.0f} MB")
    checks = [("draft ≤ 6 s per frame", total <= 6.0), ("outside Cycles ≤ 15 %", outside / total <= 0.15),
              ("RSS growth 10 → last ≤ 100 MB", rss[-1] - at10 <= 100)]
    for text, ok in checks:
        print(f"  [{'ok' if ok else 'MISSED'}] {text}")
    return 0

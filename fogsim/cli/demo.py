"""``fogsim demo`` and ``fogsim levels``: the built-in procedural street images fogged, and the
fog presets with β (1/m) and visibility (m)."""
from __future__ import annotations

from pathlib import Path

from fogsim.errors import EXIT_FAILED, EXIT_OK

#: the demo writes its procedural input images first: a handful, not a dataset
MAX_DEMO_FRAMES = 1000


def add_parsers(sub) -> None:
    demo = sub.add_parser("demo", help="fog the built-in procedural street images (no dataset needed)")
    demo.add_argument("--out", default="demo_out", help="output folder (default demo_out)")
    demo.add_argument("--frames", type=int, default=3)
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--levels", default="paper")
    demo.add_argument("--quiet", action="store_true", help="print only errors and the summary line")

    demo.set_defaults(run=cmd_demo)

    sub.add_parser("levels", help="list the fog presets with β and visibility").set_defaults(run=cmd_levels)


def cmd_demo(args) -> int:
    import numpy as np

    from fogsim.deps import package_versions
    from fogsim.fog.batch import FogJob, check_run_file, run
    from fogsim.fog.levels import parse_levels
    from fogsim.fog.synthetic import demo_scene
    from fogsim.io.depth_files import write_depth
    from fogsim.io.images import read_image, write_image
    from fogsim.readers.base import DepthSpec
    from fogsim.readers.folder import folder_samples
    from fogsim.runs import check_output
    from fogsim.viz import colorize_depth, strip

    check_output(args.out, {})
    out = Path(args.out)
    from fogsim.schema.base import check_flag, int_in

    check_flag("--frames", args.frames, int_in(1, MAX_DEMO_FRAMES))
    levels = tuple(parse_levels(args.levels))
    job = FogJob(levels, str(out / "fog"), seed=args.seed, inputs={"demo_seed": args.seed, "frames": args.frames})
    check_run_file(job, package_versions())  # before writing inputs: never overwrite another run's
    rng = np.random.default_rng(args.seed)
    K = None
    for i in range(args.frames):
        rgb, depth, K = demo_scene(rng)
        write_image(out / "input" / "images" / f"street_{i:03d}.png", rgb)
        write_depth(out / "input" / "depth" / f"street_{i:03d}.exr", depth)
    samples = folder_samples(out / "input" / "images", out / "input" / "depth", DepthSpec(""), "", K)
    summary = run(samples, job, progress=not args.quiet, environment=package_versions())
    print(summary.line(job))
    first = samples[0]
    tiles = [colorize_depth(depth_of(out, first.key))] + [read_image(job.paths(first, lv)[0]) for lv in levels]
    captions = ["depth (m)"] + [lv.name if lv.beta == 0 else f"{lv.name}, b={lv.beta:g}" for lv in levels]
    write_image(out / "fog_strip.png", strip(tiles, captions, width=320))
    if not args.quiet:
        print(f"fog strip: {out / 'fog_strip.png'}")
    return EXIT_FAILED if summary.failed else EXIT_OK


def depth_of(out: Path, key: str):
    from fogsim.io.depth_files import read_depth_file

    return read_depth_file(out / "input" / "depth" / f"{key}.exr")


def cmd_levels(args) -> int:
    from fogsim.fog.levels import load_preset, preset_names

    for name in preset_names():
        print(name)
        for lv in load_preset(name):
            vis = lv.to_dict()["visibility_m"]
            shown = "∞" if vis is None else f"{vis:.0f} m"
            print(f"  {lv.key:<12} β = {lv.beta:<6g} 1/m  visibility {shown:>6}  {lv.name}")
    return EXIT_OK

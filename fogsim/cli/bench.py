"""``fogsim bench fog | augment | render | render-fog | fog-physics | ila | lidar | lidar-fog | radar``: the speed and
accuracy benchmarks.

Each prints its figures beside a baseline measured in the same run (ratios of medians:
these machines are noisy); none of them is a test, and CI times nothing.
"""
from __future__ import annotations

from fogsim.io.pixel_bound import MAX_PIXELS, pixel_limit_problem
from fogsim.schema.vocabulary import FOG_MEDIA


def add_parsers(sub) -> None:
    bench = sub.add_parser("bench", help="benchmarks: fog speed, render speed, depth completion (ILA), "
                           "Koschmieder against path-traced fog")
    bsub = bench.add_subparsers(dest="bench_command", required=True, metavar="BENCH")

    fog = bsub.add_parser("fog", help="fog engine speed, 1920×1280, one core, against Eq. 2 in float64 "
                          "and the reference's per-pixel loop")
    fog.add_argument("--repeat", type=int, default=15, help="interleaved repeats (medians)")
    fog.add_argument("--size", default="1920x1280", help="frame WIDTHxHEIGHT (the targets are for 1920x1280)")
    fog.add_argument("--max-pixels", type=int, default=MAX_PIXELS,
                     help=f"refuse a --size of more pixels than this (default {MAX_PIXELS:,}, as fog and render)")
    _quiet_option(fog)
    fog.set_defaults(run=lambda args: _fog(args))

    aug = bsub.add_parser("augment", help="fog as augmentation: images/s (NumPy, albumentations, torch batch) at "
                          "640×640 and 1920×1280 on one core, against albumentations RandomFog, and the cost "
                          "added to an Ultralytics training sample")
    aug.add_argument("--repeat", type=int, default=5, help="interleaved repeats (medians)")
    _quiet_option(aug)
    aug.set_defaults(run=lambda args: _augment(args))

    render = bsub.add_parser("render", help="seconds per frame by stage and RSS over many frames (needs bpy), "
                             "against factory Cycles settings")
    render.add_argument("--frames", type=int, default=100)
    render.add_argument("--preset", default="default")
    render.add_argument("--resolution", default="640x426")
    render.add_argument("--baseline-frames", type=int, default=3)
    render.add_argument("--out", help="dataset folder (default: a temporary one)")
    render.add_argument("--no-skies", dest="skies", action="store_false",
                        help="skip timing the HDRI and overcast skies against the procedural one")
    render.add_argument("--lidar", metavar="SENSOR",
                        help="also sweep this LiDAR (e.g. hdl64e) in every frame: its stage beside Cycles', and the "
                             "ray casters (Embree vs Blender's BVHTree in a Python loop) on one core")
    render.add_argument("--lidar-steps", type=int, default=2048,
                        help="azimuth steps per sweep of --lidar (default 2048: 64 beams × 2048 = 131 k rays)")
    render.add_argument("--radar", metavar="SENSOR",
                        help="also sweep this radar (e.g. ars408-lr) in every frame: its stage (rays, clusters, "
                             "fogged levels) beside Cycles' render, and its detections per frame")
    _quiet_option(render)
    render.set_defaults(run=lambda args: _render(args))

    rfog = bsub.add_parser("render-fog", help="a volumetric-fog frame (full + OIDN, hybrid, cheap hybrid) against a "
                           "Koschmieder frame of the same scenes, ratio in the same run, and the cheap "
                           "variant's error against the full-resolution hybrid (needs bpy)")
    rfog.add_argument("--preset", default="default")
    rfog.add_argument("--resolution", default="160x107", help="small by default to keep the run short; "
                      "640x426 is the default preset's own")
    rfog.add_argument("--frames", type=int, default=1)
    rfog.add_argument("--repeat", type=int, default=1, help="interleaved repeats (medians)")
    rfog.add_argument("--samples", type=int, help="clear-render samples (default: the preset's quality)")
    rfog.add_argument("--fog-samples", type=int, help="fog-render samples (default: the clear render's)")
    rfog.add_argument("--levels", help="fog levels (default: the preset's)")
    rfog.add_argument("--fast-scale", type=float, default=0.5,
                      help="resolution_scale of the cheap hybrid variant (fog renders at this fraction of "
                           "width and height, rebuilt from the clear render)")
    rfog.add_argument("--out", help="folder of the five datasets (default: a temporary one)")
    _quiet_option(rfog)
    rfog.set_defaults(run=lambda args: _render_fog(args))

    ila = bsub.add_parser("ila", help="depth completion (classical fills, ILA) scored against exact rendered "
                          "depth; renders a stereo dataset first (needs bpy; torch for ILA)")
    ila.add_argument("--out", default="bench/ila", help="benchmark folder (dataset, ILA checkpoints, report)")
    ila.add_argument("--frames", type=int, default=12)
    ila.add_argument("--resolution", default="512x256")
    ila.add_argument("--samples", type=int, default=6)
    ila.add_argument("--panels", type=int, default=2, help="sample frames to draw")
    from fogsim.cli.ila import add_training_options

    add_training_options(ila)  # --rounds 0: classical baselines only
    _quiet_option(ila)
    ila.set_defaults(run=lambda args: _ila(args))

    lidar = bsub.add_parser("lidar", help="LiDAR completion time per 1920×1280 FRONT image (synthetic scan with "
                            "the real density), one core, against the fog step of the same image")
    lidar.add_argument("--repeat", type=int, default=5, help="interleaved repeats (medians)")
    lidar.add_argument("--waymo", help="a Waymo .tfrecord to also time decoding + projection of its first frame")
    _quiet_option(lidar)
    lidar.set_defaults(run=lambda args: _lidar(args))

    lfog = bsub.add_parser("lidar-fog", help="LiDAR fog speed: a 120 k-point HDL-64-like scan at the paper's four "
                           "levels, one core, against the per-point loop of the same model, with the published "
                           "models (hahner2021, stf2020) timed beside the default")
    lfog.add_argument("--repeat", type=int, default=5, help="interleaved repeats (medians)")
    lfog.add_argument("--loop-points", type=int, default=4000,
                      help="points of the subsample the per-point loop runs on (scaled to the whole scan)")
    lfog.add_argument("--bev", metavar="FILE.png", help="also write bird's-eye views of the scan at each level")
    _quiet_option(lfog)
    lfog.set_defaults(run=lambda args: _lidar_fog(args))

    rad = bsub.add_parser("radar", help="radar fog speed: detections per second through the ITU-R P.840 fog model "
                          "at the paper's four levels, one core, against per-detection loops of the same model")
    rad.add_argument("--repeat", type=int, default=5, help="interleaved repeats (medians)")
    rad.add_argument("--detections", type=int, default=100_000, help="detections in the one big sweep")
    rad.add_argument("--sweeps", type=int, default=200, help="real-sized sweeps (≈125 detections each)")
    rad.add_argument("--loop-detections", type=int, default=2000,
                     help="detections the per-detection loops run on (scaled to the big sweep)")
    _quiet_option(rad)
    rad.set_defaults(run=lambda args: _radar(args))

    fp = bsub.add_parser("fog-physics", help="Koschmieder against Cycles path-traced fog on the same frames: "
                         "per-pixel error per distance bin, per-object contrast (renders with fogsim render "
                         "--fog volumetric, twice, and once clear)")
    fp.add_argument("--out", default="bench/fog-physics", help="benchmark folder (three datasets and report/)")
    fp.add_argument("--frames", type=int, default=1)
    fp.add_argument("--preset", default="default")
    fp.add_argument("--resolution", default="160x107")
    fp.add_argument("--samples", type=int, default=16, help="Cycles samples per render")
    fp.add_argument("--seed", type=int, default=3, help="dataset seed (the scenes)")
    fp.add_argument("--levels", help="fog levels (preset name or comma-separated β; must include 0)")
    fp.add_argument("--medium", choices=FOG_MEDIA, default="full",
                    help="volumetric medium (fogsim render --fog-medium); ea = camera-only emission-absorption, "
                    "the zero-error control")
    fp.add_argument("--denoise", action="store_true", help="denoise the fog renders (off: measurements want "
                    "independent noise in the two seeds)")
    fp.add_argument("--gpu", action="store_true", help="render on the GPU when one is available")
    fp.add_argument("--analyse-only", action="store_true", help="only analyse the datasets already under OUT")
    fp.add_argument("--pool", action="append", metavar="DIR", help="another fog-physics folder whose frames are "
                    "analysed with OUT's, pooled into OUT/report (repeatable; e.g. held-out styles and seeds)")
    fp.add_argument("--scatter-params", metavar="FILE", help="the scatter model's parameter file to compare "
                    "(written by fogsim fit-fog; default: the shipped one) — a new fit, before it ships")
    _quiet_option(fp)
    fp.set_defaults(run=lambda args: _fog_physics(args))

    for p in bsub.choices.values():  # --quiet: only the summary line, which every bench prints last
        p.set_defaults(run=_summary_only(p.get_default("run")))


def _quiet_option(p) -> None:
    p.add_argument("--quiet", action="store_true", help="print only errors and the summary line (the last line "
                   "of the report): no table, no progress, no Blender output")


def _summary_only(run):
    def quietly(args) -> int:
        from fogsim.console import summary_only

        with summary_only(args.quiet):
            return run(args)
    return quietly


def _positive(**values) -> None:
    bad = [f"--{k.replace('_', '-')}" for k, v in values.items() if not v > 0]
    if bad:
        raise ValueError(f"{', '.join(bad)} must be positive")


def _fog(args) -> int:
    from fogsim.bench.fog import run
    from fogsim.render.preset import parse_resolution

    _positive(repeat=args.repeat, max_pixels=args.max_pixels)
    try:
        size = parse_resolution(args.size)
    except ValueError as e:
        raise ValueError(str(e).replace("--resolution", "--size")) from None
    too_big = pixel_limit_problem(*size, args.max_pixels, "time")
    if too_big:  # the bench holds several float64 copies of the frame
        raise ValueError(f"--size {too_big}")
    return run(args.repeat, size)


def _augment(args) -> int:
    from fogsim.bench.augment import run

    _positive(repeat=args.repeat)
    return run(args.repeat)


def _render(args) -> int:
    _positive(frames=args.frames, baseline_frames=args.baseline_frames)
    from fogsim.cli.render import require_bpy

    require_bpy()
    from fogsim.render.blender.bench import run

    return run(args)


def _render_fog(args) -> int:
    _positive(frames=args.frames, repeat=args.repeat)
    if args.samples is not None or args.fog_samples is not None:
        _positive(**{k: v for k, v in (("samples", args.samples), ("fog_samples", args.fog_samples)) if v is not None})
    from fogsim.cli.render import require_bpy

    require_bpy()
    from fogsim.render.blender.bench import run_fog

    return run_fog(args)

def _fog_physics(args) -> int:
    from fogsim.bench.fog_physics import run

    _positive(frames=args.frames, samples=args.samples)
    if not args.analyse_only:
        _check_fog_physics_flags(args)
    return run(args)


def _check_fog_physics_flags(args) -> None:
    """Every flag the three renders take, checked before the first one starts (or anything is
    written): the preset, --resolution, --levels (which must hold β = 0, the reference) …"""
    from fogsim.errors import InputError
    from fogsim.fog.levels import parse_levels
    from fogsim.render.preset import load_render_preset

    if args.levels:
        try:
            parse_levels(args.levels)
        except InputError as exc:  # an unknown fog preset name: say which flag gave it
            raise ValueError(f"--levels {args.levels}: {exc}") from None
    config = load_render_preset(args.preset, frames=args.frames, seed=args.seed, resolution=args.resolution,
                                samples=args.samples, levels=args.levels, fog="volumetric", fog_medium=args.medium)
    if not any(lv.beta == 0 for lv in config.levels):
        given = f"--levels {args.levels}" if args.levels else f"the levels of preset {args.preset}"
        raise ValueError(f"{given} must include 0 (β = 0, the clear reference both fog renders are compared with), "
                         f"got {', '.join(f'{lv.beta:g}' for lv in config.levels)}")


def _ila(args) -> int:
    from fogsim.bench.depth import run_benchmark

    _positive(frames=args.frames, samples=args.samples, epochs=args.epochs)
    from fogsim.render.preset import load_render_preset

    # the render's flags, checked before it starts (its resolution becomes Cycles' buffers)
    load_render_preset("cityscapes-stereo", frames=args.frames, resolution=args.resolution, samples=args.samples)
    config = None
    if args.rounds:
        from fogsim.cli.ila import training_config

        config = training_config(args)
    return run_benchmark(args.out, args.frames, args.resolution, args.samples, args.panels, config)


def _lidar(args) -> int:
    from fogsim.bench.lidar import run

    _positive(repeat=args.repeat)
    return run(args.repeat, args.waymo)


def _lidar_fog(args) -> int:
    from fogsim.bench.lidar_fog import run

    _positive(repeat=args.repeat, loop_points=args.loop_points)
    return run(args.repeat, args.loop_points, bev=args.bev)


def _radar(args) -> int:
    from fogsim.bench.radar import run

    _positive(repeat=args.repeat, detections=args.detections, sweeps=args.sweeps, loop_detections=args.loop_detections)
    return run(args.repeat, args.detections, args.sweeps, args.loop_detections)

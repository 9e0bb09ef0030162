"""``fogsim depth score``: score any depth folder against held-out LiDAR points or exact rendered depth."""
from __future__ import annotations

from fogsim.errors import EXIT_OK


def add_parsers(sub) -> None:
    depth = sub.add_parser("depth", help="depth tools: score predictions against LiDAR or exact depth")
    dsub = depth.add_subparsers(dest="depth_command", required=True, metavar="DEPTH")
    sc = dsub.add_parser("score",
                         help="AbsRel, RMSE, δ<1.25 per distance bin (0-10, 10-20, 20-40, 40-80, 80+ m) of a "
                              "depth folder against held-out LiDAR points or a rendered dataset's exact depth")
    sc.add_argument("--pred", required=True, help="folder of depth maps named by key: <key><suffix>.exr|.npy|.png "
                                                  "(e.g. `fogsim ila predict` output, or OUT/lidar_depth)")
    truth = sc.add_argument_group("ground truth (one of)").add_mutually_exclusive_group(required=True)
    truth.add_argument("--holdout", help="a `fogsim fog --depth-from lidar --lidar-holdout F` output folder "
                                         "(its lidar_holdout/<key>.npz), or that lidar_holdout folder")
    truth.add_argument("--dataset", help="a rendered fogsim dataset (depth/<frame>.exr, exact planar Z)")
    sc.add_argument("--pred-kind", choices=("planar", "ray"), default="planar",
                    help="planar Z (ILA predictions) or ray distance (OUT/lidar_depth)")
    sc.add_argument("--pred-suffix", default="", help="prediction name = key + this + extension")
    sc.add_argument("--depth-scale", type=float, help="metres per unit of 16-bit PNG predictions")
    sc.add_argument("--intrinsics", help="JSON with fx, fy, cx, cy, width, height for planar predictions "
                                         "against hold-out files without a camera")
    sc.add_argument("--out", required=True, help="report folder: score.json, score.md, score.png")
    sc.add_argument("--quiet", action="store_true", help="print only errors and the summary line (no table)")
    sc.set_defaults(run=cmd_score)


def cmd_score(args) -> int:
    """Everything is read and scored first; the report is written only when all of it worked."""
    from pathlib import Path

    from fogsim.camera import Intrinsics
    from fogsim.depth.score import score_dataset, score_holdout, table, write_report
    from fogsim.errors import InputError
    from fogsim.io.documents import read_json
    from fogsim.runs import check_output

    # the report may go inside the fog output or dataset it scores (e.g. OUT/score), not over it
    target = check_output(args.out, {"--pred": args.pred, "--intrinsics": args.intrinsics})
    for flag, given in (("--holdout", args.holdout), ("--dataset", args.dataset)):
        src = Path(given).resolve() if given else None
        if src is not None and (src == target or target in src.parents):
            raise InputError(args.out, f"--out is or contains {flag} {given}: choose a report folder "
                                       "outside it (a subfolder of it is fine)")
    if args.depth_scale is not None and not args.depth_scale > 0:
        raise ValueError(f"--depth-scale must be > 0 metres per unit, got {args.depth_scale}")
    if args.holdout:
        K = Intrinsics.from_dict(read_json(args.intrinsics), args.intrinsics) if args.intrinsics else None
        result = score_holdout(args.pred, args.holdout, args.pred_kind, args.pred_suffix, args.depth_scale, K)
    else:
        if args.intrinsics:
            raise ValueError("--intrinsics goes with --holdout: a rendered dataset records each frame's camera")
        result = score_dataset(args.pred, args.dataset, args.pred_kind, args.pred_suffix, args.depth_scale)
    paths = write_report(result, args.out)
    if args.quiet:
        r = result["overall"]["all"]
        print(f"depth {args.pred} vs {result['against']}, {len(result['images'])} images: AbsRel {r['abs_rel']:.4f}, "
              f"RMSE {r['rmse']:.3f} m, δ<1.25 {r['delta1']:.4f} → {paths['md']}")
        return EXIT_OK
    print(f"depth {args.pred} ({args.pred_kind}) vs {result['against']}, {len(result['images'])} images")
    print(table(result["overall"]))
    print(f"report: {paths['md']}, {paths['json']}, {paths['png']}")
    return EXIT_OK

"""``fogsim study``: the per-density detection study in one command: render (or reuse) a fogsim dataset, train one
YOLO per fog level plus one on every level mixed, predict on every level's validation images,
and write the cross-density report (Recall / mAP@50, oracle and routed rows, fog-level
estimators) under OUT/report.

Small study on a 2-core CPU (≈ 80 min):
    fogsim study --out study --render 300
Paper scale on a GPU (8,100 train / 4,800 val frames, 640 px, 100 epochs, YOLOv12m):
    fogsim render --out ds --frames 12900 --train-fraction 0.628 --shard i/N --gpu
    fogsim render --out ds --frames 12900 --train-fraction 0.628 --finalize-only
    fogsim study --out study --dataset ds --model yolo12m.yaml \\
        --imgsz 640 --epochs 100 --batch 16 --nbs 64 --shard i/6   (array job of 6: one model each)
    fogsim study --out study --dataset ds … --report-only
On a fogged real dataset (fogsim fog --cityscapes/--waymo writes one), with a sim-to-real row:
    fogsim study --out study --dataset cityscapes_fog --sim-dataset ds    (class map: fogsim-to-cityscapes)
Post-process fog vs path-traced fog (three renders of the same scenes; docs/study.md):
    fogsim study --out study --dataset ds --scatter-dataset ds_scatter --eval-dataset ds_volumetric

LiDAR and LiDAR + radar (bird's-eye-view rasters, oriented-box YOLO per level + mixed; docs/study.md):
    fogsim study --sensor lidar+radar --render 12 --resolution 320x213 --epochs 1 --mixed-epochs 1 \\
        --imgsz 160 --out S                               (renders with --lidar hdl64e --radar ars408-lr)
    fogsim fog --kitti ROOT --lidar --out KFOG && fogsim study --sensor lidar --dataset KFOG --out S
    fogsim study --sensor lidar --dataset ds --fog-models soft-target,attenuation --out S
    fogsim study --sensor lidar+radar --dataset ds --model yolo11m-obb.yaml --imgsz 640 --epochs 100 \\
        --out S --dry-run                                 (the plan, checked, nothing trained)

Resumable: finished models and prediction files are skipped, an interrupted training resumes
from its last.pt. Needs the 'detect' extra. Exit 0 done, 1 failed, 2 bad input.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from fogsim.errors import EXIT_OK
from fogsim.fog.visibility import INVISIBLE_RULE


def add_parsers(sub) -> None:
    from fogsim.detection.yolo import TrainConfig

    d = TrainConfig()
    p = sub.add_parser("study", help="train one detector per fog level (+ mixed) and write the cross-density "
                       "report (needs the 'detect' extra)", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="study folder (resumed when it exists)")
    p.add_argument("--sensor", choices=SENSORS, default="camera",
                   help="camera (2D boxes on the images), lidar (BEV rasters of each level's scans) or lidar+radar "
                        "(lidar's models plus fused ones with the radar's RCS and radial velocity); the BEV study "
                        "writes under OUT/bev and sets a camera study of the same OUT beside its tables")
    src = p.add_argument_group("dataset")
    src.add_argument("--dataset", help="an existing fogsim dataset, rendered or fogged real data (default: "
                                       "OUT/dataset); its classes come from its dataset.json")
    src.add_argument("--sim-dataset", metavar="RENDERED",
                     help="a rendered dataset: train its models too (OUT/sim_to_real/study) and add rows 'sim <model>' "
                          "evaluating them on --dataset's levels, through the class map")
    src.add_argument("--eval-dataset", metavar="VOLUMETRIC",
                     help="a render of --dataset's scenes with path-traced fog (fogsim render --fog volumetric, same "
                          "preset, seed, frames): every model is evaluated on it too, and the report gains rows "
                          "'trained on Koschmieder fog' (mixed) and 'trained on scatter fog'; needs --scatter-dataset")
    src.add_argument("--scatter-dataset", metavar="SCATTER",
                     help="with --eval-dataset: a render of the same scenes with fog kind scatter (fogsim render "
                          "--fog scatter): a model 'scatter' is trained on every level of it, as mixed is")
    src.add_argument("--render", type=int, metavar="FRAMES",
                     help="render (or complete) this many frames into the dataset first")
    src.add_argument("--preset", default="default", help="render preset (with --render)")
    src.add_argument("--resolution", default="320x213", help="render resolution WxH (with --render)")
    src.add_argument("--samples", type=int, help="Cycles samples (with --render; default: the preset's)")
    src.add_argument("--render-seed", type=int, help="dataset seed (with --render)")
    src.add_argument("--lidar-sensor", default="hdl64e", help="the LiDAR a --render with --sensor lidar or "
                     "lidar+radar sweeps: a bundled sensor or a sensor .json (default hdl64e)")
    src.add_argument("--radar-sensor", default="ars408-lr", help="the radar a --render with --sensor lidar+radar "
                     "sweeps (default ars408-lr)")
    bev = p.add_argument_group("LiDAR and radar (--sensor lidar, lidar+radar)")
    bev.add_argument("--bev-grid", default="0:50,-25:25", metavar="X0:X1,Y0:Y1",
                     help="the BEV grid in the LiDAR frame, metres (x forward, y left; default 0:50,-25:25); its "
                          "cell is the longer side / --imgsz, so the raster is the network's input")
    bev.add_argument("--fog-models", metavar="MODEL,MODEL,…",
                     help="also fog the clear scans again with each LiDAR fog model (the LiDAR fog spec's model, as "
                          "fog --lidar-model: soft-target, attenuation, …), train a mixed model on each and evaluate "
                          "every one on every model's levels")
    bev.add_argument("--difficulty", choices=("auto", "all", "easy", "moderate", "hard"), default="auto",
                     help="KITTI's difficulty counted in the scores (objects above it are ignored; auto: moderate "
                          "on real data, all on renders, whose small images fail KITTI's pixel heights)")
    bev.add_argument("--prepare-only", action="store_true", help="only write the BEV rasters, labels and ground "
                     "truth (run once before an array job of --shard tasks)")
    bev.add_argument("--dry-run", action="store_true", help="check the dataset and the model and print the plan "
                     "(models, epochs, rasters per shard); train nothing")
    tr = p.add_argument_group("training (Ultralytics; --report-only reads them from OUT/study.json)")
    tr.add_argument("--model", help=f"model YAML, trained from scratch (default {d.model}; yolo12m.yaml is the "
                    "paper's; the BEV study needs an oriented-box one, default yolov8n-obb.yaml), or an existing "
                    "weights file (a pickle: Ultralytics loads it, so only weights you trust)")
    tr.add_argument("--epochs", type=int, default=d.epochs)
    tr.add_argument("--mixed-epochs", type=int, help="epochs of the mixed model (default: --epochs, i.e. "
                    "the compute of all level models together)")
    tr.add_argument("--imgsz", type=int, default=d.imgsz)
    tr.add_argument("--batch", type=int, default=d.batch)
    tr.add_argument("--nbs", type=int, help="nominal batch size: gradients accumulate to it (default: --batch, "
                    "no accumulation — a small dataset needs the optimizer steps; Ultralytics' default is 64)")
    tr.add_argument("--device", default=d.device, help="auto (CUDA GPU 0 when present, else cpu), cpu, 0, 0,1 …")
    tr.add_argument("--workers", type=int, default=d.workers, help="data-loader workers")
    tr.add_argument("--seed", type=int, default=d.seed)
    tr.add_argument("--patience", type=int, default=d.patience, help="early-stopping patience (epochs)")
    tr.add_argument("--augment", metavar="continuous[:LOW-HIGH]",
                    help="also train a model 'augmented' on the clear images with fog drawn per sample from the "
                         "dataset's depth (β uniform in LOW–HIGH 1/m, default 0–0.12; ':visibility' draws uniformly "
                         "in visibility), the mixed model's epochs and images per epoch; needs rendered depth")
    tr.add_argument("--cache", action="store_true", help="keep decoded images in RAM (faster on large "
                    "images; Ultralytics warns it may make training non-deterministic)")
    tr.add_argument("--no-plots", action="store_true", help="skip Ultralytics' training plots")
    ev = p.add_argument_group("evaluation")
    ev.add_argument("--max-distance", type=float, default=100.0, help="objects farther (m) are ignored")
    ev.add_argument("--visible-only", action="store_true", help="also score mAP@50 and the distance bins "
                    f"with invisible objects ({INVISIBLE_RULE.replace('%', '%%')}) ignored; recall is reported both "
                    "ways always")
    ev.add_argument("--unknown-distance", choices=("ignore", "count"), default="ignore",
                    help="objects of unknown distance (no laser label, no valid disparity): ignore regions, or "
                         "ground truth counted by the distance cut; the report gives both counts")
    ev.add_argument("--class-map", metavar="NAME|JSON",
                    help="evaluate through a class map: fogsim-to-waymo, fogsim-to-cityscapes, a JSON file or "
                         "JSON text {\"map\": {src: dst or null}, \"classes\": [...]}; with --sim-dataset it maps the "
                         "rendered classes to the real ones (default: the built-in whose class lists match)")
    ev.add_argument("--shard", help="i/N: train and predict models i, i+N, … only (array jobs)")
    what = ev.add_mutually_exclusive_group()
    what.add_argument("--report-only", action="store_true", help="only evaluate and write OUT/report")
    what.add_argument("--no-report", action="store_true", help="train and predict only")
    ev.add_argument("--quiet", action="store_true", help="print only errors and the summary line (no progress bar, "
                    "no Ultralytics log, no table: it is in OUT/report)")
    p.set_defaults(run=cmd_study)



#: bounds on the training flags that become allocations (Ultralytics holds batch × 3 × imgsz² floats)
MAX_IMGSZ, MAX_BATCH = 8192, 4096
SENSORS = ("camera", "lidar", "lidar+radar")
#: flags of one kind of study only: (dest, flag, default)
CAMERA_ONLY = (("sim_dataset", "--sim-dataset", None), ("eval_dataset", "--eval-dataset", None),
               ("scatter_dataset", "--scatter-dataset", None), ("augment", "--augment", None),
               ("class_map", "--class-map", None), ("visible_only", "--visible-only", False),
               ("unknown_distance", "--unknown-distance", "ignore"), ("max_distance", "--max-distance", 100.0))
BEV_ONLY = (("fog_models", "--fog-models", None), ("bev_grid", "--bev-grid", "0:50,-25:25"),
            ("difficulty", "--difficulty", "auto"), ("prepare_only", "--prepare-only", False),
            ("dry_run", "--dry-run", False), ("lidar_sensor", "--lidar-sensor", "hdl64e"),
            ("radar_sensor", "--radar-sensor", "ars408-lr"))


def check_sensor_flags(args) -> None:
    """A flag of the other kind of study is a usage error, not silently unused."""
    other = BEV_ONLY if args.sensor == "camera" else CAMERA_ONLY
    given = [flag for dest, flag, default in other if getattr(args, dest) != default]
    if given:
        kind = "--sensor lidar or lidar+radar" if args.sensor == "camera" else "the camera study (--sensor camera)"
        raise ValueError(f"{', '.join(given)}: only for {kind}")


def check_args(args) -> None:
    """Usage errors (ValueError) before anything runs."""
    positive = {"--epochs": args.epochs, "--mixed-epochs": args.mixed_epochs, "--imgsz": args.imgsz,
                "--batch": args.batch, "--nbs": args.nbs, "--max-distance": args.max_distance,
                "--render": args.render}
    bad = [name for name, v in positive.items() if v is not None and not v > 0]
    if bad:
        raise ValueError(f"{', '.join(bad)} must be positive")
    from fogsim.schema.base import check_flag, int_in
    from fogsim.schema.presets import MAX_FRAMES

    # what becomes memory: a batch of batch × 3 × imgsz² floats; --render: the frame list
    check_flag("--imgsz", args.imgsz, int_in(1, MAX_IMGSZ))
    check_flag("--batch", args.batch, int_in(1, MAX_BATCH))
    if args.render is not None:
        check_flag("--render", args.render, int_in(1, MAX_FRAMES))
    if args.render and args.sim_dataset:
        raise ValueError("--render renders the study's own dataset: render the --sim-dataset first "
                         "(fogsim render), then pass both")
    if (args.eval_dataset is None) != (args.scatter_dataset is None):
        raise ValueError("--eval-dataset and --scatter-dataset come together (path-traced fog to evaluate on, "
                         "scatter fog to train on)")
    if args.eval_dataset and args.sim_dataset:
        raise ValueError("--eval-dataset compares fog models on renders; --sim-dataset is for a real --dataset: "
                         "give one of them")
    if args.render and args.shard:
        raise ValueError("--render with --shard would make every array task render the same dataset: "
                         "render first (fogsim render --shard), then train with --dataset")


def render_command(dataset: Path, args) -> list[str]:
    """``fogsim render`` for --render: the study's sensors too (--lidar, --radar) for a BEV study."""
    cmd = [sys.executable, "-m", "fogsim", "render", "--out", str(dataset), "--preset",
           args.preset, "--frames", str(args.render), "--resolution", args.resolution]
    if args.sensor != "camera":
        cmd += ["--lidar", args.lidar_sensor]
    if args.sensor == "lidar+radar":
        cmd += ["--radar", args.radar_sensor]
    if args.samples:
        cmd += ["--samples", str(args.samples)]
    if args.render_seed is not None:
        cmd += ["--seed", str(args.render_seed)]
    if args.quiet:
        cmd.append("--quiet")
    return cmd


def render(dataset: Path, args) -> None:
    """Render (or complete) the dataset in a process of its own: bpy keeps its memory until exit."""
    code = subprocess.run(render_command(dataset, args)).returncode
    if code:
        raise SystemExit(code)


def cmd_sensor_study(args, dataset: Path) -> int:
    """``--sensor lidar|lidar+radar``: checks, the render (printed with --dry-run), then the BEV study."""
    from fogsim.cli.study_bev import bev_setup, cmd_bev

    setup = bev_setup(args)
    check_args(args)
    if args.render and args.dry_run:
        print("render: fogsim " + " ".join(render_command(dataset, args)[3:]))
        if not (dataset / "dataset.json").is_file():
            print("then the BEV study on its levels; the dataset does not exist yet, so its plan cannot be checked: "
                  "dry-run again with --dataset after the render")
            return EXIT_OK
    elif args.render:
        render(dataset, args)
    return cmd_bev(args, dataset, setup)


def cmd_study(args) -> int:
    from fogsim.augment.spec import parse_augment
    from fogsim.cli.study_bev import report_due
    from fogsim.detection.class_map import load_class_map
    from fogsim.detection.study import Study
    from fogsim.detection.yolo import TrainConfig
    from fogsim.runs import check_output, parse_shard

    inputs = {"--dataset": args.dataset, "--sim-dataset": args.sim_dataset, "--eval-dataset": args.eval_dataset,
              "--scatter-dataset": args.scatter_dataset}
    check_output(args.out, inputs, allow_inside_out=tuple(inputs))  # read through a view
    check_sensor_flags(args)
    out = Path(args.out)
    dataset = Path(args.dataset) if args.dataset else out / "dataset"
    if args.sensor != "camera":
        return cmd_sensor_study(args, dataset)
    cfg = TrainConfig(model=args.model or TrainConfig().model, epochs=args.epochs, mixed_epochs=args.mixed_epochs,
                      imgsz=args.imgsz, batch=args.batch, nbs=args.nbs, device=args.device, workers=args.workers,
                      seed=args.seed, patience=args.patience, cache=args.cache, plots=not args.no_plots)
    check_args(args)
    augment = parse_augment(args.augment) if args.augment else None
    shard = parse_shard(args.shard)
    if args.quiet:  # read when Ultralytics is first imported: its log and progress bars off, errors kept
        os.environ["YOLO_VERBOSE"] = "False"
    if args.render:
        render(dataset, args)
    class_map = load_class_map(args.class_map) if args.class_map else None
    study = Study(dataset, out, cfg, unknown_distance=args.unknown_distance, class_map=class_map,
                  sim_dataset=args.sim_dataset, augment=augment, eval_dataset=args.eval_dataset,
                  scatter_dataset=args.scatter_dataset)
    if not report_due(study, args, shard):
        return EXIT_OK
    study.report(args.max_distance, visible_only=args.visible_only)
    if not args.quiet:
        print(study.files.report("cross_density.md").read_text())
    print(f"report: {study.files.report('report.md')} (heatmaps: recall_heatmap.png, map50_heatmap.png)")
    return EXIT_OK

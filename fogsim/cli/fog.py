"""``fogsim fog``: fog datasets with the library alone (``demo`` and ``levels``: :mod:`fogsim.cli.demo`)."""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from fogsim.cli import fog_lidar
from fogsim.dataset.writer import check_train_fraction
from fogsim.errors import EXIT_FAILED, EXIT_OK, InputError
from fogsim.fog.labelled import SPLIT_BY
from fogsim.fog.model import airlight_rgb, check_heterogeneity
from fogsim.io.pixel_bound import MAX_PIXELS, pixel_bound
from fogsim.readers.base import DEPTH_ENCODINGS
from fogsim.schema.presets import TRAIN_FRACTION
from fogsim.schema.vocabulary import KERNELS, POST_PROCESS_KINDS, SPACES


def _add_fog_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("fog")
    g.add_argument("--levels", metavar="LEVELS", help="preset name (paper, foggy-cityscapes) or comma-separated β "
                                                     "in 1/m (default: paper)")
    g.add_argument("--visibility", metavar="METRES", help="comma-separated visibilities V instead of β (β = ln20/V)")
    g.add_argument("--model", choices=POST_PROCESS_KINDS, default="koschmieder",
                   help="koschmieder (the paper's law) or scatter: forward scattering, airlight by elevation "
                   "and glow, fitted on path-traced fog (docs: Fog physics)")
    g.add_argument("--scatter-params", metavar="FILE", help="--model scatter: a parameter file written by "
                   "fogsim fit-fog (default: the one shipped with fogsim)")
    g.add_argument("--extended", action="store_true", help="extended (smoothed-transmission) form")
    g.add_argument("--kernel", choices=KERNELS, default="box",
                   help="weights of the extended form (default box, as the paper's reference run)")
    g.add_argument("--kernel-size", type=int, metavar="K", default=19, help="kernel size in pixels, odd")
    g.add_argument("--sigma", type=float, default=5.0, help="Gaussian std in pixels")
    g.add_argument("--eps", type=float, default=1e-3, help="guided-filter regularisation")
    g.add_argument("--airlight", metavar="A", default="255",
                   help="airlight in 8-bit units: one value, R,G,B, or 'estimate' (dark channel)")
    g.add_argument("--space", choices=SPACES, default=None,
                   help="blend gamma-encoded values (srgb, the paper's) or linear light (default: srgb for "
                   "koschmieder, linear for scatter)")
    g.add_argument("--fill", metavar="FILL", default=None,
                   help="hole fill for depth: none, inpaint, ipbasic (default: none; inpaint for Cityscapes)")
    g.add_argument("--heterogeneity", type=float, metavar="A", default=0.0,
                   help="patchy fog: amplitude in [0,1) of a mean-1 density field (0 = off)")
    g.add_argument("--heterogeneity-scale", type=float, metavar="PX", default=64.0, help="patch size in pixels")
    g.add_argument("--seed", type=int, default=0, help="run seed (per-sample seeds derive from it)")


def _add_batch_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("batch")
    g.add_argument("--out", required=True, help="output folder: a labelled dataset (images/<level>/, labels/, "
                                                "meta/, coco/, …) when the input has labels, else OUT/<level>/<input "
                                                "tree>")
    g.add_argument("--format", dest="image_format", choices=("png", "jpg"), default="png",
                   help="png keeps the input's bit depth (8 or 16); jpg is 8-bit (16-bit input scaled, recorded)")
    g.add_argument("--max-pixels", type=int, metavar="N", default=MAX_PIXELS,
                   help=f"an image of more pixels than this fails (default {MAX_PIXELS:,} ≈ 8192×4883)")
    g.add_argument("--workers", type=int, metavar="N", default=1, help="worker processes")
    g.add_argument("--shard", metavar="i/N", help="process every N-th sample starting at i (0-based), "
                                                  "e.g. $SLURM_ARRAY_TASK_ID/N")
    g.add_argument("--no-resume", action="store_true", help="redo samples whose outputs exist")
    g.add_argument("--quiet", action="store_true", help="print only errors and the summary line (no progress bar)")


def _add_label_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("labels (datasets with annotations: Cityscapes gtFine, Waymo camera labels)")
    g.add_argument("--no-labels", action="store_true",
                   help="fog the images alone (OUT/<level>/<key>.png + sidecar JSON), not a labelled dataset in "
                        "the render's layout")
    g.add_argument("--min-pixels", type=int, metavar="N", default=0,
                   help="annotations with fewer pixels become ignore regions (0: every one kept)")
    g.add_argument("--train-fraction", type=float, metavar="F", default=None,
                   help=f"share of frames in the train split (hash of the frame name; default {TRAIN_FRACTION}, "
                        "or the run's with --finalize-only)")
    g.add_argument("--split-by", choices=SPLIT_BY, default=None,
                   help="train/val split by hash of each frame's name, or of its input folder (a Waymo segment, "
                        "a Cityscapes city: never on both sides); default frame, or the run's with --finalize-only")
    g.add_argument("--finalize-only", action="store_true",
                   help="only write the dataset-wide files of OUT (COCO, splits, data YAMLs, dataset.json, contact "
                        "sheet), after the shards of an array job")


def add_parsers(sub) -> None:
    fog = sub.add_parser("fog", help="fog a dataset at several densities",
                         description="Fog images (and LiDAR scans, radar sweeps) at several densities β.\n"
                                     "Docs: Fog on real data, LiDAR in fog, Radar in fog (docs/, or the site).")
    inputs = fog.add_argument_group("input (one of; none with --finalize-only)")
    src = inputs.add_mutually_exclusive_group()
    src.add_argument("--input", metavar="DIR", help="folder of images (paired with --depth by name)")
    src.add_argument("--cityscapes", metavar="ROOT", help="Cityscapes root (leftImg8bit/, disparity/, camera/)")
    src.add_argument("--waymo", metavar="PATH", help="Waymo v1 .tfrecord file or folder, or a Waymo v2 parquet root")
    fog_lidar.add_inputs(src)
    inputs.add_argument("--split", default=None, help="Cityscapes split(s), comma-separated (default val); --kitti: "
                                                      "an ImageSets name or split file (default: every image); "
                                                      "--stf: a split file (date,frame lines)")
    inputs.add_argument("--cameras", default="FRONT", help="Waymo cameras, comma-separated (FRONT, FRONT_LEFT, …)")
    inputs.add_argument("--no-verify", action="store_true",
                        help="Waymo v1: skip the TFRecord data CRCs (a damaged record then goes unnoticed)")
    d = fog.add_argument_group("depth")
    d.add_argument("--depth", metavar="DIR", help="folder of depth maps for --input, matched by relative name")
    d.add_argument("--depth-dir", metavar="DIR", help="folder of depth maps for --waymo (<segment>/<time>_<CAMERA>.*)")
    d.add_argument("--depth-suffix", metavar="TEXT", default="", help="depth name = image stem + this + extension")
    d.add_argument("--depth-encoding", choices=DEPTH_ENCODINGS, default="metric",
                   help="metric: metres (EXR/.npy/16-bit PNG × --depth-scale); paper-8bit: the paper's "
                        "8-bit ILA maps decoded with its constant; disparity: Cityscapes 16-bit disparity, "
                        "which needs each image's camera JSON: only with --cityscapes (its default)")
    d.add_argument("--depth-scale", type=float, metavar="M", help="metres per unit of 16-bit PNG depth (e.g. 0.001)")
    d.add_argument("--depth-kind", choices=("planar", "ray"), default="planar",
                   help="planar Z (converted to ray distance with the intrinsics) or ray distance")
    d.add_argument("--intrinsics", metavar="JSON", help="JSON with fx, fy, cx, cy, width, height (or K, width, height)")
    d.add_argument("--hfov", type=float, metavar="DEG", help="horizontal field of view in degrees (centred, square "
                                                            "pixels)")
    d.add_argument("--depth-from", metavar="SOURCE",
                   help="ila:CHECKPOINT: depth predicted by an ILA model (datasets without depth, e.g. Waymo); "
                        "lidar[:METHOD] (--waymo; the default of --kitti, --stf): each frame's LiDAR points completed "
                        "into dense ray distance, METHOD ipbasic (default), linear (beam-aware) or ila:CHECKPOINT")
    d.add_argument("--lidar-holdout", type=float, metavar="FRACTION",
                   help="with --depth-from lidar: hold this fraction of each image's points out of the "
                        "completion and save them (OUT/lidar_holdout/<key>.npz, with the completion in "
                        "OUT/lidar_depth/<key>.exr) for `fogsim depth score` (default: none)")
    _add_fog_options(fog)
    fog_lidar.add_options(fog)
    _add_batch_options(fog)
    _add_label_options(fog)

    fog.set_defaults(run=cmd_fog)


def _samples(args):
    from dataclasses import replace

    from fogsim.camera import Intrinsics
    from fogsim.io.documents import read_json
    from fogsim.readers.base import DepthSpec

    if args.depth_encoding == "disparity" and not args.cityscapes:
        raise ValueError("--depth-encoding disparity needs each image's Cityscapes camera JSON (baseline, fx), "
                         "which --input and --waymo have no way to give: use --cityscapes ROOT (leftImg8bit/, "
                         "disparity/, camera/), which decodes disparity on its own")
    spec = DepthSpec("", args.depth_encoding, args.depth_kind, args.depth_scale)
    K = None
    if args.intrinsics:
        K = Intrinsics.from_dict(read_json(args.intrinsics), args.intrinsics)
    if args.input:
        from fogsim.readers.folder import folder_samples

        samples = folder_samples(args.input, args.depth, spec, args.depth_suffix, K)
        if args.hfov is not None and K is None:
            if not 0 < args.hfov < 180:
                raise ValueError(f"--hfov must be in (0, 180) degrees, got {args.hfov}")
            with pixel_bound(getattr(args, "max_pixels", MAX_PIXELS)):
                h, w = samples[0].read_image().shape[:2]
            K = Intrinsics.from_hfov(args.hfov, w, h)
            samples = [replace(smp, intrinsics=K) for smp in samples]
        return samples
    if args.kitti or args.stf:
        return fog_lidar.samples(args)
    if args.cityscapes:
        from fogsim.readers.cityscapes import cityscapes_samples

        return cityscapes_samples(args.cityscapes, args.split, labels=False if getattr(args, "no_labels", False)
                                  else None)
    from fogsim.readers.waymo import waymo_samples

    cameras = tuple(c.strip().upper() for c in args.cameras.split(",") if c.strip())
    return waymo_samples(args.waymo, cameras, args.depth_dir, replace(spec, path=""),
                         verify=not getattr(args, "no_verify", False))


def _check_depth_from(args) -> None:
    """``--depth-from`` and ``--lidar-holdout`` checked before any input is read (exit 2)."""
    depth_from = args.depth_from or ""
    if not depth_from.startswith("lidar"):
        if args.lidar_holdout is not None:
            raise ValueError("--lidar-holdout goes with --depth-from lidar[:METHOD]")
        return
    from fogsim.depth.complete import holdout_split
    from fogsim.depth.lidar_source import parse_lidar

    parse_lidar(depth_from)  # unknown method → the usage
    if not (args.waymo or args.kitti or args.stf):
        raise ValueError(f"--depth-from {depth_from} completes LiDAR points: it needs --waymo, --kitti or --stf")
    if args.depth_dir:
        raise ValueError(f"--depth-from {depth_from} and --depth-dir are two depth sources for one image: "
                         "give one of them")
    holdout_split(0, args.lidar_holdout or 0.0)  # a fraction outside [0, 1) → the message


def max_workers() -> int:
    """The most worker processes a command starts: 4 per CPU this process may use (more only queue)."""
    return 4 * len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 4 * (os.cpu_count() or 1)


def _depth_from_path(depth_from: str | None) -> str | None:
    """The file ``--depth-from`` names (the checkpoint), or None."""
    kind, _, rest = (depth_from or "").partition(":")
    if kind == "lidar":
        return rest.partition(":")[2] or None
    return rest or None


def _with_depth_from(samples, depth_from: str | None, out: str | None = None, holdout: float | None = None,
                     seed: int = 0, dataset: str | None = None, scans_in_meta: bool = False):
    """``--depth-from ila:CKPT``: every sample's depth is predicted by that model;
    ``--depth-from lidar[:METHOD]``: completed from its LiDAR points
    (:func:`fogsim.depth.lidar_source.lidar_samples`, hold-out files under ``out``; ``scans_in_meta``:
    the points source is the reader's own, KITTI's and STF's ``meta["lidar_points"]``).

    The checkpoint is loaded and checked here, once, before the output folder is claimed: a
    missing, unreadable or unsafe one is one line naming it (exit 2), not a failure per image.
    """
    if not depth_from:
        return samples
    if depth_from.startswith("lidar"):
        from fogsim.depth.lidar_source import lidar_samples, meta_points_source

        if scans_in_meta:
            return lidar_samples(samples, depth_from, out, holdout or 0.0, seed, points_source=meta_points_source,
                                 has_lidar=None, dataset=dataset)
        return lidar_samples(samples, depth_from, out, holdout or 0.0, seed, dataset=dataset)
    from dataclasses import replace

    from fogsim.depth.ila import ILADepth, cached_model
    from fogsim.readers.base import DepthSpec

    kind, _, path = depth_from.partition(":")
    if kind != "ila" or not path:
        raise ValueError(f"--depth-from takes ila:CHECKPOINT or lidar[:METHOD], got {depth_from!r}")
    checkpoint = str(Path(path).resolve())
    try:
        cached_model(checkpoint)  # this process's workers=1 run reuses it
    except InputError as exc:
        raise InputError(path, exc.problem) from None  # named as the user gave it
    spec = DepthSpec(checkpoint, kind="planar", reader=ILADepth(checkpoint))
    return [replace(s, depth=spec) for s in samples]


def _job(args, out: str, classes: tuple[str, ...] = ()):
    from fogsim.fog.batch import FogJob
    from fogsim.fog.engine import FogSettings, Heterogeneity
    from fogsim.fog.levels import parse_levels
    from fogsim.fog.model import Kernel

    levels = tuple(parse_levels(args.levels, args.visibility))
    if args.airlight.strip().lower() == "estimate":
        airlight = "estimate"
    else:
        try:
            vals = [float(x) for x in args.airlight.split(",")]
        except ValueError:
            raise ValueError(f"--airlight takes a value in [0, 255], R,G,B or 'estimate', "
                             f"got {args.airlight!r}") from None
        if len(vals) not in (1, 3):
            raise ValueError(f"--airlight takes one value or R,G,B, got {args.airlight!r}")
        airlight = tuple(vals * 3 if len(vals) == 1 else vals)
        airlight_rgb(airlight, name="--airlight")  # the model's range, checked before any work
    kernel = Kernel(args.kernel, args.kernel_size, args.sigma, args.eps) if args.extended else None
    model = getattr(args, "model", "koschmieder")
    scatter_file = None
    if model == "scatter":
        if args.extended or args.heterogeneity:
            raise ValueError("--model scatter has no --extended kernel or --heterogeneity (Koschmieder only)")
        if args.scatter_params:
            scatter_file = str(Path(args.scatter_params).resolve())
    elif args.scatter_params:
        raise ValueError("--scatter-params needs --model scatter")
    check_heterogeneity(args.heterogeneity, args.heterogeneity_scale, ("--heterogeneity", "--heterogeneity-scale"))
    lidar_spec = None
    if getattr(args, "lidar", False):
        lidar_spec = fog_lidar.fog_spec(args, "last" if getattr(args, "stf_returns", None) == "last" else None)
    fog = FogSettings(model, airlight, args.space, kernel,
                      Heterogeneity(args.heterogeneity, args.heterogeneity_scale) if args.heterogeneity else None,
                      scatter_file, lidar=lidar_spec)
    fog.params  # a malformed scatter parameter file: one line naming it, before any work
    fill = args.fill or ("inpaint" if getattr(args, "cityscapes", None) else "none")
    from fogsim.fog.fill import fill_methods

    if fill not in fill_methods():
        raise ValueError(f"--fill must be one of {', '.join(fill_methods())}, got {fill!r}")
    inputs = _inputs(args)
    max_pixels = getattr(args, "max_pixels", MAX_PIXELS)
    if max_pixels < 1:
        raise ValueError(f"--max-pixels must be ≥ 1, got {max_pixels}")
    min_pixels = getattr(args, "min_pixels", 0)
    if min_pixels < 0:
        raise ValueError(f"--min-pixels must be ≥ 0, got {min_pixels}")
    if classes:
        train_fraction = getattr(args, "train_fraction", None)
        inputs["train_fraction"] = check_train_fraction(TRAIN_FRACTION if train_fraction is None else train_fraction,
                                                        "--train-fraction")
        inputs["split_by"] = getattr(args, "split_by", None) or "frame"
    return FogJob(levels, out, fog, fill, args.seed, getattr(args, "image_format", "png"), inputs,
                  labels=bool(classes), classes=tuple(classes), min_pixels=min_pixels, max_pixels=max_pixels,
                  lidar=fog_lidar.output(args) if getattr(args, "lidar", False) else None)


def _inputs(args) -> dict:
    """What the run reads and how, recorded so a resumed run with other inputs is refused."""
    keys = ("input", "depth", "cityscapes", "split", "waymo", "depth_dir", "cameras", "depth_suffix",
            "depth_encoding", "depth_scale", "depth_kind", "intrinsics", "hfov", "depth_from", "lidar_holdout")
    out = {k: getattr(args, k) for k in keys if getattr(args, k, None) not in (None, "")}
    for k in ("input", "depth", "cityscapes", "waymo", "depth_dir", "intrinsics"):
        if k in out:
            out[k] = str(Path(out[k]).resolve())
    if getattr(args, "intrinsics", None):
        from fogsim.io.documents import read_json

        out["intrinsics_values"] = read_json(args.intrinsics)
    if getattr(args, "kitti", None) or getattr(args, "stf", None):
        out |= fog_lidar.inputs(args)
    return out


def cmd_fog(args) -> int:
    from dataclasses import replace

    from fogsim.deps import package_versions
    from fogsim.fog.batch import run
    from fogsim.fog.labelled import check_labelled, sample_classes
    from fogsim.runs import check_output, is_sharded, parse_shard, select_shard
    from fogsim.schema.base import check_flag, int_in

    if args.finalize_only:
        return _finalize_only(args)
    check_flag("--workers", args.workers, int_in(1, max_workers()))  # each is a process with its own inputs
    if args.points:
        return fog_lidar.cmd_points(args)
    if not (args.input or args.cityscapes or args.waymo or args.kitti or args.stf):
        raise ValueError("give one of --input, --cityscapes, --waymo, --kitti, --stf, --points "
                         "(or --finalize-only --out OUT)")
    fog_lidar.normalise(args)
    _check_depth_from(args)
    check_output(args.out, {f"--{k.replace('_', '-')}": getattr(args, k)
                            for k in ("input", "depth", "cityscapes", "waymo", "depth_dir", "intrinsics", "kitti",
                                      "stf", "stf_calib")}
                 | {"--depth-from": _depth_from_path(args.depth_from)})
    everything = _with_depth_from(_samples(args), args.depth_from, args.out, args.lidar_holdout, args.seed,
                                  args.waymo or args.kitti or args.stf, scans_in_meta=bool(args.kitti or args.stf))
    if args.lidar and args.waymo:
        everything = fog_lidar.with_waymo_scans(everything, args)
    if args.no_labels:
        everything = [replace(s, labels=None) if s.labels is not None else s for s in everything]
    labelled = any(s.labels is not None for s in everything)
    if not labelled and not args.no_labels:
        _note_unlabelled(everything)
    if labelled:
        check_labelled(everything, getattr(args, "image_format", "png"))  # every shard: one frame name rule
    job = _job(args, args.out, sample_classes(everything) if labelled else ())
    shard = parse_shard(args.shard)
    samples = select_shard(everything, shard)
    summary = run(samples, job, args.workers, not args.no_resume, not args.quiet,
                  package_versions() | {"samples": len(everything)})  # --finalize-only counts against it
    lines = [summary.line(job)]  # --quiet: joined into one summary line
    for source, error in summary.failed:
        print(f"  failed: {error if error.startswith(source) else f'{source}: {error}'}", file=sys.stderr)
    if labelled and is_sharded(shard):
        lines.append(f"fogsim: shard {shard[0]}/{shard[1]} done; when every shard has finished, write the dataset "
                     f"files with: fogsim fog --finalize-only --out {args.out}")
    elif labelled:
        if not job.layout.done_frames():
            print(lines[0])
            print(f"fogsim: error: {args.out}: no frame was fogged, so there is no dataset to finalize",
                  file=sys.stderr)
            return EXIT_FAILED
        line, skipped = _finalize(args.out, job.inputs["train_fraction"], job.inputs["split_by"], args.quiet)
        lines.append(line)
    print("; ".join(lines) if args.quiet else "\n".join(lines))
    return EXIT_FAILED if summary.failed or (labelled and not is_sharded(shard) and skipped) else EXIT_OK


def _note_unlabelled(samples) -> None:
    """One line on stderr when the dataset has label sources but none for these images (a
    Waymo segment without camera_labels for the selected cameras): the run writes images only."""
    missing = [s.meta["labels_missing"] for s in samples if (s.meta or {}).get("labels_missing")]
    if missing:
        print(f"fogsim: warning: {missing[0]}; {len(missing)} of {len(samples)} images have no labels, so "
              "this run writes images only (OUT/<level>/<key>.png + sidecar JSON); choose labelled cameras "
              "with --cameras, or pass --no-labels", file=sys.stderr)


def _finalize(out: str, train_fraction: float | None = None, split_by: str | None = None,
              quiet: bool = False) -> tuple[str, list]:
    """Write the dataset files (None: the run's own train fraction / split rule); returns the
    summary line and the meta files skipped (each named on stderr: a per-frame problem). A frame in
    both splits (a one-frame dataset) is one warning line on stderr (``quiet``: said in the summary line)."""
    from fogsim.dataset.visible import visible_line
    from fogsim.dataset.writer import split_note
    from fogsim.fog.batch import finalize_dataset

    summary = finalize_dataset(out, train_fraction, split_by)
    note = split_note(summary)
    if note and not quiet:
        print(f"fogsim: warning: {note}", file=sys.stderr)
    skipped = summary.get("skipped_frames", [])
    for line in skipped:
        print(f"  skipped: {line}", file=sys.stderr)
    if not quiet and (visible := visible_line(summary)):  # what labels/ holds that the fog hides
        print(visible)
    counts = ", ".join(f"{c} {n}" for c, n in summary["counts"].items())
    extra = f", {len(skipped)} meta files skipped" if skipped else ""
    if summary.get("absent_frames"):
        extra += (f"; {summary['absent_frames']} of the run's samples have no frame yet "
                  "(a shard not finished, or samples that failed)")
    split = ("1 frame, in both train and val" if note else
             f"{summary['frames']} frames ({summary['split']['train']} train / {summary['split']['val']} val)")
    return f"dataset: {split}{extra}, objects kept: {counts} → {out}/dataset.json", skipped


def _finalize_only(args) -> int:
    given = [f"--{k}" for k in ("input", "cityscapes", "waymo", "kitti", "stf", "points", "shard")
             if getattr(args, k, None)]
    if given:
        raise ValueError(f"--finalize-only takes --out (and --train-fraction, --split-by) only, not "
                         f"{', '.join(given)}")
    line, skipped = _finalize(args.out, args.train_fraction, args.split_by, args.quiet)  # checks: finalize_dataset
    print(line)
    return EXIT_FAILED if skipped else EXIT_OK

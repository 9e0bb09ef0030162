"""``fogsim ila train | fill | predict``: ILA depth completion (needs the ``ila`` extra: torch)."""
from __future__ import annotations

import sys
from pathlib import Path

from fogsim.depth.ila import LOSS_ON, LOSSES, ILAConfig
from fogsim.errors import EXIT_FAILED, EXIT_OK, InputError


def add_training_options(p, rounds: int = ILAConfig.rounds) -> None:
    """ILA training flags, shared by ``fogsim ila train`` and ``fogsim bench ila`` (one meaning each):
    each sets the :class:`~fogsim.depth.ila.ILAConfig` field of its name, with that field's default."""
    d = ILAConfig()
    g = p.add_argument_group("ILA training")
    g.add_argument("--rounds", type=int, default=rounds, help=f"ILA rounds (default {rounds})")
    g.add_argument("--epochs", type=int, default=d.epochs, help=f"epochs per round (default {d.epochs})")
    g.add_argument("--width", type=int, default=d.width,
                   help=f"U-Net width (default {d.width} ≈ 2 M parameters; 64 = the reference's 31 M)")
    g.add_argument("--size", default="x".join(map(str, d.size)), help="training resolution WxH, multiples of 16")
    g.add_argument("--sparse", action="store_true", help="also input the sparse disparity")
    g.add_argument("--loss-on", choices=LOSS_ON, default=d.loss_on,
                   help="the pixels of the loss: valid targets only, or all as the reference (holes → 0)")
    g.add_argument("--loss", choices=LOSSES, default=d.loss,
                   help="mse of disparity (the reference) or log_l1 (relative error)")
    g.add_argument("--seed", type=int, default=d.seed)


def parse_size(text: str) -> tuple[int, int]:
    """``--size WxH``: positive multiples of 16 (the U-Net pools four times)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size must look like 256x128 (width x height in pixels, multiples of 16), "
                         f"got {text!r}") from None
    if w < 16 or h < 16 or w % 16 or h % 16:
        raise ValueError(f"--size {text}: width and height must be positive multiples of 16 "
                         "(the U-Net halves them four times), e.g. 256x128")
    if w * h > ILAConfig.MAX_PIXELS:
        raise ValueError(f"--size {text}: at most {ILAConfig.MAX_PIXELS / 2**20:g} MP (the training set is held "
                         "in memory at this size; the reference trains at 480x320)")
    return w, h


def training_config(args):
    """The ``ILAConfig`` of the training flags; a bad value is a ``ValueError`` naming its flag."""
    from fogsim.schema.base import check_flag, int_in

    for flag, value in (("--rounds", args.rounds), ("--epochs", args.epochs)):
        if value < 1:
            raise ValueError(f"{flag} must be ≥ 1, got {value}")
    check_flag("--width", args.width, int_in(1, ILAConfig.MAX_WIDTH))  # the U-Net's parameters: ∝ width²
    if args.seed < 0:
        raise ValueError(f"--seed must be ≥ 0, got {args.seed}")
    return ILAConfig(width=args.width, size=parse_size(args.size), use_sparse=args.sparse, loss_on=args.loss_on,
                     loss=args.loss, rounds=args.rounds, epochs=args.epochs, seed=args.seed)


def add_parsers(sub) -> None:
    ila = sub.add_parser("ila", help="train ILA depth completion, or predict depth with it")
    isub = ila.add_subparsers(dest="ila_command", required=True)
    tr = isub.add_parser("train", help="train ILA rounds on a Cityscapes-layout split")
    tr.add_argument("--data", required=True, help="Cityscapes root (real, or OUT/cityscapes of a --stereo render)")
    tr.add_argument("--split", default="train")
    tr.add_argument("--out", required=True, help="folder for round_<r>.pt and ila_log.json")
    add_training_options(tr)
    tr.add_argument("--quiet", action="store_true")
    fl = isub.add_parser("fill", help="fill the holes of a Cityscapes-layout split's disparity with the model")
    fl.add_argument("--checkpoint", required=True)
    fl.add_argument("--data", required=True, help="Cityscapes root")
    fl.add_argument("--split", default="val")
    fl.add_argument("--out", required=True,
                    help="writes OUT/disparity/<split>/<city>/*_disparity.png (inputs untouched)")
    fl.add_argument("--quiet", action="store_true")
    pr = isub.add_parser("predict", help="predict planar depth (EXR, metres) for a folder of images")
    pr.add_argument("--checkpoint", required=True)
    pr.add_argument("--input", required=True)
    pr.add_argument("--out", required=True)
    pr.add_argument("--quiet", action="store_true")
    ila.set_defaults(run=cmd_ila)


def cmd_ila(args) -> int:
    import json

    from fogsim.depth import ila
    from fogsim.io.atomic import atomic_write_bytes
    from fogsim.runs import check_output

    inputs = {"--data": getattr(args, "data", None), "--input": getattr(args, "input", None),
              "--checkpoint": getattr(args, "checkpoint", None)}
    check_output(args.out, inputs)  # outputs never over the training data, images or checkpoint
    if args.ila_command == "train":
        config = training_config(args)
        data = ila.load_stereo_set(args.data, args.split, config.size)
        log = ila.train_rounds(data, config, args.out, progress=not args.quiet)
        atomic_write_bytes(Path(args.out) / "ila_log.json", json.dumps(
            {"config": str(config), "frames": data.keys, "camera": data.camera, "rounds": log}, indent=2).encode())
        print(f"trained {len(log)} ILA rounds on {len(data.keys)} frames → {log[-1]['checkpoint']}")
        return EXIT_OK
    if args.ila_command == "fill":
        return _ila_fill(args)
    return _ila_predict(args)


def _report(bar, source: str, exc: BaseException) -> str:
    """The one line for an item that failed, printed now (stderr) and returned for the summary."""
    text = str(exc) if isinstance(exc, (InputError, ValueError, OSError)) else f"{type(exc).__name__}: {exc}"
    line = text if text.startswith(source) else f"{source}: {text}"
    bar.write(f"error: {line}", file=sys.stderr)
    return line


def _ila_predict(args) -> int:
    """Planar depth for every image; an unreadable image is named and skipped (exit 1 at the end)."""

    from fogsim.depth.ila import load_model, predict_depth
    from fogsim.io.depth_files import write_depth
    from fogsim.io.images import read_image
    from fogsim.readers.folder import folder_samples

    model, config, camera = load_model(args.checkpoint)  # checked before anything is written
    samples = folder_samples(args.input, None)
    Path(args.out).mkdir(parents=True, exist_ok=True)  # an unwritable --out is a setup error

    def predict(s):
        depth = predict_depth(model, config, camera, read_image(s.source))
        write_depth(Path(args.out) / f"{s.key}.exr", depth)  # atomic: never half-written

    return _each(samples, predict, "ILA depth", "predicted planar depth (metres, EXR) for", args)


def _ila_fill(args) -> int:
    """Holes (p = 0) of each disparity map → the ILA prediction; valid pixels are kept.
    A frame that cannot be read is named and skipped (exit 1 at the end)."""

    from fogsim.camera import depth_to_disparity, encode_disparity_png
    from fogsim.depth.ila import ila_fill
    from fogsim.fog.fill import fill_holes, register_fill
    from fogsim.io.images import read_image, write_image
    from fogsim.readers.cityscapes import cityscapes_samples
    from fogsim.readers.cityscapes_files import read_cityscapes_depth

    fill = ila_fill(args.checkpoint)  # loads and checks the checkpoint before anything is written
    samples = cityscapes_samples(args.data, args.split)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    register_fill("ila", fill)

    def fill_one(s):
        depth, cam = read_cityscapes_depth(s.depth.path, s.depth.camera_path)
        filled = fill_holes(depth, "ila", read_image(s.source))
        rel = Path(s.depth.path).relative_to(Path(args.data))
        disparity = depth_to_disparity(filled, cam.baseline, cam.intrinsics.fx)
        write_image(Path(args.out) / rel, encode_disparity_png(disparity))  # atomic

    return _each(samples, fill_one, "ILA fill", "filled the disparity holes of", args)


def _each(samples, work, desc: str, summary: str, args) -> int:
    """``work(sample)`` for every sample with a progress bar; a failure is named and skipped, as
    in ``fogsim fog``, and makes the exit code 1."""
    from tqdm import tqdm

    failed = []
    with tqdm(samples, unit="img", disable=args.quiet, desc=desc) as bar:
        for s in bar:
            try:
                work(s)
            except Exception as exc:  # keep going, as fogsim fog
                failed.append(_report(bar, s.source, exc))
    done = len(samples) - len(failed)
    print(f"{summary} {done} of {len(samples)} images{f' ({len(failed)} failed)' if failed else ''} → {args.out}")
    return EXIT_FAILED if failed else EXIT_OK

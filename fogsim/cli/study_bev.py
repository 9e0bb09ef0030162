"""``fogsim study --sensor lidar|lidar+radar``: the BEV half of the study command (flags in
:mod:`fogsim.cli.study`; the study itself in :mod:`fogsim.detection.bev`)."""
from __future__ import annotations

import os
from pathlib import Path

from fogsim.errors import EXIT_OK


def parse_grid(text: str, imgsz: int):
    """``X0:X1,Y0:Y1`` (metres) → the :class:`~fogsim.detection.bev.grid.BevGrid` of ``imgsz`` pixels."""
    from fogsim.detection.bev.grid import BevGrid

    try:
        xs, ys = text.split(",")
        x_range = tuple(float(v) for v in xs.split(":"))
        y_range = tuple(float(v) for v in ys.split(":"))
        if len(x_range) != 2 or len(y_range) != 2:
            raise ValueError
    except ValueError:
        raise ValueError(f"--bev-grid must look like X0:X1,Y0:Y1 in metres (e.g. 0:50,-25:25), got {text!r}") from None
    return BevGrid.for_image(imgsz, x_range, y_range)


def parse_fog_models(text: str | None) -> tuple[str, ...]:
    """``a,b,c`` → the LiDAR fog models, each checked by the LiDAR fog spec (the names it knows)."""
    if not text:
        return ()
    from fogsim.lidar.fog import lidar_fog_spec

    names = tuple(n.strip() for n in text.split(",") if n.strip())
    for name in names:
        try:
            lidar_fog_spec({"model": name})
        except ValueError as exc:
            raise ValueError(f"--fog-models: {name!r}: {exc}") from None
    if len(names) < 2:
        raise ValueError("--fog-models compares LiDAR fog models: give at least two (e.g. soft-target,attenuation)")
    return names


def bev_setup(args):
    """(training configuration, grid, fog models, shard) from the flags: usage errors before anything runs."""
    from fogsim.detection.bev.study import DEFAULT_BEV_MODEL
    from fogsim.detection.yolo import TrainConfig
    from fogsim.runs import parse_shard

    cfg = TrainConfig(model=args.model or DEFAULT_BEV_MODEL, epochs=args.epochs, mixed_epochs=args.mixed_epochs,
                      imgsz=args.imgsz, batch=args.batch, nbs=args.nbs, device=args.device, workers=args.workers,
                      seed=args.seed, patience=args.patience, cache=args.cache, plots=not args.no_plots)
    return cfg, parse_grid(args.bev_grid, args.imgsz), parse_fog_models(args.fog_models), parse_shard(args.shard)


def report_due(study, args, shard) -> bool:
    """(The camera study's and the BEV study's.) Train this shard's models (none with --report-only); True when
    the report is to be written now: not with --no-report, nor while another shard's predictions are missing
    (then say how to finish)."""
    if not args.report_only:
        study.run_models(shard, progress=not args.quiet)
    if args.no_report:
        return False
    if not args.report_only and study.missing_predictions():
        print(f"fogsim: shard {shard[0]}/{shard[1]} done; when every shard has finished, "
              f"write the report with --report-only")
        return False
    return True


def cmd_bev(args, dataset: Path, setup) -> int:
    """The BEV study of ``dataset`` (rendered already, when --render) with ``setup`` from :func:`bev_setup`."""
    from fogsim.detection.bev.report import write_bev_report
    from fogsim.detection.bev.study import BevStudy

    cfg, grid, fog_models, shard = setup
    if args.quiet:
        os.environ["YOLO_VERBOSE"] = "False"
    if args.report_only:  # the training flags and the grid as study.json records them
        study = BevStudy.stored(dataset, Path(args.out), args.sensor, fog_models)
    else:
        study = BevStudy(dataset, Path(args.out), args.sensor, cfg, grid, fog_models)
    if args.dry_run:
        print(study.plan(shard))
        return EXIT_OK
    if args.prepare_only:
        study.prepare(progress=not args.quiet)
        print(f"BEV data: {study.files.root} ({', '.join(v.name for v in study.all_variants())})")
        return EXIT_OK
    if not report_due(study, args, shard):
        return EXIT_OK
    write_bev_report(study, args.difficulty)
    report = study.files.report("report.md")
    if not args.quiet:
        print(report.read_text())
    print(f"report: {report} (pictures: bev_contact_sheet.png, recall_by_distance.png, *_heatmap.png)")
    return EXIT_OK

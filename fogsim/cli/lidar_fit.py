"""``fogsim lidar-fit`` and ``fogsim lidar-compare``: hold a LiDAR fog model against real foggy scans
(:mod:`fogsim.lidar.fit`, :mod:`fogsim.lidar.scan_stats`, :mod:`fogsim.lidar.fit_report`).

    fogsim lidar-fit --clear CLEAR… --foggy FOGGY… --point-format stf [--visibility 80] [--lidar-model M]
                     [--lidar-calibration START] [--parameters k,…] [--evaluations 200] --out DIR
    fogsim lidar-compare --clear CLEAR… --foggy FOGGY… --point-format stf --visibility 80
                     [--lidar-model M] [--lidar-calibration NAME|FILE] --out DIR

``lidar-fit`` writes ``DIR/calibration.json`` (for ``--lidar-calibration``), ``DIR/report.json``,
``DIR/report.md``, ``DIR/histograms.png`` and ``DIR/distance.png``; ``lidar-compare`` the same but the
calibration. Every file atomically; inputs are only read.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from fogsim.errors import EXIT_OK
from fogsim.lidar.formats import FORMATS
from fogsim.schema.lidar import LIDAR_FOG_MODELS, SCALES

#: the files a fit writes in its --out folder
CALIBRATION_FILE, REPORT_JSON, REPORT_MD, HISTOGRAM_PNG, DISTANCE_PNG = (
    "calibration.json", "report.json", "report.md", "histograms.png", "distance.png")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--clear", nargs="+", required=True, metavar="FILE_OR_DIR",
                   help="clear-weather scans of the sensor (files, or folders searched for --point-format's files)")
    p.add_argument("--foggy", nargs="+", required=True, metavar="FILE_OR_DIR",
                   help="real foggy scans of the same sensor (other scenes are fine)")
    p.add_argument("--point-format", required=True, choices=FORMATS,
                   help="the scans' format (kitti 4×float32 .bin, nuscenes/stf 5×float32 .pcd.bin/.bin, ply, npy)")
    p.add_argument("--foggy-format", choices=FORMATS, help="the foggy scans' format (default: --point-format)")
    p.add_argument("--point-scale", choices=SCALES, help="ply/npy scans: the intensity scale when the file does not "
                   "say (default 0-1)")
    p.add_argument("--sensor", metavar="NAME|FILE", help="a bundled sensor (hdl64e, hdl64-s3d, hdl32e, waymo-top) or "
                   "a sensor JSON (default: the format's usual one: KITTI hdl64e, STF hdl64-s3d, nuScenes hdl32e)")
    p.add_argument("--lidar-model", choices=LIDAR_FOG_MODELS, default=None,
                   help="the fog model (default soft-target)")
    p.add_argument("--lidar-calibration", default=None, metavar="NAME|FILE",
                   help="the calibration scored (lidar-compare) or the fit's start (lidar-fit): datasheet (default), "
                        "hahner-constants or a calibration JSON")
    p.add_argument("--lidar-extinction-ratio", type=float, default=None, metavar="K",
                   help="β at 905 nm / the camera's β (default 1)")
    p.add_argument("--weights", metavar="TERM=W,…", help="the distance's weights (terms: range, near_share, "
                   "near_range, far_survival, intensity; default 1 each)")
    p.add_argument("--seed", type=int, default=0, help="the seed of the simulated fog's random draws (the same "
                   "draws at every evaluation; default 0)")
    p.add_argument("--out", required=True, metavar="DIR", help="the folder the report (and calibration) go to")
    p.add_argument("--quiet", action="store_true", help="print only errors and the summary line")


def add_parsers(sub) -> None:
    f = sub.add_parser("lidar-fit", help="fit a LiDAR fog model's calibration to real foggy scans (clear scans + "
                       "foggy scans of one sensor) and write the calibration, a report and its figures")
    _common(f)
    f.add_argument("--visibility", type=float, metavar="METRES",
                   help="the real fog's meteorological visibility, when known (default: fitted, 10-2000 m)")
    f.add_argument("--parameters", metavar="KEY,…", help="the calibration keys to fit (default: the model's: "
                   "soft-target fog_echo_scale, pulse_half_power_ns, overlap_full_m, fluctuation_sigma, max_range_m; "
                   "attenuation fluctuation_sigma, max_range_m; stf2020 stf_noise_level, stf_gain; hahner2021 none: "
                   "the visibility alone)")
    f.add_argument("--evaluations", type=int, default=200, metavar="N",
                   help="the most fogs of the clear set the fit may run (default 200)")
    f.add_argument("--name", help="the calibration's name (default fit-<sensor>-<model>)")
    f.set_defaults(run=cmd_fit)
    c = sub.add_parser("lidar-compare", help="score a LiDAR fog model and calibration against real foggy scans "
                       "(the statistics and distance of lidar-fit, without fitting)")
    _common(c)
    c.add_argument("--visibility", type=float, required=True, metavar="METRES",
                   help="the real fog's meteorological visibility")
    c.set_defaults(run=cmd_compare)


# ----------------------------------------------------------------------------- shared
def _scans(paths: list[str], fmt: str, scale: str | None):
    from fogsim.fog.point_files import point_files
    from fogsim.lidar.formats import read_points

    files = point_files(paths, fmt)
    return [read_points(f.source, fmt, scale) for f in files], [f.source for f in files]


def _problem(args, parameters):
    """(the :class:`~fogsim.lidar.fit.FitProblem`, the inputs record): flags checked before any scan is read."""
    from fogsim.cli.fog_lidar import fog_spec, sensor_choice
    from fogsim.fog.points import DEFAULT_SENSOR
    from fogsim.lidar.fit import FitProblem, beta_of_visibility
    from fogsim.lidar.scan_stats import parse_weights
    from fogsim.runs import check_output

    vis = args.visibility
    if vis is not None and not (math.isfinite(vis) and vis > 0):
        raise ValueError(f"--visibility must be a number of metres > 0, got {vis:g}")
    fmt = args.point_format
    foggy_fmt = args.foggy_format or fmt
    if args.point_scale and not {fmt, foggy_fmt} & {"ply", "npy"}:
        raise ValueError(f"--point-scale is for ply and npy scans; {fmt} scans have their own scale")
    sensor = sensor_choice(args.sensor) or DEFAULT_SENSOR.get(fmt)
    if sensor is None:
        raise ValueError(f"--point-format {fmt} has no usual sensor: give --sensor NAME|FILE")
    spec = fog_spec(args)
    weights = parse_weights(args.weights)
    given = [("--clear", p) for p in args.clear] + [("--foggy", p) for p in args.foggy]
    given += [(flag, p) for flag, p in (("--sensor", args.sensor), ("--lidar-calibration", args.lidar_calibration))
              if p and Path(p).exists()]
    check_output(args.out, given)
    clear, clear_files = _scans(args.clear, fmt, args.point_scale)
    foggy, foggy_files = _scans(args.foggy, foggy_fmt, args.point_scale)
    same = sorted(set(map(lambda p: str(Path(p).resolve()), clear_files)) &
                  set(map(lambda p: str(Path(p).resolve()), foggy_files)))
    if same:
        raise ValueError(f"{same[0]} is given as a clear and as a foggy scan")
    problem = FitProblem(clear, foggy, sensor, spec, None if vis is None else beta_of_visibility(vis), parameters,
                         weights, args.seed)
    inputs = {"clear": clear_files, "foggy": foggy_files, "point_format": fmt, "foggy_format": foggy_fmt,
              "sensor": sensor if isinstance(sensor, str) else "custom"}
    return problem, inputs


def _write(out: Path, record: dict, sets: dict, clear, trace) -> None:
    from fogsim.io.atomic import atomic_write_bytes
    from fogsim.io.documents import write_json
    from fogsim.lidar.fit_report import SIMULATED, distance_figure, histogram_figure, markdown
    from fogsim.lidar.pictures import write_png

    out.mkdir(parents=True, exist_ok=True)
    d = record["distance"]
    write_png(out / HISTOGRAM_PNG, histogram_figure(sets, clear))
    write_png(out / DISTANCE_PNG, distance_figure({k: v for k, v in d.items() if k in SIMULATED}, trace))
    atomic_write_bytes(out / REPORT_MD, markdown(record).encode())
    write_json(out / REPORT_JSON, record)


def _parameters(text: str | None):
    if text is None:
        return None
    keys = tuple(k.strip() for k in text.split(",") if k.strip())
    if not keys:
        raise ValueError("--parameters names no calibration key")
    return keys


# ----------------------------------------------------------------------------- the commands
def cmd_fit(args) -> int:
    from fogsim.console import progress_bar
    from fogsim.io.documents import write_json
    from fogsim.lidar.fit import fit, fitted_calibration
    from fogsim.lidar.fit_report import report_record

    if args.evaluations < 1:
        raise ValueError(f"--evaluations must be ≥ 1, got {args.evaluations}")
    t0 = time.perf_counter()
    problem, inputs = _problem(args, _parameters(args.parameters))
    if not problem.parameters and problem.beta is not None:
        raise ValueError(f"{problem.spec.model} has no calibration key to fit (fogsim.lidar.fit.MODEL_PARAMETERS) and "
                         "--visibility is given: nothing to fit; score it with fogsim lidar-compare")
    bar = progress_bar(args.evaluations, "lidar-fit", "fogs", args.quiet)

    def progress(done, best):
        bar.update(done - bar.n)
        bar.set_postfix_str(f"distance {best:.4f}", refresh=False)
    try:
        result = fit(problem, args.evaluations, progress)
    finally:
        bar.close()
    elapsed = time.perf_counter() - t0
    name = args.name or f"fit-{problem.sensor.name}-{problem.spec.model}"
    when = time.strftime("%Y-%m-%d")
    source = (f"fitted by fogsim lidar-fit ({when}) to {len(problem.real)} foggy scans against {len(problem.clear)} "
              f"clear ones (the {REPORT_MD} written with this file)")
    calibration = fitted_calibration(problem, result, name, {k: source for k in problem.parameters})
    out = Path(args.out)
    record = report_record(problem, result, command="lidar-fit", start_beta=result.start_beta,
                           start_distance=result.start_distance, start_terms=result.start_terms,
                           start_sim=result.start_simulated, inputs=inputs, elapsed_s=elapsed,
                           calibration_file=CALIBRATION_FILE)
    sets = {"clear": problem.clear_stats, "real": problem.real_stats, "default": result.start_simulated,
            "fitted": result.simulated}
    _write(out, record, {k: v for k, v in sets.items() if v is not None}, problem.clear_stats, result.trace)
    write_json(out / CALIBRATION_FILE, calibration)
    vis = record["visibility_m"]
    if not args.quiet:
        for k, p in record["parameters"].items():
            print(f"  {k}: {p['start']:.4g} → {p['fitted']:.4g}")
    print(f"lidar-fit: distance {result.start_distance:.4f} (start) → {result.distance:.4f} in {result.evaluations} "
          f"evaluations, {elapsed:.1f} s; visibility {vis['value']:.0f} m ({vis['source']}); wrote "
          f"{out / CALIBRATION_FILE} (use: --lidar-calibration {out / CALIBRATION_FILE}) and the report "
          f"{out / REPORT_MD}", file=sys.stdout)
    return EXIT_OK


def cmd_compare(args) -> int:
    from fogsim.lidar.fit_report import report_record

    t0 = time.perf_counter()
    problem, inputs = _problem(args, ())
    total, terms, sim = problem.evaluate(problem.start, problem.beta)
    if sim is None:
        raise ValueError(f"{problem.spec.model} cannot fog these scans: {problem.last_error}")
    record = report_record(problem, None, command="lidar-compare", start_beta=problem.beta, start_distance=total,
                           start_terms=terms, start_sim=sim, inputs=inputs, elapsed_s=time.perf_counter() - t0)
    out = Path(args.out)
    _write(out, record, {"clear": problem.clear_stats, "real": problem.real_stats, "simulated": sim},
           problem.clear_stats, None)
    if not args.quiet:
        for k, v in terms.items():
            print(f"  {k}: {v:.4f}")
    print(f"lidar-compare: {problem.spec.model} ({record['start_calibration']}) at visibility "
          f"{record['visibility_m']['value']:.0f} m: distance {total:.4f}; report {out / REPORT_MD}")
    return EXIT_OK

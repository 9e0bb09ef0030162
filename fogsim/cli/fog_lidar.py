"""``fogsim fog``'s LiDAR side: KITTI and Seeing Through Fog as inputs (``--kitti``, ``--stf``), each
level's scan (``--lidar`` with ``--kitti``, ``--stf`` or ``--waymo``) and scans without a dataset
(``--points``; radar sweeps too: ``--point-format nuscenes-radar``). The camera side and the batch
options are :mod:`fogsim.cli.fog`'s.

Why ``--stf ROOT`` and not ``--kitti ROOT --layout stf``: STF's tree shares nothing with KITTI's but the
label fields (``cam_stereo_left_lut/``, ``lidar_hdl64_{strongest,last}/``, ``gt_labels/…``, date-stamped
ids, ``date,frame`` split lines) and needs what KITTI never does — a calibration from outside the download
(``--stf-calib``) and a choice of return (``--stf-returns``). One flag per layout keeps each flag's
meaning whole and the messages plain; both go through the same reader (:mod:`fogsim.readers.kitti`).
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from fogsim.errors import EXIT_FAILED, EXIT_OK
from fogsim.lidar.formats import FORMATS
from fogsim.lidar.objects import MIN_POINTS
from fogsim.readers.kitti.samples import KITTI_PARTS, STF_RETURNS
from fogsim.schema.lidar import HAHNER_VARIANTS, LIDAR_FOG_MODELS, SCALES, STF_BETA_FIELDS

#: the inputs that have a scan per image (``--lidar`` goes with them)
SCAN_INPUTS = ("kitti", "stf", "waymo")
#: the radar formats ``--points`` reads (fogsim.radar.formats)
RADAR_POINT_FORMATS = ("nuscenes-radar",)
POINT_FORMATS = FORMATS + RADAR_POINT_FORMATS
#: the flags of the other inputs (their depth, camera, split, labels), refused with --points
OTHER_INPUTS_FLAGS = ("depth", "depth_dir", "depth_scale", "intrinsics", "hfov", "depth_from", "lidar_holdout",
                      "kitti_part", "stf_calib", "stf_returns", "split", "train_fraction", "split_by")


def add_inputs(src) -> None:
    """The LiDAR-bearing inputs in the mutually exclusive input group."""
    src.add_argument("--kitti", metavar="ROOT",
                     help="KITTI object-detection root (training/{image_2,velodyne,calib,label_2}, "
                          "ImageSets/): camera fog with depth from the projected scan")
    src.add_argument("--stf", metavar="ROOT",
                     help="Seeing Through Fog root (cam_stereo_left_lut/, lidar_hdl64_strongest|last/, "
                          "gt_labels/cam_left_labels_TMP/); needs --stf-calib")
    src.add_argument("--points", nargs="+", metavar="FILE_OR_DIR",
                     help="LiDAR scans or radar sweeps without a dataset: files, or folders searched for "
                          "--point-format's files; writes OUT/<level>/<name>.<ext> + outcomes + a sidecar JSON per "
                          "scan and level")


def add_options(fog: argparse.ArgumentParser) -> None:
    k = fog.add_argument_group("KITTI and Seeing Through Fog")
    k.add_argument("--kitti-part", choices=KITTI_PARTS, default=None,
                   help="--kitti: the part to read (default training; testing has no labels)")
    k.add_argument("--stf-calib", metavar="FILE_OR_DIR",
                   help="--stf: the calibration (the repository's kitti_stereo_velodynehdl_calib.txt, or its "
                        "tools/DatasetViewer/calibs folder); not needed when ROOT/calib/<id>.txt exist")
    k.add_argument("--stf-returns", choices=STF_RETURNS, default=None,
                   help="--stf: which scans to read, lidar_hdl64_strongest or _last (default strongest; last "
                        "also fogs with the sensor in last-return mode)")
    g = fog.add_argument_group("LiDAR (docs: LiDAR in fog)")
    g.add_argument("--lidar", action="store_true",
                   help="with --kitti, --stf or --waymo: also write each level's fogged scan (OUT/lidar/<level>/, "
                        "in the source's format, + per-point outcomes), count each object's points per level, "
                        "and (KITTI, STF) each level as a KITTI tree OUT/kitti/<level>/")
    g.add_argument("--lidar-model", choices=LIDAR_FOG_MODELS, default=None,
                   help="soft-target (fogsim's, default), attenuation (no fog echo), hahner2021 (Hahner et al.'s "
                        "released code) or stf2020 (the STF authors' chamber-fitted rule: hdl64e, hdl64-s3d)")
    g.add_argument("--hahner-variant", choices=HAHNER_VARIANTS, default=None,
                   help="hahner2021: its batch path (default) or its viewer's backscatter")
    g.add_argument("--stf-beta-field", choices=STF_BETA_FIELDS, default=None,
                   help="stf2020: one β (default) or the STF authors' random β field")
    g.add_argument("--lidar-sensor", "--sensor", dest="lidar_sensor", metavar="NAME|FILE",
                   help="hdl64e, hdl64-s3d, hdl32e, waymo-top or a sensor JSON (default: the format's usual "
                        "one); radar sweeps: ars408-lr (default), srr-corner or a JSON")
    g.add_argument("--lidar-calibration", default=None, metavar="datasheet|hahner-constants|FILE",
                   help="datasheet (default), hahner-constants (Hahner et al.'s pulse and overlap in fogsim's "
                        "model) or a calibration JSON (its keys with 'name' and 'sources')")
    g.add_argument("--lidar-extinction-ratio", type=float, default=None, metavar="K",
                   help="β at 905 nm / the camera's β (default 1: fog droplets much larger than both wavelengths)")
    g.add_argument("--lidar-min-points", type=int, default=None, metavar="N",
                   help=f"an object is seen by the LiDAR with ≥ N points in its 3D box (default {MIN_POINTS})")
    g.add_argument("--no-kitti-trees", action="store_true",
                   help="--lidar with --kitti/--stf: do not write OUT/kitti/<level>/ trees")
    g.add_argument("--point-format", choices=POINT_FORMATS,
                   help="--points: the scans' format (kitti 4×float32, nuscenes/stf 5×float32 .pcd.bin/.bin, "
                        "ply, npy; nuscenes-radar: nuScenes RADAR_* .pcd sweeps, docs: Radar in fog)")
    g.add_argument("--point-scale", choices=SCALES,
                   help="--points ply/npy: the intensity scale when the file does not say (default 0-1)")
    r = fog.add_argument_group("radar (docs: Radar in fog)")
    r.add_argument("--radar-temperature", type=float, default=None, metavar="CELSIUS",
                   help="--point-format nuscenes-radar: the fog's temperature for ITU-R P.840's liquid-water "
                        "attenuation (default 10 °C); --sensor names a radar there (default ars408-lr)")


# ----------------------------------------------------------------------------- checks and records
def _lidar_flags_given(args) -> list[str]:
    names = {"lidar_model": "--lidar-model", "lidar_sensor": "--lidar-sensor", "lidar_min_points":
             "--lidar-min-points", "lidar_extinction_ratio": "--lidar-extinction-ratio",
             "lidar_calibration": "--lidar-calibration", "hahner_variant": "--hahner-variant",
             "stf_beta_field": "--stf-beta-field"}
    given = [flag for key, flag in names.items() if getattr(args, key, None) is not None]
    return given + (["--no-kitti-trees"] if getattr(args, "no_kitti_trees", False) else [])


def normalise(args) -> None:
    """Defaults that depend on the input, and the LiDAR flags checked against it (ValueError: exit 2,
    before anything is read)."""
    kitti_like = bool(args.kitti or args.stf)
    if args.split is None and not kitti_like:
        args.split = "val"  # Cityscapes' default, as recorded by older runs
    if args.kitti:
        args.kitti_part = args.kitti_part or "training"
    elif args.kitti_part is not None:
        raise ValueError("--kitti-part goes with --kitti")
    if args.stf:
        args.stf_returns = args.stf_returns or "strongest"
    elif args.stf_returns is not None or args.stf_calib is not None:
        raise ValueError(f"{'--stf-returns' if args.stf_returns else '--stf-calib'} goes with --stf")
    if kitti_like:
        flag = "--kitti" if args.kitti else "--stf"
        for other in ("depth", "depth_dir", "intrinsics", "hfov"):
            if getattr(args, other, None):
                raise ValueError(f"{flag} brings its own camera and its scans for depth: drop "
                                 f"--{other.replace('_', '-')} (depth: --depth-from lidar[:METHOD] or ila:CHECKPOINT)")
        args.depth_from = args.depth_from or "lidar"
    if args.lidar and not any(getattr(args, k, None) for k in SCAN_INPUTS):
        raise ValueError("--lidar fogs each image's LiDAR scan: it needs --kitti, --stf or --waymo "
                         "(scans alone: --points FILES --point-format …)")
    if not args.lidar and (given := _lidar_flags_given(args)):
        raise ValueError(f"{given[0]} goes with --lidar (or --points)")
    for flag in ("--point-format", "--point-scale", "--radar-temperature"):
        if getattr(args, flag[2:].replace("-", "_"), None) is not None:
            raise ValueError(f"{flag} goes with --points")
    if args.lidar:
        fog_spec(args)  # the model against the flags and the sensor, before anything is read


def _not_empty(flag: str, given: str) -> None:
    """An empty value given to ``flag`` — most often an unset shell variable — is refused, never read as the
    default."""
    if not str(given).strip():
        raise ValueError(f"{flag} is empty (an unset shell variable?): name a value, or leave the flag out for "
                         "the default")


def sensor_choice(given: str | None, radar: bool = False):
    """``--sensor`` (``--lidar-sensor``): None, a bundled name (checked), or a custom block read from its file
    (checked, one line naming it) — a LiDAR's, or with ``radar`` a radar's: what the run records and the workers
    load."""
    if given is None:
        return None
    _not_empty("--sensor", given)
    if radar:
        from fogsim.radar.sensors import RadarSensor as Sensor
        from fogsim.radar.sensors import load_radar_sensor as load
    else:
        from fogsim.lidar.sensors import LidarSensor as Sensor
        from fogsim.lidar.sensors import load_sensor as load

    path = Path(given)
    if path.suffix == ".json" or path.is_file():
        from fogsim.io.documents import MAX_DOCUMENT_BYTES, read_json

        load(path)  # the file's problems, one line naming it
        return read_json(path, MAX_DOCUMENT_BYTES)
    Sensor.preset(given)  # an unknown name: a ValueError listing the bundled ones
    return given


def calibration_choice(given: str | None):
    """``--lidar-calibration``: None, ``datasheet``, ``hahner-constants`` (``reference``, its deprecated name,
    becomes it with a note on stderr), or a calibration block read from its file (checked: an
    :class:`~fogsim.errors.InputError` naming it) — what the fog record stores."""
    from fogsim.schema.lidar import CALIBRATIONS, DEPRECATED_CALIBRATIONS, LidarCalibration

    if given in DEPRECATED_CALIBRATIONS:
        print(f"note: --lidar-calibration {given} is deprecated: it is now called {DEPRECATED_CALIBRATIONS[given]} "
              "(Hahner et al.'s pulse and overlap constants in fogsim's model)", file=sys.stderr)
        return DEPRECATED_CALIBRATIONS[given]
    if given is None or given in CALIBRATIONS:
        return given
    _not_empty("--lidar-calibration", given)
    path = Path(given)
    if path.suffix != ".json" and not path.is_file():
        raise ValueError(f"--lidar-calibration must be {', '.join(CALIBRATIONS)} or a calibration JSON file, "
                         f"got {given!r}")
    from fogsim.schema.base import load_json

    return load_json(path, LidarCalibration).model_dump(exclude_none=True)


def fog_spec(args, return_mode: str | None = None):
    """The fog record's LiDAR part (:class:`~fogsim.schema.lidar.LidarFogSpec`) from the flags, checked against
    the model (:func:`check_model`)."""
    from fogsim.lidar.fog import lidar_fog_spec

    ratio = args.lidar_extinction_ratio
    if ratio is not None and not ratio > 0:
        raise ValueError(f"--lidar-extinction-ratio must be > 0, got {ratio:g}")
    variant, field = getattr(args, "hahner_variant", None), getattr(args, "stf_beta_field", None)
    model = args.lidar_model or "soft-target"
    if variant is not None and model != "hahner2021":
        raise ValueError("--hahner-variant goes with --lidar-model hahner2021")
    if field is not None and model != "stf2020":
        raise ValueError("--stf-beta-field goes with --lidar-model stf2020")
    block = {k: v for k, v in (("model", args.lidar_model), ("extinction_ratio", ratio),
                               ("return_mode", return_mode),
                               ("calibration", calibration_choice(getattr(args, "lidar_calibration", None))),
                               ("hahner_variant", variant), ("stf_beta_field", field))
             if v is not None}
    spec = lidar_fog_spec(block)
    _check_calibration(args, spec)
    check_model(args, spec)
    return spec


def run_sensor(args):
    """The LiDAR a run fogs for (what ``--sensor`` names, else the input's usual one; None: not known up
    front)."""
    from fogsim.fog.points import DEFAULT_SENSOR
    from fogsim.readers.kitti.samples import SENSORS

    chosen = sensor_choice(getattr(args, "lidar_sensor", None))
    if chosen is not None:
        return chosen
    if getattr(args, "points", None):
        return DEFAULT_SENSOR.get(args.point_format)
    if getattr(args, "kitti", None) or getattr(args, "stf", None):
        return SENSORS["kitti" if args.kitti else "stf"]
    return "waymo-top" if getattr(args, "waymo", None) else None


def check_model(args, spec) -> None:
    """What the published models cannot do, refused before anything is read (a ValueError: exit 2):
    hahner2021 with patchy fog (one β per scan); stf2020 with a sensor without the STF constants n and g (the
    run's sensor, :func:`run_sensor`, under the run's calibration)."""
    if spec.model == "hahner2021" and getattr(args, "heterogeneity", 0):
        raise ValueError("--lidar-model hahner2021 fogs a scan at one β (the released code's one α): drop "
                         "--heterogeneity, or use soft-target, attenuation or stf2020")
    if spec.model != "stf2020":
        return
    from fogsim.lidar.sensors import load_sensor
    from fogsim.lidar.stf2020 import constants

    given = run_sensor(args)
    if given is not None:
        constants(load_sensor(given).calibrated(spec.calibration))


def _check_calibration(args, spec) -> None:
    """A calibration that does not fit the run's sensor (its ranges after the calibration) is one line naming
    the calibration, before the output folder is claimed — not a failure of every scan."""
    from fogsim.errors import InputError
    from fogsim.lidar.sensors import load_sensor

    given = getattr(args, "lidar_calibration", None)
    sensor = run_sensor(args)
    if given in (None, "datasheet") or sensor is None:
        return
    loaded = load_sensor(sensor)  # checked where it was chosen
    try:
        loaded.calibrated(spec.calibration)
    except ValueError as exc:
        raise InputError(given, f"--lidar-calibration does not fit the sensor {loaded.name}: {exc}") from None


def output(args):
    """The job's :class:`~fogsim.fog.lidar_levels.LidarOutput` (None without --lidar)."""
    if not args.lidar:
        return None
    from fogsim.fog.lidar_levels import LidarOutput

    n = MIN_POINTS if args.lidar_min_points is None else args.lidar_min_points
    if n < 1:
        raise ValueError(f"--lidar-min-points must be ≥ 1, got {n}")
    return LidarOutput(sensor_choice(args.lidar_sensor), n, not args.no_kitti_trees)


def inputs(args) -> dict:
    """What the run records of the KITTI / STF inputs (only when given: older runs resume)."""
    out = {}
    if args.kitti:
        out |= {"kitti": str(Path(args.kitti).resolve()), "kitti_part": args.kitti_part}
    if args.stf:
        out |= {"stf": str(Path(args.stf).resolve()), "stf_returns": args.stf_returns}
        if args.stf_calib:
            out["stf_calib"] = str(Path(args.stf_calib).resolve())
    return out


# ----------------------------------------------------------------------------- samples
def samples(args):
    """The samples of ``--kitti`` / ``--stf`` (depth: their scans, wired by :mod:`fogsim.cli.fog`)."""
    from fogsim.readers.kitti.samples import kitti_samples, stf_samples

    labels = False if args.no_labels else None
    if args.kitti:
        return kitti_samples(args.kitti, args.split, labels, args.kitti_part)
    root = Path(args.stf)
    if args.stf_calib is None and (root / "cam_stereo_left_lut").is_dir() and not (root / "calib").is_dir():
        from fogsim.errors import InputError

        raise InputError(root, "Seeing Through Fog has no calibration in its download: pass --stf-calib FILE "
                               "(the repository's kitti_stereo_velodynehdl_calib.txt) or --stf-calib DIR (its "
                               "tools/DatasetViewer/calibs)")
    return stf_samples(root, args.split, args.stf_returns, args.stf_calib, labels)


def with_waymo_scans(samples_, args):
    """``--waymo … --lidar``: the samples of the first ``--cameras`` camera get their frame's TOP scan
    (:class:`~fogsim.readers.waymo.lidar_cloud.WaymoScan`, one scan per frame: its patchy-fog field is that
    camera's); data without any LiDAR is refused here, before the output folder is claimed."""
    from dataclasses import replace

    from fogsim.depth.lidar_source import waymo_has_lidar
    from fogsim.errors import InputError
    from fogsim.readers.base import SCAN_SOURCE
    from fogsim.readers.waymo.lidar import lidar_points_for_sample
    from fogsim.readers.waymo.lidar_cloud import WaymoScan

    camera = next(c.strip().upper() for c in args.cameras.split(",") if c.strip())
    if samples_ and not any(waymo_has_lidar(s) for s in samples_):
        raise InputError(args.waymo, f"no LiDAR in this data (none of its {len(samples_)} images' frames has "
                                     "range images), which --lidar fogs: drop --lidar")
    out = []
    for s in samples_:
        if s.meta.get("camera") == camera:
            scan = WaymoScan(lidar_points_for_sample(s), camera, s.key.rpartition("_")[0])
            s = replace(s, meta={**s.meta, SCAN_SOURCE: scan})
        out.append(s)
    return out


# ----------------------------------------------------------------------------- --points
@dataclass(frozen=True)
class PointsKind:
    """What one kind of sensor brings to ``fogsim fog --points``; the rest is :func:`cmd_points`, one path for
    every sensor. Each part is a function of the parsed flags (``args``):

    * ``check``: refuses the flags that are not this sensor's (a ValueError: exit 2);
    * ``sensor``: the sensor fogged for (a bundled name or a custom block read from its file);
    * ``fog``: the fog record (:class:`~fogsim.fog.engine.FogSettings`) with this sensor's part, from the flags;
    * ``job``: ``job(args, **fields)``, the job (a :class:`~fogsim.fog.point_files.PointFilesJob`) of the
      fields every sensor's job has (levels, out, fog, sensor, fmt, inputs) and this sensor's own;
    * ``counted``: what the outcome totals count ("points", "detections")."""

    check: Callable[[argparse.Namespace], None]
    sensor: Callable[[argparse.Namespace], str | dict]
    fog: Callable[[argparse.Namespace], object]
    job: Callable[..., object]
    counted: str


def cmd_points(args) -> int:
    """``fogsim fog --points …``: LiDAR scans (:mod:`fogsim.fog.points`) and radar sweeps
    (:mod:`fogsim.fog.radar_points`, ``--point-format nuscenes-radar``) — sensor, levels, output check, the input
    files, shard, run, failures and each level's outcome totals, with what differs taken from the sensor's
    :class:`PointsKind`."""
    from fogsim.deps import package_versions
    from fogsim.fog.batch import run
    from fogsim.fog.levels import parse_levels
    from fogsim.fog.point_files import point_files
    from fogsim.runs import check_output, parse_shard, select_shard

    fmt = args.point_format
    if not fmt:
        raise ValueError(f"--points needs --point-format ({', '.join(POINT_FORMATS)})")
    for key in OTHER_INPUTS_FLAGS:
        if getattr(args, key, None) is not None:
            raise ValueError(f"--{key.replace('_', '-')} goes with another input (--input, --kitti, --stf, --waymo, "
                             "--cityscapes), not --points")
    if args.heterogeneity:
        raise ValueError("--heterogeneity needs a camera image (its density field): --points fogs homogeneous fog")
    kind = RADAR_POINTS if fmt in RADAR_POINT_FORMATS else LIDAR_POINTS
    kind.check(args)
    sensor = kind.sensor(args)
    levels = tuple(parse_levels(args.levels, args.visibility))
    fog = kind.fog(args)
    check_output(args.out, [("--points", given) for given in args.points])
    items = point_files(args.points, fmt)
    recorded = {"points": [str(Path(p).resolve()) for p in args.points], "point_format": fmt}
    job = kind.job(args, levels=levels, out=args.out, fog=fog, sensor=sensor, fmt=fmt, inputs=recorded)
    mine = select_shard(items, parse_shard(args.shard))
    summary = run(mine, job, args.workers, not args.no_resume, not args.quiet,
                  package_versions() | {"samples": len(items)})
    for source, error in summary.failed:
        print(f"  failed: {error if error.startswith(source) else f'{source}: {error}'}", file=sys.stderr)
    _print_totals(job, mine, kind.counted, args.quiet)
    print(summary.line(job))
    return EXIT_FAILED if summary.failed else EXIT_OK


def _print_totals(job, items, what: str, quiet: bool) -> None:
    """Each level's outcome totals (:mod:`fogsim.fog.outcome_totals`), unless quiet."""
    from fogsim.fog.outcome_totals import outcome_totals, totals_lines

    if not quiet:
        print("\n".join(totals_lines(outcome_totals(job, items), what, job.unit)))


def _check_lidar_points(args) -> None:
    fmt = args.point_format
    if args.radar_temperature is not None:
        raise ValueError("--radar-temperature goes with --point-format nuscenes-radar")
    if args.point_scale and fmt not in ("ply", "npy"):
        raise ValueError(f"--point-scale is for ply and npy scans; {fmt} scans have their own scale")
    for flag in ("lidar", "no_kitti_trees", "lidar_min_points"):
        if getattr(args, flag, None):
            raise ValueError(f"--{flag.replace('_', '-')} goes with a dataset (--kitti, --stf, --waymo), not --points")


def _lidar_points_sensor(args):
    from fogsim.fog.points import DEFAULT_SENSOR

    sensor = sensor_choice(args.lidar_sensor) or DEFAULT_SENSOR.get(args.point_format)
    if sensor is None:
        raise ValueError(f"--point-format {args.point_format} has no usual sensor: give --sensor NAME|FILE")
    return sensor


def _lidar_points_fog(args):
    from fogsim.fog.engine import FogSettings

    return FogSettings(lidar=fog_spec(args))


def _lidar_points_job(args, **fields):
    from fogsim.fog.points import PointsJob

    return PointsJob(**fields, scale=args.point_scale, seed=args.seed)


def _check_radar_points(args) -> None:
    for flag in ("lidar", "no_kitti_trees", "lidar_min_points", "lidar_model", "lidar_extinction_ratio",
                 "point_scale", "lidar_calibration"):
        if getattr(args, flag, None) is not None and getattr(args, flag) is not False:
            raise ValueError(f"--{flag.replace('_', '-')} is for LiDAR scans, not --point-format {args.point_format}")


def _radar_points_sensor(args):
    from fogsim.fog.radar_points import DEFAULT_RADAR_SENSOR

    return sensor_choice(args.lidar_sensor, radar=True) or DEFAULT_RADAR_SENSOR[args.point_format]


def _radar_points_fog(args):
    from fogsim.fog.engine import FogSettings
    from fogsim.radar.fog import radar_fog_spec

    return FogSettings(radar=radar_fog_spec({} if args.radar_temperature is None
                                            else {"temperature_c": args.radar_temperature}))


def _radar_points_job(args, **fields):
    from fogsim.fog.radar_points import RadarPointsJob

    return RadarPointsJob(**fields)


LIDAR_POINTS = PointsKind(_check_lidar_points, _lidar_points_sensor, _lidar_points_fog, _lidar_points_job, "points")
RADAR_POINTS = PointsKind(_check_radar_points, _radar_points_sensor, _radar_points_fog, _radar_points_job,
                          "detections")

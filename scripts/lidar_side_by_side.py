"""fogsim's LiDAR fog models side by side — soft-target (the default), hahner2021 (Hahner et al. 2021's released
code as it fogs datasets) and stf2020 (the STF authors' chamber-fitted rule) — at β = 0.03, 0.06, 0.09, 0.12
on the CI fixture sweeps (KITTI-, nuScenes- and STF-format) or a scan of yours: prints the Markdown block of
``docs/lidar-fog.md`` (``fogsim.bench.lidar_side_by_side``), or rewrites it there.

    python scripts/lidar_side_by_side.py --docs docs                          # the fixture sweeps → docs/lidar-fog.md
    python scripts/lidar_side_by_side.py --scan 000008.bin --speed            # a KITTI velodyne scan (printed only)
    python scripts/lidar_side_by_side.py --scan s.pcd.bin --point-format nuscenes --sensor hdl32e
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one core, before numpy loads
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]



def fixture_subjects(folder: Path, calibration=None) -> list:
    """The CI fixture sweeps (tests/lidar_fixtures.py), one per format, as side-by-side subjects."""
    import lidar_fixtures as lf
    from fogsim.bench.lidar_side_by_side import Subject
    from fogsim.lidar.formats import read_points
    from fogsim.lidar.stf2020 import S2_ASSUMED

    fixture = "`tests/lidar_fixtures.py: {}` ({})"
    return [Subject("KITTI " + fixture.format("kitti_street_sweep()", "a ray-cast HDL-64E street sweep, camera view "
                                              "±40°, reflectance 0–1"), lf.kitti_street_cloud(folder), "hdl64e",
                    calibration, (None, "the HDL-64 S2's (assumed for KITTI's HDL-64E)")),
            Subject("nuScenes " + fixture.format("nuscenes_sweep()", "a full HDL-32E sweep, intensity 0–255"),
                    read_points(lf.nuscenes_sweep(folder), "nuscenes"), "hdl32e", calibration,
                    (S2_ASSUMED, "the HDL-64 S2's, assumed (none are published for the HDL-32E)")),
            Subject("STF " + fixture.format("stf_sweep()", "a full HDL-64 S3D sweep, intensity 0–255"),
                    read_points(lf.stf_sweep(folder), "stf"), "hdl64-s3d", calibration, (None, "the HDL-64 S3D's"))]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scan", type=Path, help="a scan to compare on (default: the CI fixture sweeps)")
    ap.add_argument("--point-format", default="kitti", help="the scan's format (default kitti)")
    ap.add_argument("--sensor", default="hdl64e", help="its sensor (default hdl64e)")
    ap.add_argument("--lidar-calibration", help="the default model's calibration (a name or a FILE)")
    ap.add_argument("--seed", type=int, default=0, help="the levels' seed (default 0)")
    ap.add_argument("--docs", type=Path, help="rewrite the block in DOCS/lidar-fog.md (fixture sweeps only)")
    ap.add_argument("--speed", action="store_true", help="also time the models on one core (medians of --repeat)")
    ap.add_argument("--repeat", type=int, default=7, help="interleaved repeats of --speed (default 7)")
    args = ap.parse_args(argv)
    if args.docs and (args.scan or args.lidar_calibration):
        ap.error("--docs documents the fixture sweeps with the default calibration: leave out --scan and "
                 "--lidar-calibration")
    sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # this repository's fogsim and its fixtures
    from fogsim.bench import lidar_side_by_side as sbs
    from fogsim.cli.fog_lidar import calibration_choice
    from fogsim.io.atomic import atomic_write_bytes
    from fogsim.lidar.formats import read_points

    try:
        calibration = calibration_choice(args.lidar_calibration)
        with tempfile.TemporaryDirectory() as tmp:
            if args.scan:
                from fogsim.lidar.sensors import load_sensor
                from fogsim.lidar.stf2020 import S2_ASSUMED

                stf = (None, "the sensor's") if load_sensor(args.sensor).stf_noise_level is not None else \
                    (S2_ASSUMED, "the HDL-64 S2's, assumed (none are published for this sensor)")
                subjects = [sbs.Subject(f"`{args.scan.name}`", read_points(args.scan, args.point_format), args.sensor,
                                        calibration, stf)]
            else:
                subjects = fixture_subjects(Path(tmp), calibration)
        results = [sbs.run_scan(s, seed=args.seed) for s in subjects]
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    block = sbs.markdown(results, args.seed)
    print(block, end="")
    if args.docs:
        page = args.docs / "lidar-fog.md"
        text = page.read_text(encoding="utf-8")
        try:
            new = sbs.replace_block(text, block, str(page))
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        if new != text:
            atomic_write_bytes(page, new.encode("utf-8"))
        print(f"{page}: {'rewritten' if new != text else 'already current'}")
    if args.speed:
        for s in subjects:
            med = sbs.speed(s, repeat=args.repeat)
            n = len(s.scan)
            print(f"speed, {s.label}: {n} points × {len(sbs.BETAS)} levels, one core, medians of {args.repeat}: "
                  + ", ".join(f"{m} {med[m]:.1f} ms" for m in sbs.MODELS) + "; "
                  + ", ".join(f"{m} {med[f'{m}/{sbs.MODELS[0]}']:.2f}× the default" for m in sbs.MODELS[1:]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

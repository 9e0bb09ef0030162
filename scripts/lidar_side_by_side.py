"""fogsim's LiDAR fog beside the reference simulator (Hahner et al. 2021, re-implemented from its paper in
``fogsim.lidar.hahner``) on one scan at β = 0.03, 0.06, 0.09, 0.12: prints the Markdown table of
``docs/lidar-fog.md`` (``fogsim.bench.lidar_side_by_side``), or rewrites it there.

    python scripts/lidar_side_by_side.py --docs docs                 # the CI fixture sweep → docs/lidar-fog.md
    python scripts/lidar_side_by_side.py --scan 000008.bin           # a KITTI velodyne scan (printed only)
    python scripts/lidar_side_by_side.py --lidar-calibration reference --speed
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scan", type=Path, help="a scan to compare on (default: the CI fixture sweep)")
    ap.add_argument("--point-format", default="kitti", help="the scan's format (default kitti)")
    ap.add_argument("--sensor", default="hdl64e", help="fogsim's sensor (default hdl64e)")
    ap.add_argument("--lidar-calibration", help="fogsim's calibration (reference|datasheet|FILE), where the model "
                                                "offers the choice")
    ap.add_argument("--seed", type=int, default=0, help="range-noise seed (default 0)")
    ap.add_argument("--docs", type=Path, help="rewrite the table block in DOCS/lidar-fog.md (fixture only)")
    ap.add_argument("--speed", action="store_true", help="also time both on one core (medians of --repeat)")
    ap.add_argument("--repeat", type=int, default=7, help="interleaved repeats of --speed (default 7)")
    args = ap.parse_args(argv)
    if args.docs and args.scan:
        ap.error("--docs documents the fixture sweep: leave out --scan")
    sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # this repository's fogsim and its fixtures
    import lidar_fixtures as lf
    from fogsim.bench import lidar_side_by_side as sbs
    from fogsim.fileio import atomic_write_bytes
    from fogsim.lidar.formats import read_points

    with tempfile.TemporaryDirectory() as tmp:
        if args.scan:
            scan, label = read_points(args.scan, args.point_format), f"`{args.scan.name}`"
        else:
            scan, label = lf.kitti_street_cloud(Path(tmp)), lf.SWEEP_LABEL
    try:
        result = sbs.side_by_side(scan, args.sensor, seed=args.seed, calibration=args.lidar_calibration, label=label)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    block = sbs.markdown(result)
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
        med = sbs.speed(scan, args.sensor, repeat=args.repeat, calibration=args.lidar_calibration)
        n = len(scan)
        print(f"speed, {n} points × {len(sbs.BETAS)} levels, one core, medians of {args.repeat}: fogsim "
              f"{med['fogsim']:.1f} ms ({4 * n / med['fogsim'] / 1e3:.2f} M points/s), reference re-implementation "
              f"{med['reference']:.1f} ms ({4 * n / med['reference'] / 1e3:.2f} M points/s): {med['ratio']:.1f}×")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

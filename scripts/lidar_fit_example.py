"""The worked example of docs/lidar-fit.md: nuScenes-format fixture sweeps (``tests/lidar_fixtures.py:
nuscenes_sweep``, an HDL-32E street) as the clear scans, other streets fogged with a hidden calibration as the
"real" foggy scans, then ``fogsim lidar-compare`` (the datasheet), ``fogsim lidar-fit`` with the visibility given
and ``fogsim lidar-fit`` with it unknown.

    python scripts/lidar_fit_example.py OUT [--docs docs]   # OUT/{clear,foggy,compare,fit,fit-vis}; pictures → docs/
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: the "real" fog: other streets, fogged at visibility 150 m by this calibration of the hdl32e (hidden from the fit)
HIDDEN = {"name": "hidden", "fog_echo_scale": 0.05, "pulse_half_power_ns": 14.0, "max_range_m": 110.0,
          "fluctuation_sigma": 0.8}
HIDDEN["sources"] = dict.fromkeys([k for k in HIDDEN if k != "name"], "assumed: the worked example's hidden fog")
VISIBILITY_M = 150.0
CLEAR_SEEDS, FOGGY_SEEDS = (0, 1, 2, 3), (10, 11, 12, 13)


def build(out: Path) -> None:
    sys.path.insert(0, str(ROOT / "tests"))
    import lidar_fixtures as lf
    from fogsim.lidar.fog import LidarFogger
    from fogsim.lidar.formats import read_points
    from fogsim.lidar.rays import empty_rays
    from fogsim.lidar.sensors import load_sensor

    sensor = load_sensor("hdl32e")
    for kind, seeds in (("clear", CLEAR_SEEDS), ("foggy", FOGGY_SEEDS)):
        (out / kind).mkdir(parents=True, exist_ok=True)
        for seed in seeds:
            work = out / "work" / str(seed)
            work.mkdir(parents=True, exist_ok=True)
            scan = read_points(lf.nuscenes_sweep(work, seed), "nuscenes")
            if kind == "foggy":
                fogger = LidarFogger(scan, sensor, {"calibration": HIDDEN}, empty_rays(scan, sensor))
                scan = fogger(np.log(20) / VISIBILITY_M, np.random.default_rng(1000 + seed)).cloud
            (out / kind / f"sweep{seed:02d}.pcd.bin").write_bytes(lf.stf_bin(scan.xyz, scan.raw_intensity, scan.ring))
        shutil.rmtree(out / "work")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--docs", type=Path, help="copy the fit's pictures here (lidar_fit_histograms.png, "
                                              "lidar_fit_distance.png)")
    ap.add_argument("--evaluations", type=int, default=200)
    args = ap.parse_args()
    from fogsim.cli import main as fogsim

    build(args.out)
    common = ["--clear", str(args.out / "clear"), "--foggy", str(args.out / "foggy"), "--point-format", "nuscenes"]
    vis = ["--visibility", f"{VISIBILITY_M:g}"]
    for argv in (["lidar-compare", *common, *vis, "--out", str(args.out / "compare")],
                 ["lidar-fit", *common, *vis, "--evaluations", str(args.evaluations), "--out", str(args.out / "fit")],
                 ["lidar-fit", *common, "--evaluations", str(args.evaluations), "--out", str(args.out / "fit-vis")]):
        print("$ fogsim " + " ".join(argv), flush=True)
        if code := fogsim(argv):
            return code
    if args.docs:
        shutil.copyfile(args.out / "fit" / "histograms.png", args.docs / "lidar_fit_histograms.png")
        shutil.copyfile(args.out / "fit" / "distance.png", args.docs / "lidar_fit_distance.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

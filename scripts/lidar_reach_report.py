"""Points per object against distance in a default clear render, beside real KITTI's cars.

Renders the default preset with ``--lidar hdl64e`` (clear air only; the camera small: the LiDAR does not
depend on it), or reads a render you made, and prints per class and distance bin the median points per
object and, for cars, the shares below, inside and above the KITTI car band (:mod:`fogsim.lidar.reach`);
``--docs DIR`` writes the picture ``DIR/render_lidar_reach.png``.

    python scripts/lidar_reach_report.py --frames 12 --docs docs
    python scripts/lidar_reach_report.py --render OUT             # an existing render with a LiDAR
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--render", type=Path, help="a render with a LiDAR (default: render one here)")
    ap.add_argument("--frames", type=int, default=12, help="frames to render (default 12)")
    ap.add_argument("--lidar", default="hdl64e", help="the LiDAR of the render made here (default hdl64e)")
    ap.add_argument("--docs", type=Path, help="write render_lidar_reach.png here")
    args = ap.parse_args()
    from fogsim.cli import main as fogsim
    from fogsim.lidar.pictures import write_png
    from fogsim.lidar.reach import KITTI_CAR_BAND, object_points_by_distance, reach_picture, reach_table

    with tempfile.TemporaryDirectory() as tmp:
        root = args.render
        if root is None:
            root = Path(tmp) / "render"
            code = fogsim(["render", "--preset", "default", "--frames", str(args.frames), "--lidar", args.lidar,
                           "--resolution", "96x64", "--samples", "1", "--levels", "clear", "--quiet",
                           "--out", str(root)])
            if code:
                return code
        rows = object_points_by_distance(root)
        frames = len(list(Path(root, "meta").glob("*.json")))
        print(f"{len(rows)} objects in {frames} frames of {root}; KITTI car band n·R² = "
              f"{KITTI_CAR_BAND[0]:,.0f}–{KITTI_CAR_BAND[1]:,.0f}\n")
        print("| class | distance | objects | median points | cars below / inside / above the KITTI band |")
        print("|---|---|---|---|---|")
        for row in reach_table(rows):
            lo, hi = row["bin"]
            band = (f"{100 * row['below']:.0f} % / {100 * row['inside']:.0f} % / {100 * row['above']:.0f} % "
                    f"(band {row['band_at_median'][0]:.0f}–{row['band_at_median'][1]:.0f})" if "below" in row else "")
            print(f"| {row['class']} | {lo:g}–{hi:g} m | {row['objects']} | {row['median_points']:.0f} | {band} |")
        if args.docs:
            write_png(args.docs / "render_lidar_reach.png",
                      reach_picture(rows, caption=f"default preset, {args.lidar}, {frames} frames"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

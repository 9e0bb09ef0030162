"""The docs' cross-sensor table and LiDAR pictures from a fixture run: a ray-cast KITTI street
(``tests/kitti_tree.py``: six frames, four cars each at 6–75 m, dark and bright) fogged with
``fogsim fog --kitti ROOT --lidar --levels paper``; prints ``cross_sensor.md`` and copies the pictures.

    python scripts/lidar_fixture_report.py --docs docs  # docs/lidar_kitti_bev.png, lidar_points_vs_distance.png
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--docs", type=Path, help="copy the pictures here (default: only print the table)")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "tests"))
    import kitti_tree as kt
    from fogsim.cli import main as fogsim

    with tempfile.TemporaryDirectory() as tmp:
        tree = kt.write_kitti_street(Path(tmp) / "kitti", kt.STREET)
        out = Path(tmp) / "out"
        code = fogsim(["fog", "--kitti", str(tree), "--lidar", "--levels", "paper", "--quiet", "--out", str(out)])
        if code:
            return code
        print((out / "cross_sensor.md").read_text())
        if args.docs:
            shutil.copyfile(out / "lidar_bev.png", args.docs / "lidar_kitti_bev.png")
            shutil.copyfile(out / "lidar_points_vs_distance.png", args.docs / "lidar_points_vs_distance.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""``fogsim export``: a finished dataset's files in another community's layout (``export nuscenes``:
:mod:`fogsim.dataset.nuscenes`).

Why a command and not a ``--nuscenes`` flag on ``render`` and ``fog``: the export reads only what a finished
dataset already holds (each level's scan and its frame record), so one command serves renders and fogged
KITTI / STF / Waymo runs alike, runs on datasets made before it existed, and costs no re-render; the
producing commands keep their flags.
"""
from __future__ import annotations

from fogsim.errors import EXIT_OK


def add_parsers(sub) -> None:
    p = sub.add_parser("export", help="write a fogsim dataset's files in another dataset's layout (nuscenes)")
    targets = p.add_subparsers(dest="target", required=True, metavar="TARGET")
    n = targets.add_parser("nuscenes", help="each fog level's LiDAR scans as nuScenes samples/LIDAR_TOP/*.pcd.bin "
                                            "(5 float32: x y z intensity 0-255 ring) and radar sweeps as "
                                            "samples/RADAR_*/*.pcd, one data root per level")
    n.add_argument("dataset", help="a fogsim dataset with LiDAR levels (render --lidar, or fog … --lidar)")
    n.add_argument("--out", required=True, help="output folder: OUT/<level>/samples/LIDAR_TOP/<frame>.pcd.bin "
                                                "and OUT/fogsim_nuscenes.json")
    n.add_argument("--levels", help="comma-separated level keys to export (default: every level)")
    n.add_argument("--quiet", action="store_true", help="print nothing (errors only)")
    n.set_defaults(run=cmd_nuscenes)


def cmd_nuscenes(args) -> int:
    from fogsim.dataset.nuscenes import export_nuscenes

    levels = None if args.levels is None else [k.strip() for k in args.levels.split(",") if k.strip()]
    summary = export_nuscenes(args.dataset, args.out, levels)
    if not args.quiet:
        print(f"exported {channels_line(summary)} samples → {args.out}; nuScenes' JSON tables are not written "
              "(see fogsim_nuscenes.json)")
    return EXIT_OK


def channels_line(summary: dict) -> str:
    """Every channel the export wrote with its samples per level: ``LIDAR_TOP (clear 2, beta0.06 2) and
    RADAR_FRONT (clear 2, beta0.06 2)``."""
    from fogsim.dataset.nuscenes import CHANNEL

    per_channel = {CHANNEL: summary["samples_per_level"]} if summary["samples_per_level"] else {}
    radar = summary.get("radar")
    if isinstance(radar, dict):
        per_channel |= radar["samples_per_channel_and_level"]
    parts = [f"{channel} ({', '.join(f'{k} {n}' for k, n in levels.items())})"
             for channel, levels in per_channel.items()]
    return ", ".join(parts[:-1]) + (" and " if len(parts) > 1 else "") + parts[-1]

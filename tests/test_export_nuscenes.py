"""``fogsim export nuscenes`` (fogsim.dataset.nuscenes, issue 40 item 7): each level's scans as nuScenes
``samples/LIDAR_TOP/*.pcd.bin``, read back with a reader written here from nuScenes' documented record
(5 little-endian float32 per point: x, y, z, intensity 0–255, ring — what the devkit's
``LidarPointCloud.from_file`` reshapes to (-1, 5)) and compared with the level's scan.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import kitti_tree as kt
from fogsim.cli import main
from fogsim.dataset.nuscenes import TABLES_NOT_WRITTEN
from fogsim.lidar.sensors import LidarSensor


def read_pcd_bin(path: Path) -> np.ndarray:
    """nuScenes' LIDAR_TOP record, from its spec: float32 × 5 little-endian per point."""
    data = path.read_bytes()
    assert len(data) % 20 == 0
    return np.frombuffer(data, "<f4").reshape(-1, 5)


def test_a_fogged_kitti_set_exports_as_nuscenes_samples(tmp_path, capsys):
    """Every level of a fogged KITTI frame: x y z bit for bit, intensity 255 × KITTI's reflectance, the ring
    the HDL-64E beam nearest each point's elevation (KITTI stores none); the JSON tables listed as not
    written; the dataset untouched."""
    from conftest import tree_digest

    root = kt.write_kitti(tmp_path / "in" / "kitti", {"000000": kt.CARS["000000"], "000001": kt.CARS["000001"]})
    ds = tmp_path / "ds"
    assert main(["fog", "--quiet", "--kitti", str(root), "--lidar", "--levels", "0,0.06", "--out", str(ds)]) == 0
    before = tree_digest(ds)
    nusc = tmp_path / "nusc"
    assert main(["export", "nuscenes", str(ds), "--out", str(nusc)]) == 0
    said = capsys.readouterr().out
    assert "\nexported LIDAR_TOP (" in said and "RADAR" not in said  # the channels written, no other
    assert tree_digest(ds) == before
    incl = np.radians(np.asarray(LidarSensor.preset("hdl64e").inclinations_deg))
    h = np.asarray(LidarSensor.preset("hdl64e").vertical_offsets_m)
    metas = [json.loads(p.read_text()) for p in sorted((ds / "meta").glob("*.json"))]
    assert len(metas) == 2
    for meta in metas:
        for level, entry in meta["lidar"]["levels"].items():
            got = read_pcd_bin(nusc / level / "samples" / "LIDAR_TOP" / f"{meta['frame']}.pcd.bin")
            scan = np.frombuffer((ds / entry["file"]).read_bytes(), "<f4").reshape(-1, 4)  # KITTI's spec
            assert len(got) == len(scan) > 100
            np.testing.assert_array_equal(got[:, :3], scan[:, :3])
            np.testing.assert_allclose(got[:, 3], 255.0 * scan[:, 3], rtol=1e-6)
            assert (got[:, 4] == np.round(got[:, 4])).all()
            # the ring: the laser whose line passes nearest (its vertical offset h: |z cos θ − ρ sin θ − h|)
            z, rho = scan[:, 2].astype(np.float64), np.hypot(scan[:, 0], scan[:, 1]).astype(np.float64)
            off = np.abs(z[:, None] * np.cos(incl) - rho[:, None] * np.sin(incl) - h)
            np.testing.assert_allclose(off[np.arange(len(scan)), got[:, 4].astype(int)], off.min(1), atol=1e-12)
    summary = json.loads((nusc / "fogsim_nuscenes.json").read_text())
    assert summary["tables_not_written"] == list(TABLES_NOT_WRITTEN) and len(TABLES_NOT_WRITTEN) == 13
    assert summary["samples_per_level"] == {"clear": 2, "beta0.06": 2}
    # --levels picks levels; an unknown one, the dataset itself as OUT, a dataset without LiDAR: exit 2
    assert main(["export", "nuscenes", str(ds), "--out", str(tmp_path / "one"), "--levels", "beta0.06",
                 "--quiet"]) == 0
    assert [p.name for p in (tmp_path / "one").iterdir() if p.is_dir()] == ["beta0.06"]
    assert main(["export", "nuscenes", str(ds), "--out", str(tmp_path / "x"), "--levels", "beta9", "--quiet"]) == 2
    assert main(["export", "nuscenes", str(ds), "--out", str(ds), "--quiet"]) == 2
    plain = tmp_path / "plain"
    assert main(["fog", "--quiet", "--kitti", str(root), "--levels", "0", "--out", str(plain)]) == 0
    assert main(["export", "nuscenes", str(plain), "--out", str(tmp_path / "y"), "--quiet"]) == 2
    assert "no frame has per-level LiDAR scans" in capsys.readouterr().err


def test_a_scan_with_rings_keeps_them(tmp_path):
    """A render-like record whose scan is nuScenes' own format (rings stored): exported bit for bit."""
    from fogsim.dataset.nuscenes import export_nuscenes

    ds = tmp_path / "ds"
    (ds / "meta").mkdir(parents=True)
    (ds / "lidar" / "clear").mkdir(parents=True)
    rng = np.random.default_rng(0)
    rec = np.zeros((50, 5), "<f4")
    rec[:, :3] = rng.uniform(-20, 20, (50, 3))
    rec[:, 3] = rng.integers(0, 256, 50)
    rec[:, 4] = rng.integers(0, 32, 50)
    (ds / "lidar" / "clear" / "f.pcd.bin").write_bytes(rec.tobytes())
    meta = {"frame": "f", "width": 8, "height": 8, "objects": [],
            "lidar": {"format": "nuscenes", "sensor": {"inclinations_deg": None},
                      "levels": {"clear": {"file": "lidar/clear/f.pcd.bin"}}}}
    (ds / "meta" / "f.json").write_text(json.dumps(meta))
    export_nuscenes(ds, tmp_path / "nusc")
    out = tmp_path / "nusc" / "clear" / "samples" / "LIDAR_TOP" / "f.pcd.bin"
    assert out.read_bytes() == rec.tobytes()
    np.testing.assert_array_equal(read_pcd_bin(out), rec)

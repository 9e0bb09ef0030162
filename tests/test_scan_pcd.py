"""Each fog level's ``.pcd`` beside its scan (fogsim.lidar.scan_pcd, issue 40 item 1), read back with the
tools people open point clouds with — open3d (``o3d.t.io`` keeps the extra fields, ``o3d.io`` the xyz) and
pypcd4 — and compared with the level's scan and outcome files that fogsim wrote beside it.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import kitti_tree as kt
import lidar_fixtures as lf
from fogsim.cli import main
from fogsim.lidar.fog import CLUTTER, LOST, LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.lidar.points import PointCloud
from fogsim.lidar.scan_pcd import reported_outcomes, scan_records, write_level_pcd


def viewer_fields(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """Every field of a PCD file as open3d's tensor reader and pypcd4 give it, and open3d's legacy xyz."""
    o3d = pytest.importorskip("open3d")
    pypcd4 = pytest.importorskip("pypcd4")
    t = o3d.t.io.read_point_cloud(str(path))
    from_o3d = {"xyz": t.point.positions.numpy()}
    for name in ("intensity", "ring", "label", "instance", "outcome"):
        if name in t.point:
            from_o3d[name] = t.point[name].numpy().reshape(-1)
    legacy = {"xyz": np.asarray(o3d.io.read_point_cloud(str(path)).points)}
    pc = pypcd4.PointCloud.from_path(path)
    table = pc.numpy()
    from_pypcd = {"xyz": table[:, :3]}
    for k, name in enumerate(pc.fields):
        if name not in "xyz":
            from_pypcd[name] = table[:, k]
    return {"open3d": from_o3d, "open3d-legacy": legacy, "pypcd4": from_pypcd}


def check_pcd(path: Path, cloud: PointCloud, outcome: np.ndarray, labels: np.ndarray | None = None,
              ring: np.ndarray | None = None) -> None:
    """The PCD at ``path`` holds ``cloud`` (xyz, raw intensity, ring where it has one — or ``ring``, where
    the scan file has none but the producer knew it), one outcome per reported point and, given
    ``labels``, their lower / upper 16 bits as label / instance — by every reader."""
    ring = cloud.ring if ring is None else ring
    for reader, f in viewer_fields(path).items():
        np.testing.assert_allclose(f["xyz"], cloud.xyz, rtol=0, atol=0, err_msg=reader)
        if reader == "open3d-legacy":
            continue
        np.testing.assert_array_equal(f["intensity"], cloud.raw_intensity, err_msg=reader)
        assert ("ring" in f) == (ring is not None), reader
        if ring is not None:
            np.testing.assert_array_equal(f["ring"], ring, err_msg=reader)
        np.testing.assert_array_equal(f["outcome"], outcome, err_msg=reader)
        assert ("label" in f) == (labels is not None), reader
        if labels is not None:
            np.testing.assert_array_equal(f["label"], labels % 65536, err_msg=reader)
            np.testing.assert_array_equal(f["instance"], labels // 65536, err_msg=reader)


def by_row(outcome: np.ndarray, index: np.ndarray) -> np.ndarray:
    """The outcome of each fogged-scan row from the outcome file's per-input-point columns."""
    out = np.full(int(index.max(initial=-1)) + 1, -1)
    out[index[index >= 0]] = outcome[index >= 0]
    return out


def test_a_fogged_level_with_labels_reads_back_in_every_viewer(tmp_path):
    """A scan with rings fogged at β = 0.06: the PCD holds the reported points, their outcomes (clutter
    included, never lost) and the labels split into SemanticKITTI's two halves."""
    xyz, rho, _, _ = lf.surfaces_scan([lf.Surface(30.0, 0.5, 200), lf.Surface(70.0, 0.1, 200)])
    cloud = PointCloud.from_raw(xyz, 255 * rho / lf.REFLECTIVITY_PER_INTENSITY, "0-255", "fixture",
                                ring=np.arange(len(xyz)) % 32)
    fogged = LidarFogger(cloud, "hdl32e")(0.06, np.random.default_rng(1))
    out = reported_outcomes(fogged)
    assert (out != LOST).all() and len(out) == len(fogged.cloud)
    np.testing.assert_array_equal(out, by_row(fogged.outcome, fogged.output_index))
    labels = (np.arange(len(fogged.cloud), dtype=np.uint32) % 7 << 16) | np.uint32(10)
    labels[out == CLUTTER] = 110
    write_level_pcd(tmp_path / "a.pcd", fogged, labels)
    check_pcd(tmp_path / "a.pcd", fogged.cloud, out, labels)
    assert (tmp_path / "a.pcd").read_bytes().startswith(b"# .PCD v0.7")
    assert b"DATA binary\n" in (tmp_path / "a.pcd").read_bytes()[:2000]
    with pytest.raises(ValueError, match="labels for"):
        scan_records(fogged.cloud, labels[:-1])


def test_fog_kitti_lidar_writes_a_pcd_per_level(tmp_path):
    """``fogsim fog --kitti … --lidar``: every level's .pcd (KITTI: no ring) is its scan with its outcomes."""
    root = kt.write_kitti(tmp_path / "in" / "kitti", {"000000": kt.CARS["000000"]})
    out = tmp_path / "out"
    assert main(["fog", "--quiet", "--kitti", str(root), "--lidar", "--levels", "0,0.06", "--out", str(out)]) == 0
    meta = json.loads(next((out / "meta").glob("*.json")).read_text())
    levels = meta["lidar"]["levels"]
    assert set(levels) == {"clear", "beta0.06"}
    for entry in levels.values():
        cloud = read_points(out / entry["file"], "kitti")
        outcome, index = read_outcomes(out / entry["outcome_file"])
        assert entry["pcd"].endswith(".pcd")
        check_pcd(out / entry["pcd"], cloud, by_row(outcome, index))


def test_fog_points_writes_a_pcd_beside_each_scan(tmp_path):
    """``fogsim fog --points`` (nuScenes sweeps, with rings): a .pcd beside each level's scan."""
    xyz, rho, _, _ = lf.surfaces_scan([lf.Surface(25.0, 0.4, 150), lf.Surface(4.0, 0.9, 40)])
    ring = (np.arange(len(xyz)) % 32).astype(np.float32)
    scan = tmp_path / "in" / "n015__LIDAR_TOP__1.pcd.bin"
    scan.parent.mkdir(parents=True)
    scan.write_bytes(lf.stf_bin(xyz, (255 * rho / lf.REFLECTIVITY_PER_INTENSITY).astype(np.float32), ring))
    out = tmp_path / "out"
    assert main(["fog", "--quiet", "--points", str(scan.parent), "--point-format", "nuscenes", "--levels", "0,0.09",
                 "--out", str(out)]) == 0
    for level in ("clear", "beta0.09"):
        side = json.loads((out / level / "n015__LIDAR_TOP__1.json").read_text())
        cloud = read_points(out / level / side["scan"], "nuscenes")
        outcome, index = read_outcomes(out / level / "n015__LIDAR_TOP__1.outcomes.npz")  # sidecar "outcomes": counts
        check_pcd(out / level / side["pcd"], cloud, by_row(outcome, index))

"""The LiDAR fog's level runs over blocks of input points (``fogsim.lidar.soft_target_model.BLOCK``) and reuses
its fogger's buffers from level to level: neither may show in what it returns. The block size changes no output
bit (a scan with lost points, no-return rows, the fog echo on the lasers' lines, empty rays, a per-point β), and a
level's result is neither changed by the next level nor different when the same level is fogged again."""
from __future__ import annotations

import numpy as np
import pytest

import lidar_fixtures as lf
from fogsim.lidar import soft_target_model as model
from fogsim.lidar.fog import CLUTTER, LOST, NO_RETURN, LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.rays import CameraView, empty_rays
from fogsim.lidar.sensors import LidarSensor


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    """(scan, sensor, empty rays) of a nuScenes sweep that stores every firing and a KITTI frame cropped to the
    camera (KITTI's lasers, off the axis), each longer than a block."""
    folder = tmp_path_factory.mktemp("blocks")
    firings = read_points(lf.nuscenes_firings(folder)[0], "nuscenes")
    frame = read_points(lf.kitti_laser_frame(folder)[0], "kitti")
    hdl64 = LidarSensor.preset("hdl64e")
    view = CameraView(lf.kitti_projection(), *lf.KITTI_IMAGE)
    return {"firings": (firings, LidarSensor.preset("hdl32e"), None),
            "kitti_frame": (frame, hdl64, empty_rays(frame, hdl64, view))}


def arrays(out):
    """Every array a level returns, and its record."""
    c = out.cloud
    return [c.xyz, c.intensity, c.raw_intensity, c.index, c.ring, c.return_index, out.outcome, out.output_index,
            out.record()]


def same(a, b):
    return all(x == y if isinstance(x, dict) else (x is None and y is None) or
               (x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()) for x, y in zip(a, b))


def levels(scan, sensor, rays, spec, beta):
    fogger = LidarFogger(scan, sensor, spec, rays)
    return [arrays(fogger(b, np.random.default_rng(k))) for k, b in enumerate(beta)]


@pytest.mark.parametrize("name", ["firings", "kitti_frame"])
@pytest.mark.parametrize("spec", [None, {"model": "attenuation"}, {"return_mode": "last"}])
def test_the_block_size_changes_no_output_bit(scans, name, spec, monkeypatch):
    scan, sensor, rays = scans[name]
    n = len(scan)
    assert n > model.BLOCK  # several blocks (and more with the smaller ones below)
    patchy = np.random.default_rng(3).uniform(0.02, 0.3, n)  # a per-point β
    beta = (0.03, 0.12, 0.3, patchy)
    base = levels(scan, sensor, rays, spec, beta)
    outcome = np.concatenate([b[6] for b in base])
    attenuation = spec == {"model": "attenuation"}  # (lost points: rows that end the arrays early, or placeholders)
    assert (outcome == LOST).sum() > (100 if attenuation else 0) and (attenuation or (outcome == CLUTTER).sum() > 100)
    assert name != "firings" or (outcome == NO_RETURN).sum() > 100
    for block in (1000, 4097, n + 1):
        monkeypatch.setattr(model, "BLOCK", block)
        assert all(same(a, b) for a, b in zip(levels(scan, sensor, rays, spec, beta), base)), block


def test_a_level_is_not_changed_by_the_next_nor_by_fogging_it_again(scans):
    scan, sensor, rays = scans["kitti_frame"]
    fogger = LidarFogger(scan, sensor, None, rays)
    first = fogger(0.06, np.random.default_rng(1))
    kept = [a.copy() if isinstance(a, np.ndarray) else a for a in arrays(first)]
    fogger(0.12, np.random.default_rng(2))
    again = fogger(0.06, np.random.default_rng(1))
    assert same(arrays(first), kept) and same(arrays(again), kept)
    assert not np.shares_memory(first.cloud.xyz, again.cloud.xyz)

"""LiDAR depth: completion, the sky rule, hold-out, scoring, and their command lines."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fogsim.bench.lidar import synthetic_scan
from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.depth.complete import complete, holdout_split, sky_mask, sparse_image
from fogsim.depth.lidar_source import LidarDepth, parse_lidar, read_holdout, write_holdout
from fogsim.depth.score import BINS, binned_metrics, pool
from fogsim.errors import InputError
from fogsim.io.depth_files import read_depth_file, write_depth
from fogsim.io.documents import write_json
from fogsim.io.images import read_image

W, H = 320, 240
K = Intrinsics(300.0, 300.0, 159.5, 119.5, W, H)
CAM_HEIGHT = 1.5


def _ground_ray() -> np.ndarray:
    """Ray distance to a flat road 1.5 m below the camera (inf above the horizon)."""
    v = np.arange(H, dtype=np.float64)[:, None] - K.cy
    z = np.where(v > 0.5, K.fy * CAM_HEIGHT / np.maximum(v, 1e-9), np.inf) * np.ones((1, W))
    return planar_to_ray(z.astype(np.float32), K)


def _scan(ray, seed=0):
    """Beam rows from row 130 every 4 px down to the bottom, a return every 2 px."""
    return synthetic_scan(ray, np.random.default_rng(seed), rows=28, top_row=130.0, row_step=4.0, col_step=2.0,
                          keep=0.9, max_range=1e9)


# ----------------------------------------------------------------------------- completion
def test_sparse_image_uses_pixel_edges_and_min_pools():
    """uv in pixel-edge coordinates (Waymo's: 0 = left edge of the first pixel): pixel = floor(uv)."""
    uv = np.array([[2.4, 1.0], [2.6, 1.0], [2.55, 0.6], [-0.6, 0.0], [9.5, 0.0], [1.0, 1.0], [10.0, 1.0]])
    ray = np.array([5.0, 7.0, 3.0, 1.0, 1.0, 0.0, 2.0], np.float32)
    sparse = sparse_image(uv, ray, 10, 3)
    expected = np.zeros((3, 10), np.float32)
    expected[1, 2] = 5.0  # u = 2.4 and 2.6 both land in column 2: the nearer wins
    expected[0, 2] = 3.0  # v = 0.6 is row 0
    expected[0, 9] = 1.0  # u = 9.5 is inside the last column
    assert np.array_equal(sparse, expected)  # u = −0.6 and u = 10.0 (the right edge) outside; ray 0 dropped


@pytest.mark.parametrize("method, mean_tol, p99_tol", [("ipbasic", 0.012, 0.03), ("linear", 0.004, 0.012)])
def test_completion_recovers_the_plane(method, mean_tol, p99_tol):
    truth = _ground_ray()
    uv, ray = _scan(truth)
    done = complete(sparse_image(uv, ray, W, H), method)
    # the beams' rows, away from the horizon (where 1/ℓ changes > 25 % per beam)
    band = np.abs(done.ray[150:] - truth[150:]) / truth[150:]
    assert band.mean() < mean_tol and np.percentile(band, 99) < p99_tol, (band.mean(), np.percentile(band, 99))
    # the returns themselves are kept exactly
    sparse = sparse_image(uv, ray, W, H)
    assert np.array_equal(done.ray[sparse > 0], sparse[sparse > 0])
    rec = done.record
    assert rec["method"] == method and rec["points"] == int((sparse > 0).sum())
    assert rec["coverage"] == pytest.approx(rec["points"] / (W * H), abs=1e-6) and rec["seconds"] >= 0


def test_linear_is_exact_on_a_plane_without_jitter():
    truth = _ground_ray()
    uv = np.array([(u, v) for v in range(140, H, 5) for u in range(0, W, 3)], np.float64)
    ray = truth[uv[:, 1].astype(int), uv[:, 0].astype(int)]
    done = complete(sparse_image(uv, ray, W, H), "linear")
    # inverse distance of a plane is linear in the row along a column: interpolation is exact
    # wherever a column has returns above and below (columns u % 3 == 0); elsewhere the row
    # spread copies the neighbour column's value (a ray-factor difference below 1 %)
    on = np.zeros((H, W), bool)
    on[140:236, ::3] = True
    assert np.abs(done.ray[on] / truth[on] - 1).max() < 1e-3
    assert np.abs(done.ray[140:236] / truth[140:236] - 1).max() < 0.01


def test_sky_rule_sets_inf_above_coverage_only():
    truth = _ground_ray()
    uv, ray = _scan(truth)
    sparse = sparse_image(uv, ray, W, H)
    done = complete(sparse, "ipbasic", sky="above", gap_px=24)
    top = int(np.floor(uv[:, 1].min() + 0.5))  # the highest row with a return (≈ 129)
    assert np.isinf(done.ray[: top - 25]).all()           # above coverage and > 24 px from any point
    assert np.isfinite(done.ray[top:]).all()              # inside the envelope every hole is filled
    assert np.isfinite(done.ray[top - 20: top]).all()     # just above (≤ 24 px from a point): extended
    assert done.record["sky_fraction"] == pytest.approx(float(np.isinf(done.ray).mean()))
    # a hole inside the coverage (a dark car without returns) is filled, never sky
    holed = sparse.copy()
    holed[170:230, 100:200] = 0
    assert np.isfinite(complete(holed, "ipbasic").ray[150:]).all()
    assert not sky_mask(holed > 0)[150:].any()
    # "extend": no sky at all; each column's top value copied to row 0
    ext = complete(sparse, "ipbasic", sky="extend")
    assert np.isfinite(ext.ray).all() and ext.record["sky_fraction"] == 0
    col = 40
    assert np.all(ext.ray[:top - 5, col] == ext.ray[0, col])
    lin = complete(sparse, "linear", sky="above")
    assert np.isinf(lin.ray[: top - 25]).all() and np.isfinite(lin.ray[top:]).all()


def test_completion_refuses_no_points_and_unknown_names():
    with pytest.raises(ValueError, match="no LiDAR point"):
        complete(np.zeros((4, 5), np.float32))
    with pytest.raises(ValueError, match="unknown LiDAR completion method 'magic'"):
        complete(np.ones((4, 5), np.float32), "magic")
    with pytest.raises(ValueError, match="unknown sky rule"):
        complete(np.ones((4, 5), np.float32), sky="blue")


# ----------------------------------------------------------------------------- hold-out
def test_holdout_split_is_deterministic_and_disjoint():
    used, held = holdout_split(1000, 0.1, seed=7)
    assert len(held) == 100 and len(used) == 900
    assert np.intersect1d(used, held).size == 0
    assert np.array_equal(np.sort(np.concatenate([used, held])), np.arange(1000))
    again_used, again_held = holdout_split(1000, 0.1, seed=7)
    assert np.array_equal(held, again_held) and np.array_equal(used, again_used)
    assert not np.array_equal(held, holdout_split(1000, 0.1, seed=8)[1])
    u0, h0 = holdout_split(50, 0.0, seed=1)
    assert len(h0) == 0 and np.array_equal(u0, np.arange(50))
    for bad in (1.0, -0.1):
        with pytest.raises(ValueError, match=r"\[0, 1\)"):
            holdout_split(10, bad)


def test_lidar_depth_holds_out_writes_and_records(tmp_path):
    truth = _ground_ray()
    uv, ray = _scan(truth)
    image = np.zeros((H, W, 3), np.uint8)
    hold, comp = tmp_path / "h" / "k.npz", tmp_path / "d" / "k.exr"
    reader = LidarDepth(lambda: (uv, ray), K, "linear", 0.1, 3, str(hold), str(comp), source="frame 1")
    assert reader.name == "lidar:linear"
    dense, intrinsics, rec = reader.read_with_record(image)
    assert intrinsics is None
    used, held = holdout_split(len(ray), 0.1, 3)
    assert rec["points_held_out"] == len(held) and rec["points_used"] == len(used)
    assert rec["holdout_file"] == str(hold) and rec["completion_file"] == str(comp)
    # the completion is the one made from the used points only
    expected = complete(sparse_image(uv[used], ray[used], W, H), "linear").ray
    assert np.array_equal(dense, expected)
    assert np.array_equal(read_depth_file(comp), expected)
    got = read_holdout(hold)
    assert np.allclose(got.uv, uv[held], atol=1e-4) and np.array_equal(got.ray, ray[held])
    assert (got.width, got.height) == (W, H) and got.camera == K
    # the DepthSpec path: the record reaches sample_distance's record
    from fogsim.fog.depth_input import sample_distance
    from fogsim.readers.base import DepthSpec, Sample

    sample = Sample("k", "frame 1", lambda: image, DepthSpec("frame 1 (LiDAR)", kind="ray", reader=reader))
    dist = sample_distance(sample, W, H, "none", image)
    assert dist.record["encoding"] == "lidar:linear" and dist.record["depth_record"]["points_held_out"] == len(held)
    assert np.array_equal(dist.ray, expected)


def _grid_points(distance: float):
    uv = np.array([(u, v) for v in range(130, H, 4) for u in range(0, W, 2)], np.float64)
    return uv, np.full(len(uv), distance, np.float32)


def test_lidar_depth_pickles_for_worker_processes():
    import pickle
    from functools import partial

    from fogsim.readers.base import DepthSpec

    spec = DepthSpec("x", kind="ray", reader=LidarDepth(partial(_grid_points, 12.0), K, "ipbasic", 0.2, 5))
    back = pickle.loads(pickle.dumps(spec))
    assert back.decoded_by == "lidar:ipbasic" and back.is_ray_distance and back.reader.seed == 5
    image = np.zeros((H, W, 3), np.uint8)
    a, _, rec = back.read_with_record(image)
    assert np.array_equal(a, spec.read_for_image(image)[0]) and rec["points_held_out"] > 0
    assert np.allclose(a[130:], 12.0, rtol=1e-6)


def test_lidar_depth_without_points_names_the_frame():
    reader = LidarDepth(lambda: (np.zeros((0, 2)), np.zeros(0, np.float32)), source="seg/123_FRONT")
    with pytest.raises(InputError, match="seg/123_FRONT: no LiDAR point"):
        reader(np.zeros((8, 8, 3), np.uint8))
    bad = LidarDepth(lambda: (np.zeros((3, 3)), np.zeros(3, np.float32)), source="seg/1")
    with pytest.raises(InputError, match="seg/1: LiDAR points: expected uv N×2"):
        bad(np.zeros((8, 8, 3), np.uint8))


def test_parse_lidar():
    assert parse_lidar("lidar") == ("ipbasic", None)
    assert parse_lidar("lidar:linear") == ("linear", None)
    assert parse_lidar("lidar:ila:/x/r.pt") == ("ila", "/x/r.pt")
    for bad, msg in (("lidar:foo", "unknown LiDAR completion method 'foo'"), ("lidar:ila", "needs a checkpoint"),
                     ("lidar:ipbasic:x", "takes no argument")):
        with pytest.raises(ValueError, match=msg):
            parse_lidar(bad)


def test_read_holdout_refuses_pickles_and_missing_fields(tmp_path):
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    import zipfile

    with zipfile.ZipFile(tmp_path / "evil.npz", "w") as z:
        z.write(tmp_path / "obj.npy", "u.npy")
    with pytest.raises(InputError, match="evil.npz: holds pickled"):
        read_holdout(tmp_path / "evil.npz")
    np.savez(tmp_path / "part.npz", u=np.zeros(2), v=np.zeros(2))
    with pytest.raises(InputError, match="part.npz: malformed LiDAR hold-out file: lacks 'ray', 'width', 'height'"):
        read_holdout(tmp_path / "part.npz")


# ----------------------------------------------------------------------------- scoring numbers
def test_binned_metrics_by_hand():
    gt = np.array([5.0, 15.0, 30.0, 60.0, 100.0, np.inf, 0.0], np.float32)
    pred = gt * np.float32(1.1)
    m = binned_metrics(pred, gt)
    for name, _, _ in BINS:
        assert m[name]["pixels"] == 1 and m[name]["abs_rel"] == pytest.approx(0.1, rel=1e-5)
        assert m[name]["delta1"] == 1.0
    assert m["all"]["pixels"] == 5  # inf and 0 ground truth are not scored
    assert m["all"]["abs_rel"] == pytest.approx(0.1, rel=1e-5)
    assert m["all"]["rmse"] == pytest.approx(np.sqrt(np.mean((0.1 * gt[:5].astype(np.float64)) ** 2)), rel=1e-5)
    assert m["10-20"]["rmse"] == pytest.approx(1.5, rel=1e-5)
    # a missing prediction (hole or +inf) is counted, not scored
    pred2 = pred.copy()
    pred2[1], pred2[2] = 0.0, np.inf
    m2 = binned_metrics(pred2, gt)
    assert m2["10-20"]["missing"] == 1 and m2["10-20"]["pixels"] == 0 and m2["all"]["missing"] == 2
    # δ < 1.25: one pixel off by 30 % in four
    g = np.full(4, 12.0, np.float32)
    assert binned_metrics(np.array([12, 12, 12, 15.6], np.float32), g)["10-20"]["delta1"] == 0.75


def test_pool_weights_by_count():
    a = binned_metrics(np.full(3, 11.0, np.float32), np.full(3, 10.0, np.float32))    # AbsRel 0.1, 3 px
    b = binned_metrics(np.full(1, 13.0, np.float32), np.full(1, 10.0, np.float32))    # AbsRel 0.3, 1 px
    p = pool([a, b])["10-20"]
    assert p["pixels"] == 4 and p["abs_rel"] == pytest.approx((3 * 0.1 + 0.3) / 4, rel=1e-5)
    assert p["rmse"] == pytest.approx(np.sqrt((3 * 1.0 + 9.0) / 4), rel=1e-5)


# ----------------------------------------------------------------------------- fogsim depth score
def _rendered(tmp_path, frames=("f0", "f1")):
    """A two-frame rendered-layout dataset written by hand: depth/<f>.exr planar + meta/<f>.json."""
    from fogsim.dataset.layout import DatasetLayout

    layout = DatasetLayout(tmp_path / "ds")
    cam = Intrinsics(40.0, 40.0, 15.5, 11.5, 32, 24)
    rng = np.random.default_rng(2)
    depths = {}
    for f in frames:
        d = rng.uniform(3, 120, (24, 32)).astype(np.float32)
        d[:4] = np.inf  # sky
        write_depth(layout.depth(f), d)
        write_json(layout.meta(f), {"frame": f, "camera": {"intrinsics": cam.to_dict()}})
        depths[f] = d
    return layout, cam, depths


def _score(*args):
    from fogsim.cli import main

    return main(["depth", "score", *map(str, args)])


def test_cli_score_rendered_dataset_planar_and_ray(tmp_path, capsys):
    layout, cam, depths = _rendered(tmp_path)
    for f, d in depths.items():
        write_depth(tmp_path / "planar" / f"{f}.exr", d * np.float32(1.1))
        write_depth(tmp_path / "ray" / f"{f}.npy", planar_to_ray(d, cam) * np.float32(0.9))
    out = tmp_path / "rep"
    assert _score("--pred", tmp_path / "planar", "--dataset", layout.root, "--out", out) == 0
    printed = capsys.readouterr().out
    assert "| all |" in printed and "0.1000" in printed
    rep = json.loads((out / "score.json").read_text())
    assert rep["overall"]["all"]["abs_rel"] == pytest.approx(0.1, rel=1e-4)
    assert rep["overall"]["all"]["pixels"] == 2 * 20 * 32
    n_bins = sum(rep["overall"][b[0]]["pixels"] for b in BINS)
    assert n_bins == rep["overall"]["all"]["pixels"]
    assert (out / "score.md").read_text().count("|") > 20
    assert read_image(out / "score.png").shape == (320, 720, 3)
    out2 = tmp_path / "rep2"
    assert _score("--pred", tmp_path / "ray", "--pred-kind", "ray", "--dataset", layout.root, "--out", out2) == 0
    rep2 = json.loads((out2 / "score.json").read_text())
    assert rep2["overall"]["all"]["abs_rel"] == pytest.approx(0.1, rel=1e-4)
    assert rep2["against"].startswith("exact rendered depth (ray")


def test_cli_score_holdout_files(tmp_path, capsys):
    cam = Intrinsics(40.0, 40.0, 15.5, 11.5, 32, 24)
    uv = np.array([[3.0, 20.0], [10.2, 18.0], [30.0, 12.4], [16.0, 15.0]])
    ray = np.array([8.0, 15.0, 35.0, 90.0], np.float32)
    write_holdout(tmp_path / "fog" / "lidar_holdout" / "seg" / "1_FRONT.npz", uv, ray, 32, 24, cam)
    pred = np.full((24, 32), 50.0, np.float32)
    rows, cols = np.floor(uv[:, 1] + 0.5).astype(int), np.floor(uv[:, 0] + 0.5).astype(int)
    pred[rows, cols] = ray * np.float32(1.2)  # 20 % too far at every point
    write_depth(tmp_path / "pred" / "seg" / "1_FRONT.exr", pred)
    out = tmp_path / "fog" / "score"  # a report inside the fog output is fine
    assert _score("--pred", tmp_path / "pred", "--pred-kind", "ray", "--holdout", tmp_path / "fog", "--out", out) == 0
    rep = json.loads((out / "score.json").read_text())
    assert rep["overall"]["all"]["pixels"] == 4
    assert rep["overall"]["all"]["abs_rel"] == pytest.approx(0.2, rel=1e-5)
    assert [rep["overall"][b]["pixels"] for b in ("0-10", "10-20", "20-40", "40-80", "80+")] == [1, 1, 1, 0, 1]
    assert rep["overall"]["all"]["delta1"] == 1.0
    # a planar prediction is converted with the hold-out file's camera at each point
    factor = np.sqrt(1 + ((cols - cam.cx) / cam.fx) ** 2 + ((rows - cam.cy) / cam.fy) ** 2)
    planar = np.full((24, 32), 50.0, np.float32)
    planar[rows, cols] = ray / factor
    write_depth(tmp_path / "planar" / "seg" / "1_FRONT.exr", planar)
    assert _score("--pred", tmp_path / "planar", "--holdout", tmp_path / "fog" / "lidar_holdout",
                  "--out", tmp_path / "r2") == 0
    rep2 = json.loads((tmp_path / "r2" / "score.json").read_text())
    assert rep2["overall"]["all"]["abs_rel"] < 1e-5


def test_cli_score_bad_inputs_write_nothing(tmp_path, capsys):
    layout, cam, depths = _rendered(tmp_path)
    out = tmp_path / "rep"
    # missing prediction folder
    assert _score("--pred", tmp_path / "nope", "--dataset", layout.root, "--out", out) == 2
    assert "nope: prediction folder not found" in capsys.readouterr().err
    # size mismatch: names the prediction file and the truth
    write_depth(tmp_path / "p" / "f0.exr", np.ones((24, 32), np.float32))
    write_depth(tmp_path / "p" / "f1.exr", np.ones((12, 16), np.float32))
    assert _score("--pred", tmp_path / "p", "--dataset", layout.root, "--out", out) == 2
    err = capsys.readouterr().err
    assert "f1.exr: prediction is 16×12" in err and "f1.exr is for a 32×24 image" in err
    # a missing prediction for one frame
    (tmp_path / "p" / "f1.exr").unlink()
    assert _score("--pred", tmp_path / "p", "--dataset", layout.root, "--out", out) == 2
    assert "f1.exr: prediction not found" in capsys.readouterr().err
    # no dataset / no hold-out files
    assert _score("--pred", tmp_path / "p", "--dataset", tmp_path / "p", "--out", out) == 2
    assert "not a fogsim dataset" in capsys.readouterr().err
    assert _score("--pred", tmp_path / "p", "--holdout", tmp_path / "p", "--out", out) == 2
    assert "no LiDAR hold-out files" in capsys.readouterr().err
    # a planar prediction against a hold-out file without a camera
    write_holdout(tmp_path / "h" / "f0.npz", np.array([[1.0, 1.0]]), np.array([5.0], np.float32), 32, 24)
    assert _score("--pred", tmp_path / "p", "--holdout", tmp_path / "h", "--out", out) == 2
    assert "f0.npz: a planar prediction needs the camera" in capsys.readouterr().err
    assert not out.exists()


# ----------------------------------------------------------------------------- fogsim fog --waymo --depth-from lidar
STAMPS = (1000, 2000)


def _waymo_file(tmp_path):
    """Two v1 frames of the LiDAR fixture scene (a wall at x = 20 m, one camera, uniform grey
    image): the first with its range images, the second without LiDAR."""
    import waymo_lidar_fixtures as fx
    from fogsim.io.images import encode_image
    from fogsim.readers.waymo.tfrecord import write_tfrecord

    scene = fx.wall_scene()
    image = encode_image(np.full((fx.IMAGE_H, fx.IMAGE_W, 3), 60, np.uint8), ".png")
    path = tmp_path / "seg.tfrecord"
    write_tfrecord(path, [fx.frame_msg(scene, STAMPS[0], image=image),
                          fx.frame_msg(scene, STAMPS[1], with_lasers=False, image=image)])
    return path


def _fog(*args):
    from fogsim.cli import main

    return main(["fog", "--levels", "0.06", "--quiet", *map(str, args)])


def test_cli_fog_waymo_lidar_end_to_end(tmp_path, capsys):
    """The real decoder → completion → fog; the frame without LiDAR fails by name; the
    completion is scored against the held-out points."""
    import waymo_lidar_fixtures as fx

    src = _waymo_file(tmp_path)
    out = tmp_path / "out"
    assert _fog("--waymo", src, "--depth-from", "lidar:linear", "--lidar-holdout", "0.1", "--out", out) == 1
    err = capsys.readouterr().err
    assert "frame has no LiDAR range image" in err and "#record 1" in err  # that frame failed, named
    key = f"{fx.CONTEXT}/{STAMPS[0]}_FRONT"
    side = json.loads((out / "beta0.06" / f"{key}.json").read_text())
    rec = side["depth_record"]
    assert side["encoding"] == "lidar:linear" and rec["method"] == "linear"
    assert rec["points_held_out"] == round(0.1 * rec["points_in_image"]) > 10
    assert 0 < rec["coverage"] < 1
    held = read_holdout(out / "lidar_holdout" / f"{key}.npz")
    assert len(held.ray) == rec["points_held_out"]
    assert held.camera == Intrinsics(fx.FOCAL, fx.FOCAL, fx.IMAGE_W / 2, fx.IMAGE_H / 2, fx.IMAGE_W, fx.IMAGE_H)
    # the held-out points lie on the wall: their camera ray distance is that of the wall plane
    assert held.ray.min() > 15 and held.ray.max() < 75
    # the fogged image at held-out pixels follows Koschmieder at the held-out (true) distance
    got = read_image(out / "beta0.06" / f"{key}.png").astype(np.float64)
    col, row = np.floor(held.uv[:, 0]).astype(int), np.floor(held.uv[:, 1]).astype(int)
    t = np.exp(-0.06 * held.ray)
    assert np.median(np.abs(got[row, col, 0] - (60 * t + 255 * (1 - t)))) <= 1.0
    assert not (out / "beta0.06" / f"{fx.CONTEXT}/{STAMPS[1]}_FRONT.json").exists()
    # the completion made without the held-out points, scored against them
    assert _score("--pred", out / "lidar_depth", "--pred-kind", "ray", "--holdout", out,
                  "--out", out / "score") == 0
    rep = json.loads((out / "score" / "score.json").read_text())
    assert rep["overall"]["all"]["pixels"] == len(held.ray) and rep["overall"]["all"]["abs_rel"] < 0.01


def test_cli_fog_lidar_usage_errors(tmp_path, capsys):
    src = _waymo_file(tmp_path)
    (tmp_path / "depth").mkdir()
    out = tmp_path / "out"
    cases = [
        (("--waymo", src, "--depth-from", "lidar", "--depth-dir", tmp_path / "depth"), "two depth sources"),
        (("--waymo", src, "--depth-from", "lidar:foo"), "unknown LiDAR completion method 'foo'"),
        (("--waymo", src, "--depth-from", "lidar", "--lidar-holdout", "1.5"), "[0, 1)"),
        (("--waymo", src, "--lidar-holdout", "0.1", "--depth-dir", tmp_path / "depth"), "--lidar-holdout goes with"),
        (("--input", tmp_path, "--depth-from", "lidar"), "needs --waymo"),
        (("--waymo", src, "--depth-from", "lidar:ila:" + str(tmp_path / "none.pt")), "none.pt"),
    ]
    for args, message in cases:
        assert _fog(*args, "--out", out) == 2, args
        assert message in capsys.readouterr().err, args
        assert not out.exists(), args


def test_synthetic_scan_has_the_real_density():
    """The bench's scan: ≈ 20 k points on 64 rows covering the lower ≈ 55 % of a FRONT image."""
    from fogsim.bench.lidar import TOP_ROW_PX

    uv, ray = synthetic_scan(np.full((1280, 1920), 30.0, np.float32), np.random.default_rng(0))
    assert 19_000 < len(ray) < 24_000
    assert abs(uv[:, 1].min() - TOP_ROW_PX) < 2 and uv[:, 1].max() > 1260
    assert 0.54 < 1 - uv[:, 1].min() / 1280 < 0.56


# ----------------------------------------------------------------------------- ILA, aligned
@pytest.mark.torch
def test_ila_prediction_is_aligned_to_the_points(tmp_path):
    pytest.importorskip("torch")
    from fogsim.depth.ila import ILAConfig, build_unet, load_model, predict_depth, save_checkpoint

    config = ILAConfig(width=2, size=(32, 32))
    ck = tmp_path / "round_0.pt"
    save_checkpoint(ck, build_unet(config), config, {"baseline_m": 0.2, "fx_over_w": 1.0}, 0)
    rgb = np.random.default_rng(0).integers(0, 256, (48, 64, 3), dtype=np.uint8)
    cam = Intrinsics(50.0, 50.0, 31.5, 23.5, 64, 48)
    model, cfg, camera = load_model(ck)
    pred_inv = 1.0 / planar_to_ray(predict_depth(model, cfg, camera, rgb), cam).astype(np.float64)
    # LiDAR points that are an exact affine map of the prediction's inverse distance
    target = 1.0 / (2.0 * pred_inv + 0.01)
    sparse = np.zeros((48, 64), np.float32)
    sparse[20::4, ::3] = target[20::4, ::3]
    done = complete(sparse, "ila", image=rgb, checkpoint=str(ck), camera=cam)
    assert done.record["scale"] == pytest.approx(2.0, rel=1e-3)
    assert done.record["shift_per_m"] == pytest.approx(0.01, rel=1e-2)
    assert np.allclose(done.ray, target, rtol=1e-3)  # everywhere, the upper image included
    pts = sparse > 0
    assert np.array_equal(done.ray[pts], sparse[pts])  # the points override
    with pytest.raises(ValueError, match="needs the image"):
        complete(sparse, "ila", checkpoint=str(ck), camera=cam)

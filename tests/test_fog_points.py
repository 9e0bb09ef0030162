"""``fogsim fog --points``: scans without a dataset, in every format, written by hand from the formats' specs
(:mod:`lidar_fixtures`: surfaces at known ranges and reflectivities); each level read back by the spec and
checked against the model for the documented seed, and against the survival the model's closed form
gives; sidecars, resume, shards, workers, and an output inside the input refused."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import lidar_fixtures as lf
from conftest import tree_digest
from fogsim.cli import main
from fogsim.lidar.fog import CLUTTER, LOST, LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.runs import level_seed

SURFACES = [lf.Surface(r, rho, 12) for r in (5.0, 15.0, 30.0, 45.0) for rho in (0.1, 0.9)]
LEVELS = (("clear", 0.0), ("beta0.03", 0.03), ("beta0.06", 0.06), ("beta0.09", 0.09), ("beta0.12", 0.12))


def fog(*args) -> int:
    return main(["fog", "--quiet", *map(str, args)])


def ply_bytes(xyz, intensity_255, ring) -> bytes:
    """A binary little-endian PLY written from the format's description (no library)."""
    head = ("ply\nformat binary_little_endian 1.0\ncomment fogsim intensity_scale 0-255\n"
            f"element vertex {len(xyz)}\nproperty float x\nproperty float y\nproperty float z\n"
            "property float intensity\nproperty short ring\nend_header\n").encode()
    rec = np.empty(len(xyz), [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<i2")])
    rec["x"], rec["y"], rec["z"], rec["intensity"], rec["ring"] = *xyz.T, intensity_255, ring
    return head + rec.tobytes()


@pytest.fixture
def scans(tmp_path):
    """The same surfaces in each format under in/<format>/ (two scans each, one in a sub-folder)."""
    xyz, rho, rng_m, sid = lf.surfaces_scan(SURFACES)
    i01 = (rho / lf.REFLECTIVITY_PER_INTENSITY).astype(np.float32)
    i255 = (255 * rho / lf.REFLECTIVITY_PER_INTENSITY).astype(np.float32)
    ring = (np.arange(len(xyz)) % 32).astype(np.float32)
    data = {"kitti": (lf.kitti_bin(xyz, i01), "a.bin"), "stf": (lf.stf_bin(xyz, i255, ring), "a.bin"),
            "nuscenes": (lf.stf_bin(xyz, i255, ring), "n015-2018_LIDAR_TOP__1533151603547590.pcd.bin"),
            "ply": (ply_bytes(xyz, i255, ring.astype(np.int16)), "a.ply")}
    import io

    buf = io.BytesIO()
    np.save(buf, np.column_stack([xyz, i01]).astype(np.float32), allow_pickle=False)
    data["npy"] = (buf.getvalue(), "a.npy")
    for fmt, (blob, name) in data.items():
        for where in (tmp_path / "in" / fmt / name, tmp_path / "in" / fmt / "sweeps" / name):
            where.parent.mkdir(parents=True, exist_ok=True)
            where.write_bytes(blob)
    return tmp_path, rho, rng_m


FORMATS = {"kitti": (".bin", "hdl64e"), "stf": (".bin", "hdl64-s3d"), "nuscenes": (".pcd.bin", "hdl32e"),
           "ply": (".ply", "hdl64-s3d"), "npy": (".npy", "hdl64e")}


@pytest.mark.parametrize("fmt", list(FORMATS))
def test_points_in_each_format(scans, fmt):
    tmp, rho, rng_m = scans
    suffix, sensor = FORMATS[fmt]
    src, out = tmp / "in" / fmt, tmp / "out"
    before = tree_digest(tmp / "in")
    extra = ("--sensor", sensor) if fmt in ("ply", "npy") else ()
    assert fog("--points", src, "--point-format", fmt, *extra, "--levels", "paper", "--out", out) == 0
    assert tree_digest(tmp / "in") == before
    inputs = sorted(p for p in src.rglob(f"*{suffix}"))
    assert len(inputs) == 2
    for path in inputs:
        name = path.relative_to(src).as_posix()[: -len(suffix)]
        cloud = read_points(path, fmt)
        for level, beta in LEVELS:
            got_path = out / level / f"{name}{suffix}"
            expected = LidarFogger(cloud, sensor)(beta, np.random.default_rng(level_seed(0, name, level)))
            got, want = read_points(got_path, fmt), expected.cloud
            assert np.array_equal(got.xyz, want.xyz) and np.array_equal(got.raw_intensity, want.raw_intensity)
            assert (got.ring is None) == (want.ring is None)
            assert got.ring is None or np.array_equal(got.ring, want.ring)
            assert got.scale == want.scale == cloud.scale
            if beta == 0:
                assert got_path.read_bytes() == path.read_bytes()  # the input, bit for bit
            outcome, index = read_outcomes(out / level / f"{name}.outcomes.npz")
            np.testing.assert_array_equal(outcome, expected.outcome)
            np.testing.assert_array_equal(index, expected.output_index)
            side = json.loads((out / level / f"{name}.json").read_text())
            assert side["source"] == str(path) and side["sensor"]["name"] == sensor
            assert side["outcomes"] == expected.counts() and side["seed"] == level_seed(0, name, level)
            assert side["outcome_file"] == f"{Path(name).name}.outcomes.npz" and side["pcd"] == f"{Path(name).name}.pcd"
            # the physics: a dark surface loses its hard returns (to nothing or to the fog's echo) before a
            # bright one at the same range (12 rays each, every echo fluctuating)
            if beta > 0:
                gone = (outcome == LOST) | (outcome == CLUTTER)
                for r in (15.0, 30.0, 45.0):
                    dark, bright = gone[(rng_m == r) & (rho == 0.1)], gone[(rng_m == r) & (rho == 0.9)]
                    assert dark.mean() >= bright.mean()
    shares = [json.loads((out / lv / f"{inputs[0].relative_to(src).as_posix()[: -len(suffix)]}.json").read_text())
              ["outcomes"]["kept"] for lv, _ in LEVELS]
    assert shares[0] == len(rho) and all(a >= b for a, b in zip(shares, shares[1:])) and shares[-1] < shares[0]


def test_the_same_scan_in_kitti_and_stf_scales_gives_the_same_outcomes(scans):
    tmp, *_ = scans
    for fmt in ("kitti", "stf"):
        assert fog("--points", tmp / "in" / fmt / "a.bin", "--point-format", fmt, "--sensor", "hdl64e",
                   "--levels", "0.09", "--out", tmp / f"out_{fmt}") == 0
    a = read_outcomes(tmp / "out_kitti" / "beta0.09" / "a.outcomes.npz")[0]
    b = read_outcomes(tmp / "out_stf" / "beta0.09" / "a.outcomes.npz")[0]
    np.testing.assert_array_equal(a, b)
    assert (a != 0).any()


def test_resume_shards_workers_and_refusals(scans, capsys):
    tmp, *_ = scans
    src = tmp / "in" / "kitti"
    whole, parts, pool = tmp / "whole", tmp / "parts", tmp / "pool"
    argv = ("--points", src, "--point-format", "kitti", "--levels", "0,0.06,0.12")
    assert fog(*argv, "--out", whole) == 0
    for i in range(2):
        assert fog(*argv, "--shard", f"{i}/2", "--out", parts) == 0
    assert fog(*argv, "--workers", "2", "--out", pool) == 0
    run = lambda p: {q.relative_to(p) for q in p.rglob("*") if q.is_file() and q.name != "fogsim_run.json"}  # noqa: E731
    assert run(whole) == run(parts) == run(pool)
    for rel in run(whole):
        if rel.suffix != ".json":
            assert (whole / rel).read_bytes() == (parts / rel).read_bytes() == (pool / rel).read_bytes(), rel
    capsys.readouterr()
    assert fog(*argv, "--out", whole) == 0
    assert "2 already done" in capsys.readouterr().out
    assert fog("--finalize-only", "--out", whole) == 2
    assert "fogged scans alone (--points)" in capsys.readouterr().err
    assert fog(*argv, "--lidar-model", "attenuation", "--out", whole) == 2
    assert "other parameters" in capsys.readouterr().err
    cases = [((*argv, "--out", src / "o"), "lies inside --points"),
             (("--points", tmp / "in" / "ply", "--point-format", "ply", "--out", tmp / "o2"), "--sensor"),
             (("--points", src, "--out", tmp / "o3"), "--point-format"),
             (("--points", tmp / "in" / "ply", "--point-format", "kitti", "--out", tmp / "o4"), "holds no .bin"),
             ((*argv, "--heterogeneity", "0.3", "--out", tmp / "o5"), "--heterogeneity"),
             ((*argv, "--lidar", "--out", tmp / "o6"), "--lidar goes with a dataset"),
             ((*argv, "--point-scale", "0-255", "--out", tmp / "o7"), "--point-scale")]
    for args, message in cases:
        assert fog(*args) == 2, args
        assert message in capsys.readouterr().err, args
    assert not any((tmp / f"o{k}").exists() for k in range(2, 8)) and not (src / "o").exists()


def test_a_bad_scan_fails_alone(scans, capsys):
    tmp, *_ = scans
    src = tmp / "in" / "kitti"
    (src / "sweeps" / "a.bin").write_bytes((src / "a.bin").read_bytes()[:-5])
    out = tmp / "out"
    assert fog("--points", src, "--point-format", "kitti", "--levels", "0.06", "--out", out) == 1
    err = capsys.readouterr().err
    assert "sweeps/a.bin" in err and "not a whole number of 16-byte kitti records" in err
    assert (out / "beta0.06" / "a.json").is_file() and not (out / "beta0.06" / "sweeps").exists()


def _totals(out: str) -> dict[str, dict[str, int]]:
    """The ``outcomes per level`` lines of a run's output: level → outcome → count."""
    lines = out[out.index("outcomes per level"):].splitlines()[1:]
    got = {}
    for line in lines:
        if not line.startswith("  "):
            break
        key, rest = line.strip().split(": ", 1)
        got[key] = {w.split()[0]: int(w.split()[1]) for w in rest.split(" + ")[0].split(", ")}
    return got


def test_the_run_ends_with_each_levels_outcome_totals(scans, capsys):
    """Summed from the outcome files on disk, without fogsim's summary code: kept, attenuated, lost per input
    point, clutter adding the empty rays' (the sidecar's count); a resumed run counts the scans it found done."""
    from fogsim.lidar.fog import OUTCOMES
    from fogsim.lidar.outcome_file import read_outcomes

    tmp, *_ = scans
    src, out = tmp / "in" / "kitti", tmp / "totals"
    argv = ["fog", "--points", str(src), "--point-format", "kitti", "--levels", "0,0.06,0.12", "--out", str(out)]
    capsys.readouterr()
    assert main(argv) == 0
    said = capsys.readouterr().out
    want, extra = {}, {}
    for level in ("clear", "beta0.06", "beta0.12"):
        counts, extra[level] = np.zeros(len(OUTCOMES), np.int64), 0
        for f in (out / level).rglob("*.outcomes.npz"):
            counts += np.bincount(read_outcomes(f)[0], minlength=len(OUTCOMES))
            extra[level] += json.loads(f.with_name(f.name.replace(".outcomes.npz", ".json")).read_text())[
                "empty_ray_clutter"]
        want[level] = dict(zip(OUTCOMES, counts.tolist()))
    assert _totals(said) == want
    for level, n in extra.items():  # the fog's points on rays with no input point, said apart
        line = next(ln for ln in said.splitlines() if ln.strip().startswith(f"{level}:"))
        assert line.endswith(f" + {n} on empty rays") if n else "empty rays" not in line
        share = 100 * want[level]["kept"] / sum(want[level].values())
        assert f"kept {want[level]['kept']} ({share:.1f} %)" in line  # shares of the input points
    assert want["beta0.12"]["kept"] < want["clear"]["kept"] and want["clear"]["lost"] == 0
    assert said.index("outcomes per level") < said.index("fogged 2 of 2 scans")  # before the summary line
    assert main(argv) == 0  # resumed: nothing fogged, the same totals
    again = capsys.readouterr().out
    assert "2 already done" in again and _totals(again) == want
    assert main([*argv, "--quiet"]) == 0 and "outcomes per level" not in capsys.readouterr().out

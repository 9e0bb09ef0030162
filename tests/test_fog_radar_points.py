"""``fogsim fog --points DIR --point-format nuscenes-radar``: nuScenes RADAR_* sweeps built here from the
format's spec (test_radar_formats' writer), every level read back by the spec's reader and checked against
the model; β = 0 the input byte for byte; sidecars, resume, shards, refusals naming the file."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import tree_digest
from fogsim.cli import main
from fogsim.radar.fog import KEPT, RadarFogger
from fogsim.radar.formats import read_radar
from fogsim.radar.outcome_file import read_radar_outcomes
from test_radar_formats import SPEC_FIELDS, spec_bytes, spec_read

pytest.importorskip("itur")

LEVELS = (("clear", 0.0), ("beta0.03", 0.03), ("beta0.06", 0.06), ("beta0.09", 0.09), ("beta0.12", 0.12))


def fog(*args) -> int:
    return main(["fog", "--quiet", *map(str, args)])


def sweep_rows(seed: int, n: int = 60) -> list[tuple]:
    """Detections of an ARS 408 far scan: strong near, some weak far ones close to the threshold (a 10 dBsm
    car is at the threshold at 250 m; 5–8 dBsm at 200–240 m sit within the estimate's 1 dB margin of it, and
    the round trip through β = 0.12 costs them ≈ 1.0–1.2 dB)."""
    rng = np.random.default_rng(seed)
    r = np.concatenate([rng.uniform(5, 90, n // 2), rng.uniform(200, 240, n - n // 2)])
    rcs = np.concatenate([rng.uniform(0, 20, n // 2), rng.uniform(5.0, 8.0, n - n // 2)])
    az = np.radians(rng.uniform(-8, 8, n))
    rows = []
    for k in range(n):
        x, y = float(np.float32(r[k] * np.cos(az[k]))), float(np.float32(r[k] * np.sin(az[k])))
        rows.append((x, y, 0.0, k % 8, k, float(np.float32(rcs[k])), -1.5, 0.25, 0.0, 0.0, 1, 3, 19, 18,
                     0, 1, 17, 3))
    return rows


@pytest.fixture
def sweeps(tmp_path):
    src = tmp_path / "samples" / "RADAR_FRONT"
    (src / "sub").mkdir(parents=True)
    (src / "n008__RADAR_FRONT__1.pcd").write_bytes(spec_bytes(sweep_rows(1)))
    (src / "sub" / "n008__RADAR_FRONT__2.pcd").write_bytes(spec_bytes(sweep_rows(2)))
    (src / "n008__LIDAR_TOP__1.pcd.bin").write_bytes(b"\0" * 20)  # not a radar sweep: not picked up
    return tmp_path, src


def test_every_level_with_its_outcomes(sweeps):
    tmp, src = sweeps
    out = tmp / "out"
    before = tree_digest(src)
    assert fog("--points", src, "--point-format", "nuscenes-radar", "--levels", "paper", "--out", out) == 0
    assert tree_digest(src) == before
    lost_any = False
    for name in ("n008__RADAR_FRONT__1", "sub/n008__RADAR_FRONT__2"):
        path = src / f"{name}.pcd"
        scan = read_radar(path)
        _, in_rows = spec_read(path.read_bytes())
        kept_before = len(scan)
        for level, beta in LEVELS:
            got = out / level / f"{name}.pcd"
            want = RadarFogger(scan, "ars408-lr")(beta)
            outcome, index, snr = read_radar_outcomes(out / level / f"{name}.outcomes.npz")
            np.testing.assert_array_equal(outcome, want.outcome)
            np.testing.assert_array_equal(index, want.output_index)
            np.testing.assert_array_equal(snr, want.snr_fog_db)
            head, rows = spec_read(got.read_bytes())
            assert head["FIELDS"] == SPEC_FIELDS
            assert rows == [in_rows[i] for i in np.flatnonzero(outcome == KEPT)]  # every field as read
            if beta == 0:
                assert got.read_bytes() == path.read_bytes()
            side = json.loads((out / level / f"{name}.json").read_text())
            assert side["outcomes"] == want.counts() and side["sensor"]["name"] == "ars408-lr"
            assert side["source"] == str(path) and side["outcome_file"] == f"{name.split('/')[-1]}.outcomes.npz"
            kept = side["outcomes"]["kept"]
            assert kept <= kept_before
            kept_before = kept
            lost_any |= side["outcomes"]["lost"] > 0
            if beta > 0:  # only far detections go, and they go first
                r = scan.range_m
                assert (outcome[r < 90] == KEPT).all()
    assert lost_any


def test_resume_shards_and_refusals(sweeps, capsys):
    tmp, src = sweeps
    argv = ("--points", src, "--point-format", "nuscenes-radar", "--levels", "0,0.12")
    whole, parts = tmp / "whole", tmp / "parts"
    assert fog(*argv, "--out", whole) == 0
    for i in range(2):
        assert fog(*argv, "--shard", f"{i}/2", "--out", parts) == 0
    files = lambda p: {q.relative_to(p) for q in p.rglob("*") if q.is_file() and q.name != "fogsim_run.json"}  # noqa: E731
    assert files(whole) == files(parts) and len(files(whole)) == 12
    for rel in files(whole):
        if rel.suffix != ".json":
            assert (whole / rel).read_bytes() == (parts / rel).read_bytes(), rel
    capsys.readouterr()
    assert fog(*argv, "--out", whole) == 0
    assert "2 already done" in capsys.readouterr().out
    assert fog(*argv, "--radar-temperature", "0", "--out", whole) == 2  # other parameters: refused
    assert "other parameters" in capsys.readouterr().err
    cases = [((*argv, "--lidar-model", "attenuation", "--out", tmp / "o1"), "--lidar-model is for LiDAR"),
             ((*argv, "--sensor", "hdl64e", "--out", tmp / "o2"), "unknown radar sensor"),
             ((*argv, "--heterogeneity", "0.3", "--out", tmp / "o3"), "--heterogeneity"),
             (("--points", src / "sub" / "none", "--point-format", "nuscenes-radar", "--out", tmp / "o5"),
              "no such file"),
             (("--points", src, "--point-format", "kitti", "--radar-temperature", "5", "--out", tmp / "o6"),
              "--radar-temperature goes with")]
    for args, message in cases:
        assert fog(*args) == 2, args
        assert message in capsys.readouterr().err, args
    assert not any((tmp / f"o{k}").exists() for k in (1, 2, 3, 5, 6))


def test_a_bad_sweep_fails_alone_naming_it(sweeps, capsys):
    tmp, src = sweeps
    bad = src / "sub" / "n008__RADAR_FRONT__2.pcd"
    bad.write_bytes(bad.read_bytes()[:-100])
    out = tmp / "out"
    assert fog("--points", src, "--point-format", "nuscenes-radar", "--levels", "0.06", "--out", out) == 1
    err = capsys.readouterr().err
    assert "sub/n008__RADAR_FRONT__2.pcd" in err and "truncated" in err
    assert (out / "beta0.06" / "n008__RADAR_FRONT__1.json").is_file() and not (out / "beta0.06" / "sub").exists()


def test_the_run_ends_with_each_levels_detections_kept_and_lost(sweeps, capsys):
    """The totals summed from the outcome files on disk (kept and lost per input detection)."""
    tmp, src = sweeps
    out = tmp / "totals"
    argv = ["fog", "--points", str(src), "--point-format", "nuscenes-radar", "--levels", "paper", "--out", str(out)]
    assert main(argv) == 0
    said = capsys.readouterr().out
    lines = said[said.index("outcomes per level (detections"):].splitlines()[1:6]
    for line in lines:
        key, rest = (part.strip() for part in line.split(": ", 1))
        outcome = np.concatenate([read_radar_outcomes(f)[0] for f in (out / key).rglob("*.outcomes.npz")])
        kept, lost = int((outcome == KEPT).sum()), int((outcome != KEPT).sum())
        assert rest.startswith(f"kept {kept} (") and f"lost {lost} (" in rest, line
    assert [ln.strip().split(":")[0] for ln in lines] == ["clear", "beta0.03", "beta0.06", "beta0.09", "beta0.12"]

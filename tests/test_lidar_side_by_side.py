"""The three LiDAR fog models side by side (fogsim.bench.lidar_side_by_side and scripts/lidar_side_by_side.py)
on the CI fixture sweeps: the invariants each model's rows must hold, the statistics against the fogged scans
they summarise, and docs/lidar-fog.md holding the block exactly as the script makes it (stale: fails)."""
from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

import numpy as np
import pytest

from fogsim.bench import lidar_side_by_side as sbs
from fogsim.lidar.fog import CLUTTER, LOST, OUTCOMES, LidarFogger
from fogsim.schema.lidar import CALIBRATIONS, DEPRECATED_CALIBRATIONS

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "lidar-fog.md"


def _script():
    path = ROOT / "scripts" / "lidar_side_by_side.py"
    spec = importlib.util.spec_from_file_location("lidar_side_by_side_script", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def subjects(tmp_path_factory):
    return _script().fixture_subjects(tmp_path_factory.mktemp("sweeps"))


@pytest.fixture(scope="module")
def results(subjects):
    return [sbs.run_scan(s) for s in subjects]


def test_the_fixtures_are_one_per_format(subjects):
    kitti, nuscenes, stf = (s.scan for s in subjects)
    assert kitti.scale == "0-1" and 17_000 <= len(kitti) <= 21_000
    assert 17.0 <= 100.0 * float((kitti.raw_intensity == 0).mean()) <= 22.0
    assert nuscenes.scale == stf.scale == "0-255" and nuscenes.ring.max() == 31 and stf.ring.max() == 63
    assert [s.sensor for s in subjects] == ["hdl64e", "hdl32e", "hdl64-s3d"]


def test_rows_hold_each_models_invariants(results):
    for r in results:
        assert [lv.model for lv in r.levels] == [m for m in sbs.MODELS for _ in sbs.BETAS]
        for lv in r.levels + [x for c in r.calibrations.values() for x in c]:
            assert list(lv.shares) == list(OUTCOMES) and sum(lv.shares.values()) == pytest.approx(100.0, abs=1e-9)
            assert sum(lv.far) <= sum(r.clear_far) + 1e-9
        hahner = [lv for lv in r.levels if lv.model == "hahner2021"]
        assert all(lv.shares["lost"] == 0.0 and lv.added == 0.0 for lv in hahner)  # it never drops or adds a point
        assert all(lv.shares["kept"] >= r.zero - 1e-9 for lv in hahner)  # zero-intensity points are kept
        clutter = [lv.shares["clutter"] for lv in hahner]
        assert all(a < b for a, b in zip(clutter, clutter[1:]))  # grows with β
        stf = [lv for lv in r.levels if lv.model == "stf2020"]
        for lv in stf:  # its clutter all at d_new = ln 2 / β
            assert lv.clutter_m[0] == pytest.approx(math.log(2) / lv.beta, rel=1e-5)
            assert lv.clutter_m[2] == pytest.approx(math.log(2) / lv.beta, rel=1e-5)
        assert all(lv.added > 0 for lv in stf)
        assert list(r.calibrations) == [c for c in CALIBRATIONS if c not in DEPRECATED_CALIBRATIONS]
    kitti = results[0]
    assert kitti.trap is not None and all(v > 0.95 * (100.0 - kitti.zero) for v in kitti.trap)  # the 0–1 trap
    assert results[1].trap is None and results[2].trap is None


def test_statistics_are_those_of_the_fogged_scan(subjects, results):
    """One level recomputed from its fogged scan: the far field per bin and the clutter's range spread."""
    s, r = subjects[1], results[1]
    fogged = LidarFogger(s.scan, s.sensor, sbs.model_specs(s)["hahner2021"])(0.06, np.random.default_rng(1))
    lv = next(x for x in r.levels if x.model == "hahner2021" and x.beta == 0.06)
    d = s.scan.range_m
    hard = (fogged.outcome != LOST) & (fogged.outcome != CLUTTER)
    want = [100 * float((hard & (d >= 30) & (d < 50)).mean()), 100 * float((hard & (d >= 50) & (d < 80)).mean()),
            100 * float((hard & (d >= 80)).mean())]
    assert lv.far == pytest.approx(want, abs=1e-12)
    rows = fogged.output_index[fogged.outcome == CLUTTER]
    out, own = fogged.cloud.xyz[rows].astype(np.float64), s.scan.xyz[fogged.outcome == CLUTTER].astype(np.float64)
    signed = np.linalg.norm(out, axis=1) * np.sign((out * own).sum(axis=1))  # a dark point near the sensor may
    assert (signed < 0).any()  # be scattered behind it (u < 0 in R_f·R₀/u when R₀ < 10 m)
    assert lv.clutter_m == pytest.approx(tuple(np.percentile(signed, (5, 50, 95))), rel=1e-9)
    assert r.clear_far == pytest.approx([100 * float(((d >= lo) & (d < hi)).mean())
                                         for lo, hi in ((30, 50), (50, 80), (80, math.inf))])


def test_markdown_structure_and_determinism(results, subjects):
    text = sbs.markdown(results)
    assert text.count("| β (1/m) |") == 3 * len(results) and sbs.REGENERATE in text
    for line in text.splitlines():
        if line.startswith("| 0.") and " / " in line and line.count("|") == len(sbs.MODELS) + 3:
            for cell in line.strip("|").split("|")[1:1 + len(sbs.MODELS)]:
                assert sum(float(v) for v in cell.split(" / ")) == pytest.approx(100.0, abs=0.3)
    assert sbs.markdown([sbs.run_scan(subjects[0])]) == sbs.markdown(results[:1])  # seeded: the same twice


def test_docs_hold_the_block_as_generated(results):
    text = DOCS.read_text(encoding="utf-8")
    assert text.count(sbs.BEGIN) == 1 and text.count(sbs.END) == 1
    current = text[text.index(sbs.BEGIN) + len(sbs.BEGIN):text.index(sbs.END)]
    # the words exactly, the numbers to their last printed digit (a point on a decision boundary may round
    # the other way under another numpy's exp/log: one point of 20 324 is 0.005 %)
    number = re.compile(r"(\d+\.\d+)")
    got, want = number.split(current), number.split("\n" + sbs.markdown(results))
    stale = f"docs/lidar-fog.md's side-by-side block is stale: run `{sbs.REGENERATE}`"
    assert got[0::2] == want[0::2] and len(got) == len(want), stale
    assert all(abs(float(a) - float(b)) <= 0.11 for a, b in zip(got[1::2], want[1::2])), stale
    assert "## Beside the published models" in text and "the trap applies only to unscaled input" in text


def test_replace_block_needs_its_markers():
    assert sbs.replace_block(f"a\n{sbs.BEGIN}\nold\n{sbs.END}\nb", "new\n") == f"a\n{sbs.BEGIN}\nnew\n{sbs.END}\nb"
    with pytest.raises(ValueError, match="markers"):
        sbs.replace_block("no markers here", "x")


def test_script_rewrites_a_stale_block_and_then_leaves_it(tmp_path, capsys, results):
    page = tmp_path / "lidar-fog.md"
    page.write_text(f"# page\n\n{sbs.BEGIN}\n| stale |\n{sbs.END}\n\nafter\n", encoding="utf-8")
    script = _script()
    assert script.main(["--docs", str(tmp_path)]) == 0
    assert "rewritten" in capsys.readouterr().out
    text = page.read_text(encoding="utf-8")
    assert sbs.replace_block(text, sbs.markdown(results)) == text and text.endswith(f"{sbs.END}\n\nafter\n")
    assert script.main(["--docs", str(tmp_path)]) == 0
    assert "already current" in capsys.readouterr().out
    (tmp_path / "lidar-fog.md").write_text("no markers\n", encoding="utf-8")
    assert script.main(["--docs", str(tmp_path)]) == 2
    assert (tmp_path / "lidar-fog.md").read_text(encoding="utf-8") == "no markers\n"

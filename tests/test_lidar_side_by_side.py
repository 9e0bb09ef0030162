"""fogsim beside the reference re-implementation (fogsim.bench.lidar_side_by_side and
scripts/lidar_side_by_side.py) on the CI fixture sweep: the table's structure and the invariants it must
hold whatever fogsim's model is, and docs/lidar-fog.md holding the table exactly as the script makes it."""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

import lidar_fixtures as lfx
from fogsim.bench import lidar_side_by_side as sbs
from fogsim.lidar.fog import OUTCOMES
from fogsim.schema.lidar import LidarFogSpec

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "lidar-fog.md"


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    return lfx.kitti_street_cloud(tmp_path_factory.mktemp("sweep"))


@pytest.fixture(scope="module")
def result(scan):
    return sbs.side_by_side(scan, label=lfx.SWEEP_LABEL)


def test_fixture_is_kitti_like(scan):
    assert scan.scale == "0-1" and 17_000 <= len(scan) <= 21_000
    assert 17.0 <= 100.0 * float((scan.raw_intensity == 0).mean()) <= 22.0


def test_rows_hold_the_invariants(result, scan):
    assert [r.beta for r in result.rows] == list(sbs.BETAS)
    zero = 100.0 * float((scan.raw_intensity == 0).mean())
    assert result.zero_intensity == pytest.approx(zero)
    for r in result.rows:
        for shares in (r.fogsim, r.reference):
            assert list(shares) == list(OUTCOMES)
            assert sum(shares.values()) == pytest.approx(100.0, abs=1e-9)
        assert r.reference["lost"] == 0.0  # the reference never drops a point
        assert r.reference["kept"] >= zero - 1e-9  # every zero-intensity point is kept
        assert r.reference_unscaled_clutter > 0.95 * (100.0 - zero)  # the 0–1 trap, unscaled only
        assert r.reference["clutter"] < 15.0
        assert r.reference_clutter_m is None or 0.0 < r.reference_clutter_m < 8.0
    clutter = [r.reference["clutter"] for r in result.rows]
    assert all(a < b for a, b in zip(clutter, clutter[1:]))  # grows with β


def test_zero_intensity_points_kept_point_by_point(scan):
    from fogsim.lidar.hahner import fed_intensity, hahner_fog

    zero = scan.raw_intensity == 0
    for beta in sbs.BETAS:
        level = hahner_fog(scan.xyz, fed_intensity(scan), beta, np.random.default_rng(0))
        assert (level.outcome[zero] == 0).all()


def test_markdown_table_structure(result, scan):
    text = sbs.markdown(result)
    lines = text.splitlines()
    assert lines[0].startswith("| β (1/m) |") and lines[1] == "|---|---|---|---|---|"
    rows = lines[2:2 + len(sbs.BETAS)]
    for line, beta in zip(rows, sbs.BETAS):
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert len(cells) == 5 and float(cells[0]) == beta
        for cell in cells[1:3]:
            assert sum(float(v) for v in cell.split(" / ")) == pytest.approx(100.0, abs=0.3)
    assert sbs.REGENERATE in text and result.calibration in text
    assert sbs.markdown(sbs.side_by_side(scan, label=lfx.SWEEP_LABEL)) == text  # seeded: the same table twice


def test_docs_hold_the_table_as_generated(result):
    text = DOCS.read_text(encoding="utf-8")
    assert text.count(sbs.BEGIN) == 1 and text.count(sbs.END) == 1
    current = text[text.index(sbs.BEGIN) + len(sbs.BEGIN):text.index(sbs.END)]
    # the words exactly, the numbers to their last printed digit (a point on a decision boundary may round
    # the other way under another numpy's exp/log: one point of 20 324 is 0.005 %)
    number = re.compile(r"(\d+\.\d+)")
    got, want = number.split(current), number.split("\n" + sbs.markdown(result))
    stale = f"docs/lidar-fog.md's side-by-side table is stale: run `{sbs.REGENERATE}`"
    assert got[0::2] == want[0::2] and len(got) == len(want), stale
    assert all(abs(float(a) - float(b)) <= 0.11 for a, b in zip(got[1::2], want[1::2])), stale
    assert "## Beside the reference simulator" in text


def test_trap_claim_says_unscaled_only():
    text = DOCS.read_text(encoding="utf-8")
    assert "the trap applies only to unscaled input" in text


def test_calibration_passes_through_when_the_model_has_one():
    if "calibration" in LidarFogSpec.model_fields:
        spec, name = sbs.calibration_spec("reference")
        assert spec == {"calibration": "reference"} and name == "reference"
    else:
        assert sbs.calibration_spec(None)[0] is None
        with pytest.raises(ValueError, match="no calibration choice"):
            sbs.calibration_spec("reference")


def test_replace_block_needs_its_markers():
    assert sbs.replace_block(f"a\n{sbs.BEGIN}\nold\n{sbs.END}\nb", "new\n") == f"a\n{sbs.BEGIN}\nnew\n{sbs.END}\nb"
    with pytest.raises(ValueError, match="markers"):
        sbs.replace_block("no markers here", "x")


def _script():
    path = ROOT / "scripts" / "lidar_side_by_side.py"
    spec = importlib.util.spec_from_file_location("lidar_side_by_side_script", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_script_rewrites_a_stale_block_and_then_leaves_it(tmp_path, capsys, result):
    page = tmp_path / "lidar-fog.md"
    page.write_text(f"# page\n\n{sbs.BEGIN}\n| stale |\n{sbs.END}\n\nafter\n", encoding="utf-8")
    script = _script()
    assert script.main(["--docs", str(tmp_path)]) == 0
    assert "rewritten" in capsys.readouterr().out
    text = page.read_text(encoding="utf-8")
    assert sbs.replace_block(text, sbs.markdown(result)) == text and text.endswith(f"{sbs.END}\n\nafter\n")
    assert script.main(["--docs", str(tmp_path)]) == 0
    assert "already current" in capsys.readouterr().out
    (tmp_path / "lidar-fog.md").write_text("no markers\n", encoding="utf-8")
    assert script.main(["--docs", str(tmp_path)]) == 2
    assert (tmp_path / "lidar-fog.md").read_text(encoding="utf-8") == "no markers\n"

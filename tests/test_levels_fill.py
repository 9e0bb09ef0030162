"""Fog levels and presets; hole filling."""
import math

import numpy as np
import pytest

from fogsim.fog.fill import HolesError, fill_holes, fill_methods
from fogsim.fog.levels import beta_from_visibility, load_preset, parse_levels, preset_names, visibility_from_beta


def test_visibility_conversion():
    assert visibility_from_beta(0.03) == pytest.approx(99.86, abs=0.01)
    assert visibility_from_beta(0.12) == pytest.approx(24.96, abs=0.01)
    assert math.isinf(visibility_from_beta(0))
    assert beta_from_visibility(visibility_from_beta(0.06)) == pytest.approx(0.06)
    # at the visibility, a black object's contrast is 5 %: t = 1/20
    assert math.exp(-0.06 * visibility_from_beta(0.06)) == pytest.approx(0.05)


def test_presets():
    assert {"paper", "foggy-cityscapes"} <= set(preset_names())
    paper = load_preset("paper")
    assert [lv.beta for lv in paper] == [0.0, 0.03, 0.06, 0.09, 0.12]
    assert paper[0].key == "clear" and paper[4].name == "very heavy fog"
    assert [lv.beta for lv in parse_levels("foggy-cityscapes")] == [0.005, 0.01, 0.02]


def test_parse_levels():
    assert [lv.key for lv in parse_levels("clear,0.005,0.01")] == ["clear", "beta0.005", "beta0.01"]
    vis = parse_levels(visibility="50,100")
    assert [lv.key for lv in vis] == ["vis50m", "vis100m"]
    assert vis[0].beta == pytest.approx(math.log(20) / 50)
    assert parse_levels() == load_preset("paper")
    for bad in ("-0.1", "0.1,abc", "0.1,0.1"):
        with pytest.raises(ValueError):
            parse_levels(bad)
    with pytest.raises(ValueError):
        parse_levels(visibility="0")
    with pytest.raises(Exception, match="unknown fog preset"):
        parse_levels("nonesuch")


@pytest.mark.parametrize("method", ["inpaint", "ipbasic"])
def test_fill_changes_only_holes_and_interpolates(method):
    # a tilted plane: inverse depth linear in v; punch holes, fill, compare
    v = np.arange(60, dtype=np.float32)[:, None] * np.ones((1, 80), np.float32)
    depth = 1.0 / (0.02 + 0.004 * v)
    holes = np.zeros_like(depth, bool)
    holes[20:26, 30:40] = True
    holes[40:44, 5:9] = True
    d = depth.copy()
    d[holes] = 0
    d[0, :3] = np.inf  # no-hit pixels are not holes
    out = fill_holes(d, method)
    assert np.array_equal(out[~holes], d[~holes])
    assert np.all(out[holes] > 0) and np.all(np.isfinite(out[holes]))
    rel = np.abs(out[holes] - depth[holes]) / depth[holes]
    assert np.median(rel) < 0.08


def test_fill_none_refuses_holes_and_passes_clean_maps():
    d = np.full((5, 5), 10.0, np.float32)
    assert fill_holes(d, "none") is d
    d[2, 2] = 0
    with pytest.raises(HolesError, match="1 hole pixels"):
        fill_holes(d, "none")
    assert set(fill_methods()) >= {"none", "inpaint", "ipbasic"}

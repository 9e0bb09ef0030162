"""The bird's-eye pictures read alone (issue 47, point 5): a legend below them, distances written on the range
rings, captions that fit their tile, and on the radar picture what the fog costs radar against light."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from fogsim.dataset.radar import BEV_LEGEND as RADAR_LEGEND
from fogsim.dataset.radar import KIND_COLOURS, fog_note, radar_bev_image
from fogsim.lidar.pictures import BEV_LEGEND, OUTCOME_COLOURS, bev_image, bev_levels
from fogsim.lidar.points import PointCloud
from fogsim.viz import fitted_scale, label, legend_row, ring_labels

DARK = 160  # a text pixel: every channel below this


def _dark(img: np.ndarray) -> np.ndarray:
    return (img < DARK).all(axis=2)


def test_a_caption_too_long_for_its_tile_is_made_smaller_not_clipped():
    text = "LiDAR beta0.03: lost 0%, clutter 9%"
    assert cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.7, 1)[0][0] > 256 - 12  # the old caption overflowed
    scale = fitted_scale(text, 256 - 12, 0.7)
    assert cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0] <= 256 - 12
    bar = label(np.zeros((10, 256, 3), np.uint8), text)[:28]
    cols = np.flatnonzero(_dark(bar).any(axis=0))
    assert cols.min() >= 4 and cols.max() <= 256 - 4  # the whole text inside, margins on both sides
    short = "clear"
    assert fitted_scale(short, 256, 0.7) == 0.7


def test_ring_labels_sit_where_each_ring_meets_the_ray():
    img = np.full((400, 400, 3), 255, np.uint8)
    ring_labels(img, (200, 200), [10, 20], px_per_m=8.0, angle_deg=0.0)
    for r in (10, 20):  # "10 m" centred on (200 + 8 r, 200)
        x = 200 + 8 * r
        assert _dark(img[190:210, x - 20:x + 20]).sum() > 20, r
    assert _dark(img).sum() == _dark(img[185:215, 250:400]).sum()  # nothing drawn anywhere else
    ring_labels(img := np.full((50, 50, 3), 255, np.uint8), (25, 25), [100], px_per_m=8.0)
    assert not _dark(img).any()  # a ring outside the picture: no label


def test_the_legend_shows_each_colour_with_its_words_and_wraps():
    entries = [("dot", (44, 160, 44), "kept"), ("ring", (150, 150, 150), "removed by the fog"),
               ("box", (60, 60, 60), "box")]
    row = legend_row(entries, 600)
    assert row.shape == (20, 600, 3)
    for colour in ((44, 160, 44), (150, 150, 150), (60, 60, 60)):
        assert (row == colour).all(axis=2).any(), colour
    assert legend_row(entries * 6, 300).shape[0] > 20  # too many for one line: more lines, nothing cut
    with pytest.raises(ValueError, match="swatch"):
        legend_row([("star", (0, 0, 0), "x")], 100)


def _scan():
    rng = np.random.default_rng(0)
    xyz = (rng.uniform(-30, 30, (3000, 3)) * [1, 1, 0.05]).astype(np.float32)
    return PointCloud.from_raw(xyz, np.full(len(xyz), 0.3), "0-1", "test")


def test_the_lidar_birds_eye_views_carry_their_legend_and_ring_distances():
    scan = _scan()
    view = bev_image(scan, None, extent_m=40.0, px_per_m=5.0)
    centre, a = 200, math.radians(-35)
    for r in (10, 20, 30, 40):  # each ring's distance, where the ring meets the -35° ray
        x, y = round(centre + 5 * r * math.cos(a)), round(centre - 5 * r * math.sin(a))
        patch = view[y - 8:y + 8, x - 16:x + 16]
        assert _dark(patch).sum() > 10 and (patch == 255).all(axis=2).sum() > 100, r  # text on its white patch
    levels = bev_levels(scan, {"clear": None}, width=300, extent_m=40.0)
    assert levels.shape[1] == 300 and levels.shape[0] >= 28 + 300 + 20  # caption, the view drawn at 300 px, legend
    legend = levels[28 + 300:]
    for _, colour, _ in BEV_LEGEND[:4]:
        assert (legend == colour).all(axis=2).any(), colour
    assert {OUTCOME_COLOURS[k] for k in OUTCOME_COLOURS} <= {c for _, c, _ in BEV_LEGEND}


def test_the_radar_picture_says_what_fog_costs_radar_and_light():
    levels = {"clear": {"beta": 0.0, "attenuation_db_per_km": 0.0, "frequency_ghz": 76.5},
              "beta0.06": {"beta": 0.06, "attenuation_db_per_km": 1.1, "frequency_ghz": 76.5},
              "beta0.12": {"beta": 0.12, "attenuation_db_per_km": 2.5, "frequency_ghz": 76.5}}
    note = fog_note(levels)
    radar_db = 2 * 2.5 * 100 / 1000  # 2 γ R, the densest level, 100 m
    light_db = 10 * math.log10(math.exp(2 * 0.12 * 100))  # exp(-2 β R) in dB
    assert "at beta 0.12/m" in note and f"loses {radar_db:.1f} dB" in note and f"light {light_db:.0f} dB" in note
    assert note.startswith("76.5 GHz radar") and "barely attenuates radar" in note
    assert fog_note({"clear": levels["clear"]}) is None
    img = radar_bev_image(np.array([[30.0, 0.0, 0.0]]), np.array([0]), np.array([True]))
    assert (img == KIND_COLOURS[0]).all(axis=2).any()
    assert _dark(img[:, img.shape[1] // 2 + 5:]).sum() > 200  # the ring distances, right of the centre line
    assert {KIND_COLOURS[k] for k in KIND_COLOURS} <= {c for _, c, _ in RADAR_LEGEND}

"""The quality preset → Cycles settings, without Blender: every default comes from the schema."""
import json

import pytest

from fogsim.render.preset import load_render_preset
from fogsim.render.quality import FIXED, cycles_settings
from fogsim.schema.presets import Bounces, Quality


def test_a_quality_that_omits_transparent_bounces_renders_with_the_schemas_8():
    s = cycles_settings({"samples": 8, "bounces": {"total": 6}})
    assert s["transparent_max_bounces"] == Bounces().transparent == 8
    assert s["max_bounces"] == 6 and s["samples"] == 8
    assert s["diffuse_bounces"] == Bounces().diffuse


def test_every_preset_key_reaches_its_cycles_setting():
    q = {"samples": 64, "adaptive_threshold": 0.02, "denoise": False, "denoise_quality": "FAST",
         "denoise_prefilter": "NONE",
         "bounces": {"total": 9, "diffuse": 3, "glossy": 5, "transmission": 7, "transparent": 11}}
    s = cycles_settings(q)
    assert s == {"samples": 64, "use_adaptive_sampling": True, "adaptive_threshold": 0.02, "use_denoising": False,
                 "denoising_quality": "FAST", "denoising_prefilter": "NONE", "max_bounces": 9, "diffuse_bounces": 3,
                 "glossy_bounces": 5, "transmission_bounces": 7, "transparent_max_bounces": 11, **FIXED}


def test_an_empty_quality_is_the_schemas_defaults():
    s, q = cycles_settings({}), Quality()
    assert (s["samples"], s["use_denoising"], s["use_adaptive_sampling"]) == (q.samples, q.denoise, False)


def test_a_bad_quality_names_the_key():
    with pytest.raises(ValueError, match="quality.bounces.transparent"):
        cycles_settings({"bounces": {"transparent": -1}})


def test_the_render_config_hands_readers_the_checked_blocks(tmp_path):
    preset = tmp_path / "p.json"
    preset.write_text(json.dumps({"style": "suburban", "camera": "waymo-front",
                                  "quality": {"samples": 4, "bounces": {"total": 2}}, "labels": {"min_pixels": 7}}))
    cfg = load_render_preset(str(preset))
    assert cfg.quality == {"samples": 4, "bounces": {"total": 2}}  # as given: render_run.json reads like the preset
    assert cfg.quality_settings.bounces.transparent == 8
    assert cfg.label_settings.min_pixels == 7 and cfg.label_settings.min_visible_fraction == 0.1
    assert cfg.lighting_settings.time_of_day == "day"

"""LiDAR sensors: the bundled presets, custom blocks checked by the schema (one-line errors, defaults from
the schema alone), the radiometry they share, and the fog model's parameter block."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.lidar.sensors import LIGHT_SPEED, LidarSensor, load_sensor, sensor_names
from fogsim.schema.lidar import LidarFogSpec, LidarSensorSpec

CUSTOM = {"beams": 16, "vertical_fov_deg": [-15, 15], "horizontal_resolution_deg": 0.2, "max_range_m": 100,
          "intensity_scale": "0-255"}


def test_the_four_presets_are_bundled_and_read():
    assert sensor_names() == ["hdl32e", "hdl64-s3d", "hdl64e", "waymo-top"]
    kitti = LidarSensor.preset("hdl64e")
    assert kitti.beams == 64 and len(kitti.inclinations_deg) == 64
    assert kitti.inclinations_deg[0] == pytest.approx(1.9367)
    assert kitti.inclinations_deg[-1] == pytest.approx(-24.999201)
    assert kitti.steps_per_sweep == 2000 and kitti.intensity_scale == "0-1"
    assert kitti.mount_pose[2, 3] == pytest.approx(1.73)
    assert kitti.pulse_length_m == pytest.approx(LIGHT_SPEED * 10e-9)
    assert LidarSensor.preset("hdl64-s3d").intensity_scale == "0-255"
    assert LidarSensor.preset("hdl32e").beams == 32
    waymo = LidarSensor.preset("waymo-top")
    assert waymo.inclinations_deg is None and waymo.steps_per_sweep == 2650
    with pytest.raises(ValueError, match="calibration"):
        waymo.inclinations_rad
    given = np.linspace(-0.3, 0.04, 64)
    np.testing.assert_allclose(waymo.with_inclinations(given).inclinations_rad, given)
    with pytest.raises(ValueError, match="64 beams"):
        waymo.with_inclinations(given[:10])


def test_the_hdl64e_lasers_are_kittis_two_blocks():
    """KITTI's HDL-64E S2 factory calibration: 32 upper lasers ≈ 1/3° apart above −8.8°, 32 lower ones ≈ 1/2°
    apart below, each laser's line 0.10–0.21 m off the origin (upper block ≈ 0.2 m, lower ≈ 0.11 m)."""
    s = LidarSensor.preset("hdl64e")
    incl, h = np.asarray(s.inclinations_deg), np.asarray(s.vertical_offsets_m)
    assert np.all(np.diff(incl) < 0) and len(h) == 64  # listed highest first
    upper, lower = incl > -8.8, incl < -8.8
    assert upper.sum() == lower.sum() == 32
    assert np.mean(-np.diff(incl[upper])) == pytest.approx(1 / 3, abs=0.02)
    assert np.mean(-np.diff(incl[lower])) == pytest.approx(1 / 2, abs=0.02)
    assert np.all((h[upper] > 0.19) & (h[upper] < 0.21)) and np.all((h[lower] > 0.10) & (h[lower] < 0.13))
    assert "KITTI" in s.sources["inclinations_deg"] and "vertOffsetCorrection" in s.sources["vertical_offsets_m"]
    assert s.to_dict()["vertical_offsets_m"] == list(h)
    assert LidarSensor.preset("waymo-top").with_inclinations(np.zeros(64)).vertical_offsets_m is None
    with pytest.raises(ValueError, match="vertical_offsets_m"):
        LidarSensor.from_dict({**CUSTOM, "vertical_offsets_m": [0.1, 0.2]})


def test_defaults_come_from_the_schema_alone():
    custom = LidarSensor.from_dict(CUSTOM)
    for key in ("min_range_m", "reference_reflectivity", "pulse_half_power_ns", "overlap_full_m", "range_noise_m",
                "range_noise_at_threshold_m", "return_mode", "reflectivity_per_intensity", "intensity_range_exponent"):
        assert getattr(custom, key) == LidarSensorSpec.model_fields[key].default, key
    assert custom.name == "custom" and custom.steps_per_sweep == 1800
    assert custom.mount_xyz_m == (0.0, 0.0, 0.0)
    d = dict(CUSTOM, inclinations_deg=[float(v) for v in range(16)])
    del d["vertical_fov_deg"]
    assert LidarSensor.from_dict(d).inclinations_deg == tuple(float(v) for v in range(16))


@pytest.mark.parametrize("change,message", [
    ({"beams": 0}, "beams: must be an integer in [1, 1024]"),
    ({"colour": "red"}, "unknown key"),
    ({"inclinations_deg": [1.0, 2.0]}, "exactly one of 'vertical_fov_deg'"),
    ({"steps_per_sweep": 100}, "exactly one of 'horizontal_resolution_deg'"),
    ({"intensity_scale": "0-100"}, "intensity_scale: must be one of 0-1, 0-255, tanh"),
    ({"min_range_m": 90, "max_range_m": 50}, "must be below max_range_m"),
    ({"max_range_m": "far"}, "max_range_m: must be a finite number"),
])
def test_a_bad_custom_block_is_one_line(change, message):
    with pytest.raises(ValueError) as e:
        LidarSensor.from_dict(dict(CUSTOM, **change))
    assert message in str(e.value) and "\n" not in str(e.value)


def test_a_custom_sensor_file_names_itself(tmp_path):
    good = tmp_path / "mine.json"
    good.write_text(json.dumps(dict(CUSTOM, name="mine")))
    assert load_sensor(good).name == "mine" and load_sensor(str(good)).beams == 16
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(dict(CUSTOM, beams=-1)))
    with pytest.raises(InputError) as e:
        load_sensor(bad)
    assert str(e.value).startswith(str(bad)) and "beams" in str(e.value)
    with pytest.raises(ValueError, match="unknown LiDAR sensor 'hdl128'"):
        load_sensor("hdl128")
    assert load_sensor(CUSTOM).beams == 16


def test_the_threshold_is_calibrated_by_the_maximum_range():
    s = LidarSensor.preset("hdl64e")
    # the reference target at the maximum range is exactly at the threshold; twice as far, a quarter
    assert s.clear_signal(s.reference_reflectivity, s.max_range_m) == pytest.approx(1.0)
    assert s.clear_signal(s.reference_reflectivity, 2 * s.max_range_m) == pytest.approx(0.25)
    # the overlap: (R / R_o)² below R_o, then 1 — so near targets are not infinitely bright
    ro = s.overlap_full_m
    assert s.overlap(0.5 * ro) == pytest.approx(0.25) and s.overlap(1.4 * ro) == 1.0
    assert s.clear_signal(s.reference_reflectivity, 1.0) == pytest.approx((120.0 / ro) ** 2)
    # intensity ↔ reflectivity (KITTI's 0–1: ρ = 0.4·I, no range term) and a range-corrected custom sensor
    assert s.reflectivity_of(0.5, 40.0) == pytest.approx(0.2) and s.intensity_of(0.2, 7.0) == pytest.approx(0.5)
    raw = LidarSensor.from_dict(dict(CUSTOM, intensity_range_exponent=2.0, intensity_reference_range_m=10.0,
                                     reflectivity_per_intensity=0.5))
    assert raw.reflectivity_of(0.4, 20.0) == pytest.approx(0.5 * 0.4 * 4.0)
    assert raw.intensity_of(raw.reflectivity_of(0.4, 20.0), 20.0) == pytest.approx(0.4)


def test_mount_pose_is_rz_ry_rx():
    s = LidarSensor.from_dict(dict(CUSTOM, mount={"xyz_m": [1, 2, 3], "rpy_deg": [0, 0, 90]}))
    m = s.mount_pose
    np.testing.assert_allclose(m[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(m[:3, 3], [1, 2, 3])
    pitch = LidarSensor.from_dict(dict(CUSTOM, mount={"rpy_deg": [0, 10, 0]})).mount_pose
    assert pitch[0, 2] == pytest.approx(math.sin(math.radians(10)))


def test_the_fog_spec_block():
    spec = LidarFogSpec()
    assert spec.model == "soft-target" and spec.extinction_ratio == 1.0 and spec.return_mode is None
    assert spec.backscatter_coefficient == 0.046 and spec.lidar_ratio_sr == pytest.approx(math.log(20) / 0.046)
    with pytest.raises(Exception, match="model"):
        LidarFogSpec.model_validate({"model": "hahner"})
    assert LidarFogSpec.model_validate({"return_mode": "last"}).return_mode == "last"

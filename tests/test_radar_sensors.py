"""fogsim.radar.sensors: the bundled radars (every parameter sourced), the radar equation against its
linear form, and the threshold's calibration."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.radar.sensors import BOLTZMANN, T0_K, RadarSensor, load_radar_sensor, radar_sensor_names
from fogsim.schema.radar import BOOKKEEPING


def test_bundled_sensors_load_with_a_source_for_every_parameter():
    assert {"ars408-lr", "srr-corner"} <= set(radar_sensor_names())
    for name in radar_sensor_names():
        s = RadarSensor.preset(name)
        from fogsim.presets import presets_dir

        doc = json.loads((presets_dir() / "radar" / f"{name}.json").read_text())
        for key in doc:
            if key not in BOOKKEEPING:
                assert key in doc["sources"], (name, key)
        assert s.sources == doc["sources"]
    ars = RadarSensor.preset("ars408-lr")
    assert ars.frequency_ghz == pytest.approx(76.5) and ars.max_range_m == 250 and ars.azimuth_fov_deg == (-9, 9)
    assert ars.near_range["azimuth_fov_deg"] == [-60, 60] and not ars.measures_elevation


def test_a_parameter_without_a_source_is_refused(tmp_path):
    from fogsim.presets import presets_dir

    doc = json.loads((presets_dir() / "radar" / "ars408-lr.json").read_text())
    del doc["sources"]["noise_figure_db"]
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="noise_figure_db") as err:
        load_radar_sensor(path)
    assert str(path) in str(err.value)
    with pytest.raises(ValueError, match="unknown radar sensor"):
        load_radar_sensor("nope")


def test_radar_equation_is_the_linear_formula_and_the_calibration_holds():
    s = RadarSensor.preset("ars408-lr")
    # calibrated: the reference target at the maximum range is exactly at the threshold
    assert s.snr_db(s.reference_rcs_dbsm, s.max_range_m) == pytest.approx(s.detection_threshold_db, abs=1e-9)
    assert s.max_range_for(s.reference_rcs_dbsm) == pytest.approx(s.max_range_m)
    # the linear radar equation, written out: Pt Gt Gr λ² σ / ((4π)³ R⁴ k T0 B F) · Gp
    lam = 299_792_458.0 / 76.5e9
    pt = 10 ** ((s.transmit_power_dbm - 30) / 10)
    g = 10 ** ((s.tx_gain_dbi + s.rx_gain_dbi) / 10)
    for rcs_db, r in ((10.0, 250.0), (-5.0, 40.0), (20.0, 3.0)):
        snr = (pt * g * lam ** 2 * 10 ** (rcs_db / 10) / ((4 * math.pi) ** 3 * r ** 4
               * BOLTZMANN * T0_K * s.noise_bandwidth_mhz * 1e6 * 10 ** (s.noise_figure_db / 10))
               * 10 ** (s.processing_gain_db / 10))
        assert s.snr_db(rcs_db, r) == pytest.approx(10 * math.log10(snr), abs=1e-9)
    # 40 dB per decade of range, 1 dB per dB of RCS
    assert s.snr_db(0, 10) - s.snr_db(0, 100) == pytest.approx(40)
    assert s.snr_db(3, 50) - s.snr_db(0, 50) == pytest.approx(3)
    given = load_radar_sensor({**_spec_of(s), "processing_gain_db": 40.0,
                               "sources": {**s.sources, "processing_gain_db": "test"}})
    assert given.processing_gain_db == 40.0
    assert given.snr_db(0, 10) - s.snr_db(0, 10) == pytest.approx(40.0 - s.processing_gain_db)


def _spec_of(s: RadarSensor) -> dict:
    from fogsim.presets import presets_dir

    doc = json.loads((presets_dir() / "radar" / "ars408-lr.json").read_text())
    return {k: v for k, v in doc.items() if k != "sources"}


def test_field_of_view_far_and_near():
    s = RadarSensor.preset("ars408-lr")
    r = np.array([200.0, 200.0, 50.0, 50.0, 100.0])
    az = np.radians([5.0, 20.0, 20.0, 59.0, 30.0])
    assert s.in_view(r, az).tolist() == [True, False, True, True, False]
    assert s.sweep_bandwidth_mhz == pytest.approx(299_792_458.0 / (2 * 1.79) / 1e6)  # ≈ 84 MHz far scan

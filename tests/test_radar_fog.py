"""fogsim.radar.fog and .attenuation: ITU-R P.840 attenuation (itur, and the Recommendation's formula
written out here), Kunkel's liquid water against P.840's guide values, the SNR threshold per detection,
β = 0 bit for bit, continuity in β, and the share a realistic sweep keeps in the paper's thickest fog."""
from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from fogsim.bench.radar import synthetic_sweep
from fogsim.cli import main
from fogsim.errors import InputError, MissingDependency
from fogsim.fog.engine import FogSettings
from fogsim.radar.attenuation import attenuation_db_per_km, liquid_water_coefficient, lwc_from_beta
from fogsim.radar.detections import RadarScan
from fogsim.radar.fog import KEPT, LOST, RadarFogger
from fogsim.radar.outcome_file import read_radar_outcomes, write_radar_outcomes
from fogsim.radar.sensors import RadarSensor

itur = pytest.importorskip("itur")


def p840_k_l(f_ghz: float, t_c: float) -> float:
    """K_l of ITU-R P.840 written from the Recommendation's text (double-Debye permittivity of water)."""
    theta = 300.0 / (t_c + 273.15)
    e0 = 77.66 + 103.3 * (theta - 1)
    e1, e2 = 0.0671 * e0, 3.52
    fp = 20.20 - 146 * (theta - 1) + 316 * (theta - 1) ** 2
    fs = 39.8 * fp
    e_im = f_ghz * (e0 - e1) / (fp * (1 + (f_ghz / fp) ** 2)) + f_ghz * (e1 - e2) / (fs * (1 + (f_ghz / fs) ** 2))
    e_re = (e0 - e1) / (1 + (f_ghz / fp) ** 2) + (e1 - e2) / (1 + (f_ghz / fs) ** 2) + e2
    eta = (2 + e_re) / e_im
    return 0.819 * f_ghz / (e_im * (1 + eta ** 2))


def realistic_sweep(seed: int = 3, n: int = 4000) -> RadarScan:
    """An ARS 408-like far-range sweep drawn from the radar equation (cars, pedestrians, poles and rails at
    1–250 m within ±9°, only what clears the threshold in clear air; SNR unknown as in a real file)."""
    return synthetic_sweep(n, seed)


def test_k_l_is_itur_and_the_recommendation():
    for f, t in ((76.5, 10.0), (77.0, 0.0), (79.0, 20.0), (24.0, 10.0)):
        k = liquid_water_coefficient(f, t)
        assert k == pytest.approx(float(itur.models.itu840.specific_attenuation_coefficients(f, t)), rel=1e-12)
        assert k == pytest.approx(p840_k_l(f, t), rel=2e-3)


def test_attenuation_at_77_ghz_equals_p840_for_the_stated_lwc():
    sensor = RadarSensor.preset("ars408-lr")
    s77 = RadarSensor.from_dict({**_doc("ars408-lr"), "frequency_ghz": 77.0})
    scan = realistic_sweep()
    for lwc in (0.05, 0.5):
        fogged = RadarFogger(scan, s77, {"lwc_g_m3": lwc})(0.05)
        want = float(itur.models.itu840.specific_attenuation_coefficients(77.0, 10.0)) * lwc
        assert fogged.parameters["attenuation_db_per_km"] == pytest.approx(want, rel=1e-12)
        assert fogged.parameters["lwc_g_m3"] == lwc
    # from β through Kunkel: γ = K_l(76.5 GHz, 10 °C) · (1000 β / 144.7)^(1/0.88)
    b = 0.12
    m = (1000 * b / 144.7) ** (1 / 0.88)
    assert attenuation_db_per_km(b, sensor.frequency_ghz) == pytest.approx(p840_k_l(76.5, 10.0) * m, rel=2e-3)


def _doc(name: str) -> dict:
    import json

    from fogsim.presets import presets_dir
    return json.loads((presets_dir() / "radar" / f"{name}.json").read_text())


def test_kunkel_gives_p840_guide_values():
    # P.840: M ≈ 0.05 g/m³ for medium fog (visibility ≈ 300 m), ≈ 0.5 g/m³ for thick fog (≈ 50 m)
    assert 0.035 <= float(lwc_from_beta(math.log(20) / 300)) <= 0.07
    assert 0.3 <= float(lwc_from_beta(math.log(20) / 50)) <= 0.6
    assert float(lwc_from_beta(0.0)) == 0.0


def test_clear_air_is_the_input_bit_for_bit():
    scan = realistic_sweep()
    fogged = RadarFogger(scan, "ars408-lr")(0.0)
    assert fogged.scan.same_as(scan) and fogged.scan.xyz is not scan.xyz
    assert (fogged.outcome == KEPT).all() and np.array_equal(fogged.output_index, np.arange(len(scan)))


def test_threshold_per_detection_matches_a_loop():
    scan = realistic_sweep(seed=5, n=600)
    s = RadarSensor.preset("ars408-lr")
    beta = 0.12
    k = float(itur.models.itu840.specific_attenuation_coefficients(s.frequency_ghz, 10.0))
    gamma = k * (1000 * beta / 144.7) ** (1 / 0.88)
    fogged = RadarFogger(scan, s)(beta)
    for i in range(len(scan)):
        r = math.sqrt(sum(float(c) ** 2 for c in scan.xyz[i]))
        snr = max(float(s.snr_db(float(scan.rcs_dbsm[i]), r)), s.detection_threshold_db)
        keep = snr - 2 * gamma * r / 1000 >= s.detection_threshold_db
        assert fogged.outcome[i] == (KEPT if keep else LOST), i
    kept = fogged.outcome == KEPT
    assert fogged.scan.same_as(scan.select(np.flatnonzero(kept)))
    assert (fogged.output_index[~kept] == -1).all()
    assert np.array_equal(fogged.output_index[kept], np.arange(kept.sum()))


def test_given_snr_is_used_and_weak_far_detections_go_first():
    s = RadarSensor.preset("ars408-lr")
    r = np.array([50.0, 200.0, 200.0, 240.0])
    scan = RadarScan.checked(np.stack([r, np.zeros(4), np.zeros(4)], 1), np.zeros(4),
                             snr_db=[13.4, 13.2, 20.0, 13.5])
    fogged = RadarFogger(scan, s)(0.12)  # 2·γ·R: 0.25 dB at 50 m, 1.0 dB at 200 m, 1.2 dB at 240 m
    assert fogged.outcome.tolist() == [KEPT, LOST, KEPT, LOST]


def test_realistic_sweep_keeps_95_percent_within_100_m_at_visibility_25_m():
    scan = realistic_sweep()
    near = scan.range_m <= 100
    fogged = RadarFogger(scan, "ars408-lr")(0.12)
    share = float((fogged.outcome[near] == KEPT).mean())
    assert near.sum() > 500 and share >= 0.95
    far = ~near
    assert (fogged.outcome[far] == LOST).mean() > (fogged.outcome[near] == LOST).mean()  # the far ones go first


def test_continuity_in_beta():
    scan = realistic_sweep(seed=11)
    fogger = RadarFogger(scan, "ars408-lr")
    betas = np.linspace(0, 0.2, 81)
    kept = [int((fogger(b).outcome == KEPT).sum()) for b in betas]
    assert kept[0] == len(scan) and all(a >= b for a, b in zip(kept, kept[1:]))  # monotone
    assert fogger(1e-9).counts()["kept"] == len(scan)  # no jump just above clear air
    # the SNR in fog is Lipschitz in M: |Δs| ≤ 2·K_l·R_max/1000·|ΔM|
    k = fogger.k_l
    for b0, b1 in zip(betas[1:], betas[2:]):
        ds = np.abs(fogger.snr_in_fog(b1) - fogger.snr_in_fog(b0)).max()
        dm = float(lwc_from_beta(b1) - lwc_from_beta(b0))
        assert ds <= 2 * k * fogger.range_m.max() / 1000 * dm * (1 + 1e-9)
    # one β per detection, all equal, is the scalar
    assert np.array_equal(fogger(np.full(len(scan), 0.09)).outcome, fogger(0.09).outcome)


def test_fog_record_carries_the_radar_block():
    fog = FogSettings(radar={"temperature_c": 0.0})
    assert fog.record()["radar_fog"]["temperature_c"] == 0.0
    fogged = fog.radar_fogger(realistic_sweep(n=200), "ars408-lr")(0.06)
    assert fogged.parameters["temperature_c"] == 0.0
    assert fogged.parameters["k_l_db_per_km_per_g_m3"] == pytest.approx(liquid_water_coefficient(76.5, 0.0))
    with pytest.raises(ValueError, match="radar_fog.*temperature"):
        FogSettings(radar={"temperature_c": 99})
    assert "radar_fog" not in FogSettings().record()


def test_outcome_file_round_trips_and_refuses_a_tampered_one(tmp_path):
    fogged = RadarFogger(realistic_sweep(n=300), "ars408-lr")(0.12)
    path = tmp_path / "s.outcomes.npz"
    write_radar_outcomes(path, fogged)
    outcome, index, snr = read_radar_outcomes(path)
    assert np.array_equal(outcome, fogged.outcome) and np.array_equal(index, fogged.output_index)
    assert np.array_equal(snr, fogged.snr_fog_db)
    bad = tmp_path / "bad.outcomes.npz"
    np.savez(bad, outcome=fogged.outcome, output_index=fogged.output_index + 1, snr_fog_db=fogged.snr_fog_db)
    with pytest.raises(InputError, match="output rows"):
        read_radar_outcomes(bad)


def test_missing_itur_says_which_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "itur", None)
    liquid_water_coefficient.cache_clear()
    try:
        with pytest.raises(MissingDependency, match=r"fogsim\[radar\]"):
            liquid_water_coefficient(33.3, 10.0)
    finally:
        liquid_water_coefficient.cache_clear()


def test_the_benchmark_runs(capsys):
    assert main(["bench", "radar", "--repeat", "1", "--detections", "3000", "--sweeps", "3",
                 "--loop-detections", "40"]) == 0
    out = capsys.readouterr().out
    assert "loop, itur per detection" in out and out.strip().splitlines()[-1].startswith("bench radar: ")


def test_an_empty_sweep_stays_empty(tmp_path):
    from fogsim.radar.formats import read_radar, write_radar

    fogged = RadarFogger(RadarScan.empty(), "ars408-lr")(0.12)
    assert len(fogged.scan) == 0 and fogged.counts() == {"kept": 0, "lost": 0}
    write_radar(tmp_path / "e.pcd", fogged.scan)
    assert len(read_radar(tmp_path / "e.pcd")) == 0
    assert fogged.parameters["k_l_from"].startswith("ITU-R P.840 via itur ")

"""What road_height_est estimates on a real road (harness.metrics.reference_profile), the honesty of
road_height_std there, and the excitation report of the sprung mass (mass_std)."""
from __future__ import annotations

import numpy as np
import pytest

from suspension_estimation.estimators import SuspensionEstimator
from suspension_estimation.estimators.model import IZR, RoadModel
from suspension_estimation.estimators.steady_state import reference_highpass, reference_lag, road_transfer
from suspension_estimation.harness import metrics
from suspension_estimation.harness.cosim import CoSimulation, System
from suspension_estimation.harness.testroads import add_bump, add_pothole, add_sag, joined_iso, write_profile
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

WIRES = ("acc_sprung", "acc_unsprung", "susp_deflection")
# the estimator told its sensors are calibrated, as the plant's are: road_height_std then
# describes the filter alone, without the allowance for untold gain and delay errors
CALIBRATED = {"calibration_gain_std": 0.0, "calibration_delay_std": 0.0}


@pytest.mark.parametrize("kmh", [40.0, 72.0])
def test_the_lag_correction_brings_the_filter_onto_the_reference(kmh):
    """The road filter's own transfer T(f) misses HP(f) below the band by about q / s
    (steady_state.reference_lag, the rate KFRoad.lag_rate adds back to z_s_est and
    z_u_est); T (1 + q / s) is within 1 % of HP(f) (relative) from 0.005 to 0.3 Hz, and at least
    twice as close as T alone below 0.02 Hz."""
    est = SuspensionEstimator(mass_estimator=0, road_class=2)
    for _ in range(200):
        est.step(0.0, 0.0, 0.0, kmh / 3.6, 1e-3)
    kf, m = est.anchor, est.anchor_model
    K, _ = kf.stationary_solution
    rm = RoadModel()
    q = reference_lag(m.Phi, m.H, K, m.h, rm.f_ref, rm.zeta_ref, DEFAULT_VEHICLE, est.acc_sampling, IZR)
    assert q == est.road.lag_rate() and q > 0
    f = np.geomspace(0.005, 0.3, 20)
    T = road_transfer(m.Phi, m.H, K, m.h, f, DEFAULT_VEHICLE, est.acc_sampling, IZR)
    hp = reference_highpass(f, rm.f_ref, rm.zeta_ref)
    corrected, alone = np.abs(T * (1 + q / (2j * np.pi * f)) / hp - 1), np.abs(T / hp - 1)
    assert corrected.max() < 0.01
    low = f < 0.02
    assert corrected[low].max() < 0.5 * alone[low].max()


def _closed_loop(dist, profile, kmh: float, seconds: float, road_class: int = 0, seed: int = 1,
                 mass: float = 410.0, estimator: dict | None = None):
    comps = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu", "e": dist / "SuspensionEstimator.fmu"}
    conn = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height"),
            ("vehicle_speed", "e.vehicle_speed")] + [(f"plant.{w}", f"e.{w}") for w in WIRES]
    par = {"plant.noise_seed": seed, **{f"e.{k}": v for k, v in (estimator or {}).items()}}
    if profile is not None:
        par["road.profile_file"] = str(profile)
    else:
        par.update({"road.road_class": road_class, "road.seed": seed})
    with CoSimulation(System(comps, conn), parameters=par, inputs={"vehicle_speed": kmh / 3.6, "plant.sprung_mass": mass},
                      record=["road.road_height", "road.distance", "e.road_height_est", "e.road_height_std",
                              "e.sprung_mass_est", "e.mass_std"]) as sim:
        return sim.run(round(seconds / 1e-3) * 1e-3, 1e-3)


def _coverage(rec) -> tuple[float, float, float]:
    """(2-sigma coverage against the profile, rms error / rms std, coverage against the absolute
    road) after the warm-up."""
    t, est, std, road = rec["time"], rec["e.road_height_est"], rec["e.road_height_std"], rec["road.road_height"]
    keep = t >= metrics.warmup_for(t)
    e = (est - metrics.reference_profile(rec["road.distance"], road))[keep]
    s = std[keep]
    return (float(np.mean(np.abs(e) <= 2 * s)), float(np.sqrt(np.mean(e ** 2) / np.mean(s ** 2))),
            float(np.mean(np.abs(est - road)[keep] <= 2 * s)))


def test_road_std_is_honest_on_vertical_curves_at_an_absolute_level(dist, tmp_path):
    """Through the FMUs at 72 km/h, ISO B with a 2 m sag over 300 m, a 0.5 m crest over 100 m and
    a 1 m sag over 150 m, 583 m above the datum, the estimator told its sensors are calibrated:
    +-2 road_height_std covers most of the errors against the profile, the std is the size of the
    error, and the absolute road is not what is estimated (it is covered nowhere). Noise seeds
    1-4: coverage 0.78-0.82, rms error / rms std 1.48-1.65 (0.15-0.16 mm against 0.098 mm);
    the same road without the curves 0.93 and 1.11. The excess is in the crest and the short
    sag (0.22 mm rms there, coverage 0.52-0.61, no long-wave flag); with the default allowance
    for calibration errors the std is 0.51 mm and covers every error."""
    s, h = joined_iso([2], [600.0], seed=3)
    h = add_sag(s, h, 50.0, 300.0, 2.0)
    h = add_sag(s, add_sag(s, h, 380.0, 100.0, -0.5), 440.0, 150.0, 1.0)
    rec = _closed_loop(dist, write_profile(tmp_path / "curves.csv", s, h, level=583.0), 72.0, 29.0,
                       estimator=CALIBRATED)
    cov, ratio, cov_abs = _coverage(rec)
    assert cov > 0.7 and 0.5 < ratio < 2.0, (cov, ratio)
    assert cov_abs < 0.05


def test_road_std_is_honest_on_a_grade_with_a_bump_and_a_pothole(dist, tmp_path):
    """Through the FMUs at 72 km/h, ISO B on a 3 % grade from the start with a 30 mm bump (0.5 m)
    and a 30 mm pothole (0.4 m), four sensor-noise seeds, the estimator told its sensors are
    calibrated: the grade is not in the estimate, the events are (within 3 m of each the error
    stays below 5 % of its 30 mm), and +-2 road_height_std covers most of the errors. Seeds 1-6:
    coverage 0.905-0.937, rms error / rms std 1.09-1.20 (0.11 mm against 0.098 mm); near the
    events at most 0.37-0.53 mm, which is 3.7-5.4 std: the std is that of the road's roughness,
    not of a discrete event."""
    s, h = joined_iso([2], [600.0], seed=4)
    h = add_pothole(s, add_bump(s, h + 0.03 * s, 250.0, 0.5, 0.03), 400.0, 0.4, 0.03)
    profile = write_profile(tmp_path / "grade.csv", s, h)
    ratios = []
    for seed in range(1, 5):
        rec = _closed_loop(dist, profile, 72.0, 29.0, seed=seed, estimator=CALIBRATED)
        cov, ratio, cov_abs = _coverage(rec)
        assert cov > 0.85 and cov_abs < 0.05, (seed, cov, cov_abs)
        ratios.append(ratio)
        d = rec["road.distance"]
        e = np.abs(rec["e.road_height_est"] - metrics.reference_profile(d, rec["road.road_height"]))
        for at in (250.0, 400.0):
            assert e[np.abs(d - at) < 3.0].max() < 0.05 * 0.03, (seed, at)
    pooled = float(np.sqrt(np.mean(np.square(ratios))))
    assert 0.7 < pooled < 1.5, ratios


def test_mass_std_reports_the_excitation(dist):
    """Through the FMUs at 40 km/h, 410 kg: on ISO A the regressor (the body acceleration) is 4
    times smaller in amplitude than on ISO C (Gd(n0) 16 times smaller) and the sensor noise the
    same, so mass_std is about 4 times as large; on both, the mass is
    within +-1 % or mass_std says it cannot be (2 mass_std > 1 %) at least 90 % of the time, and
    2 mass_std covers most of the errors."""
    out = {}
    for cls in (1, 3):
        rec = _closed_loop(dist, None, 40.0, 20.0, road_class=cls, seed=5)
        keep = rec["time"] >= 5.0
        m, sd = rec["e.sprung_mass_est"][keep], rec["e.mass_std"][keep]
        err = np.abs(m - 410.0)
        ok = (err <= 0.01 * 410.0) | (2 * sd > 0.01 * m)
        assert ok.mean() > 0.9 and (err <= 2 * sd).mean() > 0.8, (cls, ok.mean(), (err <= 2 * sd).mean())
        out[cls] = float(np.sqrt(np.mean(sd ** 2)))
    assert 2.5 < out[1] / out[3] < 6.0, out


def test_a_road_that_does_not_excite_holds_the_mass(dist, tmp_path):
    """Through the FMUs at 72 km/h on a flat road (the sensors give their noise only), 500 kg
    against the nominal 410: the mass cannot be identified, so the estimate holds the nominal
    and mass_std says so (2 mass_std above the 90 kg error); before, least squares fitted noise
    to noise and the mass fell to its 41 kg bound within 15 s. The road stays within its std (told
    the sensors are calibrated; noise seeds 1-3: coverage 0.91-0.96, rms error / rms std
    0.96-1.17)."""
    s = np.arange(0.0, 600.0, 0.25)
    rec = _closed_loop(dist, write_profile(tmp_path / "flat.csv", s, 0.0 * s), 72.0, 20.0, mass=500.0,
                       estimator=CALIBRATED)
    keep = rec["time"] >= 5.0
    m, sd = rec["e.sprung_mass_est"][keep], rec["e.mass_std"][keep]
    assert np.abs(m - 410.0).max() < 0.01 * 410.0, (m.min(), m.max())
    assert (2 * sd > np.abs(m - 500.0)).all(), sd.min()
    cov, ratio, _ = _coverage(rec)
    assert cov > 0.85 and 0.5 < ratio < 2.0, (cov, ratio)

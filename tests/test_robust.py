"""The default estimator (road_estimator 2, suspension-force error state) on a plant that is NOT
its model: plain cores (linear plant with the vehicle off) and one run through the built FMUs.
Loose, seed-robust bounds of the targets; the full grid is ``python -m suspension_estimation.harness paper --study robust``."""
from __future__ import annotations

import numpy as np
import pytest

from suspension_estimation.estimators import SuspensionEstimator
from suspension_estimation.harness.metrics import highpass, reference_profile, road_scores
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE as NOMINAL
from test_estimator_fmu import loop

SPEED = 40 / 3.6  # m/s
H = 1e-3  # s
WARMUP = 4.0  # s


def drive(plant_vehicle, T=14.0, seed=2, road_class=3):
    """(t, measurements, true road) of the linear plant with ``plant_vehicle`` on an ISO road."""
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    car = QuarterCar(plant_vehicle, SensorNoise(), noise_seed=100 + seed)
    n = int(round(T / H))
    meas, zr = np.empty((n, 3)), np.empty(n)
    for k in range(n):
        car.step(road.height(SPEED * k * H), H)
        meas[k], zr[k] = car.measured, car.road
    return np.arange(1, n + 1) * H, meas, zr


def scores(t, est, zr, std=None):
    """harness.metrics.road_scores of ``est`` against the true road ``zr`` sampled at t (s) at SPEED."""
    return road_scores(t, est, zr, std, warmup=WARMUP, distance=SPEED * t)


def estimate(meas, **kw):
    """Road estimate, its std and the mass estimate of an estimator told the nominal vehicle."""
    est = SuspensionEstimator(**kw)
    out = np.array([[o["road_height_est"], o["road_height_std"], o["sprung_mass_est"]]
                    for o in (est.step(z[0], z[1], z[2], SPEED, H) for z in meas)])
    return out[:, 0], out[:, 1], out[:, 2]


@pytest.fixture(scope="module")
def exact():
    t, meas, zr = drive(NOMINAL)
    new, _, _ = estimate(meas)
    old, _, _ = estimate(meas, road_estimator=0)
    return scores(t, new, zr)["err_std_hp_pct"], scores(t, old, zr)["err_std_hp_pct"]


def test_default_costs_little_on_the_exact_vehicle(exact):
    new, old = exact
    # 14 s, road seeds 1-6: 1.63-1.96 % against 1.65-1.85 % (ratio 0.98-1.12)
    assert new < 1.25 * old, exact


@pytest.mark.parametrize("factors", [{"c_s": 0.7}, {"c_s": 1.3}, {"k_s": 1.15}])
def test_road_holds_when_the_damper_or_spring_is_off(exact, factors):
    """The force-error state takes up F_s - (k_s d + c_s d'); the road follows from the corner's
    force balance. The exact-model KF loses 7-21x its exact-vehicle error in these cases (13-38 %
    HP). Road seeds 1-4, 14 s: HP error 1.16-1.39x the exact vehicle's with c_s -30 %, 0.87-1.03x
    with c_s +30 %, 1.04-1.12x the floor (below) with k_s +15 %; in-band gain 0.998-1.007."""
    t, meas, zr = drive(NOMINAL.with_(**{k: getattr(NOMINAL, k) * f for k, f in factors.items()}))
    road, std, mass = estimate(meas)
    s = scores(t, road, zr, std)
    kf, _, _ = estimate(meas, road_estimator=0)
    s_kf = scores(t, kf, zr)
    bound = 1.5 * exact[0]
    if "k_s" in factors:
        # the mass comes out off by the k_s error and carries it into the m_s a_s / k_t term of
        # the road (benchmarks/identifiability_floor.py): that term, in quadrature, is the floor
        e = abs(factors["k_s"] - 1)
        cut = t >= WARMUP
        truth = highpass(reference_profile(SPEED * t, zr), H)[cut]
        term = 100 * np.std(highpass(e * NOMINAL.m_s * meas[:, 0] / NOMINAL.k_t, H)[cut]) / np.std(truth)
        bound = 1.2 * np.hypot(exact[0], term)
    assert s["err_std_hp_pct"] < bound, (s, exact, bound)
    assert s["err_std_hp_pct"] < 0.5 * s_kf["err_std_hp_pct"], (s, s_kf)
    assert 0.9 < s["gain_hp"] < 1.1
    # the mass: right where k_s is right; k_s / m_s is what the body equation identifies, so a
    # model k_s off by x gives m_s off by x. (The fast RLS estimate [m_s, c] over 10 s scatters
    # ~1-2 %; the study's 60 s runs are within 2 %.)
    m = float(np.mean(mass[t >= WARMUP]))
    expected = NOMINAL.m_s * factors.get("k_s", 1.0) ** -1
    assert abs(m / expected - 1) < 0.03, (m, expected)


def test_road_std_once_the_damping_is_identified_is_that_of_the_right_damping():
    """road_height_std after the anchor is rebuilt at the identified damping equals that of an
    estimator told the plant's damping from the start: the real raw-error variance is computed
    for the anchor's own vehicle. (It was computed for the told c_s: on ISO D at 40 km/h with
    c_s -30 % a std 19 % too large, 2-sigma coverage 0.997 against 0.981 on the exact vehicle.)
    Road seeds 1-3: median ratio 0.999-1.001."""
    plant = NOMINAL.with_(c_s=0.7 * NOMINAL.c_s)
    t, meas, zr = drive(plant, T=12.0, seed=1, road_class=4)
    _, told_nominal, _ = estimate(meas)
    _, told_plant, _ = estimate(meas, c_s=plant.c_s)
    late = t >= 8.0
    ratio = np.median(told_nominal[late]) / np.median(told_plant[late])
    assert abs(ratio - 1) < 0.03, ratio


def test_default_through_the_fmus_holds_a_wrong_damper(dist):
    """Road -> QuarterCar with c_s -30 % -> the default estimator and the exact-model KF, both told
    the contract's default vehicle. Road seeds 1-3, 12 s: HP error 2.1-2.5 % against 36-39 %,
    in-band gain 1.001-1.009, mass within 0.06 %."""
    res = loop(dist, {"default": {}, "kf": {"road_estimator": 0}}, true_mass=410.0, stop=12.0,
               plant={"c_s": 0.7 * NOMINAL.c_s})
    t, truth = res["time"], res["road.road_height"]
    new = scores(t, res["default.road_height_est"], truth)
    old = scores(t, res["kf.road_height_est"], truth)
    assert new["err_std_hp_pct"] < 5.0 and old["err_std_hp_pct"] > 3 * new["err_std_hp_pct"], (new, old)
    assert 0.9 < new["gain_hp"] < 1.1
    assert abs(res["default.sprung_mass_est"][t >= WARMUP].mean() / 410.0 - 1) < 0.02


def test_default_on_the_air_spring_plant_told_only_its_linearisation():
    """Air spring + asymmetric 3:1 damper (plant/nonlinear_car.py), the estimators told the
    static-point linearisation: the exact-model KF drifts away (29-38 % HP, raw error 39-47 mm);
    the default drops its anchor and keeps the force-error filter's road (2.2-2.5 % HP). Road
    seeds 1-4, 14 s."""
    from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER

    seed, n = 1, int(round(14.0 / H))
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=seed)
    car = NonlinearQuarterCar(NOMINAL, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, noise=SensorNoise(), noise_seed=100 + seed)
    meas, zr = np.empty((n, 3)), np.empty(n)
    for k in range(n):
        car.step(road.height(SPEED * k * H), H)
        meas[k], zr[k] = car.measured, car.road
    t = np.arange(1, n + 1) * H
    lin = car.linearisation()
    told = dict(m_u=lin.m_u, k_s=lin.k_s, k_t=lin.k_t, c_s=lin.c_s)
    road, std, _ = estimate(meas, **told)
    new = scores(t, road, zr, std)
    old = scores(t, estimate(meas, road_estimator=0, **told)[0], zr)
    assert new["err_std_hp_pct"] < 5.0 and old["err_std_hp_pct"] > 3 * new["err_std_hp_pct"], (new, old)
    assert 0.9 < new["gain_hp"] < 1.1
    # the low frequencies: the restarting anchor no longer pulls the force-error filter's common
    # velocity (anchored_road.ALIGN_QUIET); road seeds 1-4: raw rms against the profile 0.41 / 0.53 /
    # 0.32 / 0.50 mm, 2-sigma coverage 1.0 (with the pull, against the former time-domain
    # reference: 38 / 264 / 24 mm on seeds 1-3)
    assert new["rmse_raw_mm"] < 2.0 and new["coverage_2sigma"] > 0.9, new
    # the start, before the anchor is dropped (2.4 s here: anchored_road.START_DISAGREE_SPAN): the
    # output is the force-error filter without the pull while the two disagree (the anchor's
    # road was 0.1-0.56 m off in the first 2.4 s when the output was the anchor's). Seeds 1-4:
    # rms error 0.33-0.64 mm over the first 4 s, at most 2.3 mm; road_height_std there carries the
    # raw road gap of the two filters (15-46 mm median, up to 0.9 m), so the coverage is loose
    first = t < 4.0
    e = (road - reference_profile(SPEED * t, zr))[first]
    assert 1e3 * np.sqrt(np.mean(e ** 2)) < 3.0
    assert np.mean(np.abs(e) <= 2 * std[first]) > 0.9


def test_the_std_once_the_anchor_is_dropped_is_the_force_error_filters_times_the_factor():
    """Tuning.nonlinear_std_factor scales road_height_std only where the anchor is dropped (the
    air-spring plant), and never the estimate; on the linear plant it changes nothing. (On ISO D the
    air-spring car's body innovations exceed what the linear model explains, status 3 with its own
    std: the self-diagnosis is set off here, tests/test_sensor_check.py has it.)"""
    from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER

    seed, n = 2, int(round(6.0 / H))
    road = SyntheticRoad(iso8608.class_psd_n0(4), seed=seed)
    car = NonlinearQuarterCar(NOMINAL, DEFAULT_AIR_SPRING, DEFAULT_DAMPER, noise=SensorNoise(), noise_seed=100 + seed)
    meas = np.empty((n, 3))
    for k in range(n):
        car.step(road.height(SPEED * k * H), H)
        meas[k] = car.measured
    lin = car.linearisation()
    told = dict(m_u=lin.m_u, k_s=lin.k_s, k_t=lin.k_t, c_s=lin.c_s)
    runs = {}
    for f in (1.0, 1.2, 3.0):
        est = SuspensionEstimator(nonlinear_std_factor=f, diagnosis_limit=1e6, **told)
        out = np.array([[o["road_height_est"], o["road_height_std"]]
                        for o in (est.step(z[0], z[1], z[2], SPEED, H) for z in meas)])
        assert not est.anchor_trusted  # dropped at about 2.2 s
        runs[f] = out
    np.testing.assert_array_equal(runs[1.2][:, 0], runs[1.0][:, 0])
    late = slice(n - 1000, n)
    np.testing.assert_allclose(runs[1.2][late, 1], 1.2 * runs[1.0][late, 1], rtol=1e-12)
    np.testing.assert_allclose(runs[3.0][late, 1], 3.0 * runs[1.0][late, 1], rtol=1e-12)
    # the force-error filter's P (the same in every run) scaled to the band of road_height_est
    assert runs[1.0][-1, 1] == pytest.approx(np.sqrt(est.kf.P[4, 4] * est.road.band_ratio()), rel=1e-12)

    t, meas, zr = drive(NOMINAL, T=6.0)
    _, std1, _ = estimate(meas, nonlinear_std_factor=1.0)
    _, std3, _ = estimate(meas, nonlinear_std_factor=3.0)
    np.testing.assert_array_equal(std1, std3)
    from suspension_estimation.estimators.tuning import Tuning
    assert any("nonlinear_std_factor" in m for m in Tuning(nonlinear_std_factor=0.5).problems())


@pytest.mark.parametrize("spring", [False, True])
def test_mass_regression_fits_an_asymmetric_damper_and_an_air_spring(spring):
    """With the damping estimated, the mass regression also fits the damper's asymmetry and
    progression and the spring's curvature (estimators/mass.py). A 3:1 damper without knees on
    a linear spring: c and c_a = (c_r - c_c)/2 come out near the plant's, and the mass near the
    true 410 kg, where the paper's [m_s, c] on the very same filtered sums is far off."""
    from suspension_estimation.estimators.mass import MassEstimator
    from suspension_estimation.plant.nonlinear_car import NonlinearQuarterCar
    from suspension_estimation.plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_DAMPER, PiecewiseDamper

    damper = DEFAULT_DAMPER if spring else PiecewiseDamper(3000.0, 1000.0, 1e3, 1e3, 3000.0, 1000.0)
    car = NonlinearQuarterCar(NOMINAL, DEFAULT_AIR_SPRING if spring else None, damper, noise=SensorNoise(),
                              noise_seed=7)
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=5)
    car.settle(road.height(0.0))
    lin = car.linearisation()
    me = MassEstimator(NOMINAL.m_s, lin.k_s, lin.c_s, estimate_damping=True)
    for k in range(int(round(20.0 / H))):
        car.step(road.height(SPEED * (k + 1) * H), H)
        a_s, _, d = car.measured
        me.update(a_s, d, H)
    two = np.linalg.solve(me._S2pp[:2, :2], me._S2py[:2])  # the paper's theta = [m_s, c]
    assert abs(me.mass_slow / NOMINAL.m_s - 1) < 0.03, (me.mass_slow, me.damping, me.extra_hat)
    assert abs(two[0] / NOMINAL.m_s - 1) > 0.08, two
    if not spring:
        assert me.damping == pytest.approx(2000.0, rel=0.1)
        assert me.damping_asymmetry == pytest.approx(1000.0, rel=0.15)


def test_the_nonlinear_case_of_the_study_through_the_fmus(dist):
    """The study's nonlinear case (air spring + asymmetric damper plant): the spec's plant models
    reach the QuarterCar, the default and the KFs are told the static point's linear vehicle and
    paper 003's observers the plant's maps; they hold the road where the linear KF does not."""
    import json

    from suspension_estimation.harness.studies import robust
    from suspension_estimation.harness.studies.runner import jsonable, plant_params

    spec = robust.case_spec(robust.NONLINEAR, road_class=3, seed=1, duration=8.0, warmup=3.0, step=1e-3,
                            dist=str(dist), speed=SPEED)
    assert plant_params(spec)["QuarterCar.spring_model"] == 1 == plant_params(spec)["QuarterCar.damper_model"]
    assert plant_params(robust.case_spec("exact", road_class=3, seed=1, duration=8.0, warmup=3.0, step=1e-3,
                                         dist=str(dist)))["QuarterCar.spring_model"] == 0
    told = {e.instance: e.parameters for e in robust.estimators_for(robust.NONLINEAR)}
    lin = robust.linearisation()
    assert abs(lin["k_s"] / 20000.0 - 1) < 1e-5 and lin["c_s"] == 2000.0  # the static point
    assert all(told[i].get("spring_model", 0) == 0 for i in ("default", "KF_nominal", "KF_exact"))
    assert all(told[i]["spring_model"] == 1 == told[i]["damper_model"] for i in ("EKF", "UKF", "dual"))
    res = {"spec": json.loads(json.dumps(jsonable(spec.__dict__))), **robust.run(spec)}
    assert robust.case_of(robust.spec_of(res)) == robust.NONLINEAR  # survives paper_runs.json
    s = res["estimators"]
    for i in ("EKF", "UKF"):
        assert s[i]["err_std_hp_pct"] < 5.0 and 0.9 < s[i]["gain_hp"] < 1.1, (i, s[i])
    # the dual observer's mass settles a few % low (docs/nonlinear-plant.md), which costs road
    assert s["dual"]["err_std_hp_pct"] < 10.0 and 0.9 < s["dual"]["gain_hp"] < 1.1, s["dual"]
    # the KF told the linearisation cannot explain the asymmetric damper's mean force (the default's
    # force-error state takes it up in band: docs/robustness.md)
    assert s["KF_nominal"]["err_std_hp_pct"] > 3 * s["EKF"]["err_std_hp_pct"], s
    assert abs(s["dual"]["mass_err_end_pct"]) < 8.0, s["dual"]


@pytest.mark.parametrize("q_b", [0.0, 1000.0])
def test_the_slow_force_bias_is_what_a_mean_deflection_says(q_b):
    """A mean deflection with no acceleration (an asymmetric damper's jacking) is a mean
    suspension force the linear spring does not explain. With the slow bias state the force
    states take it up, k_s |d0| to 1 %, and the road stays within 2 |d0| of its start after
    60 s; with the fast error alone (correlation 0.1 s) the force cannot hold, the filter reads
    the deflection as motion and the road drifts by tens of |d0|."""
    from dataclasses import replace

    from suspension_estimation.estimators.kalman import LinearKF
    from suspension_estimation.estimators.model import IZR, IZS, IZU, DiscreteModel, ModelNoise, RoadModel, \
        measurement_covariance
    from suspension_estimation.estimators.tuning import TUNING

    noise = replace(ModelNoise(), q_f=TUNING.force_error_q, q_b=q_b, tau_b=TUNING.force_bias_tau)
    m = DiscreteModel.build(NOMINAL, SPEED, iso8608.class_psd_n0(3), H, RoadModel(), noise)
    assert m.Phi.shape[0] == 6 + noise.force_states
    kf = LinearKF(m.Phi.shape[0], 3)
    kf.set_model(m.Phi, m.Q, m.H, measurement_covariance(0.05, 0.5, 5e-4))
    assert kf.stationary()
    kf.x = np.zeros(m.Phi.shape[0])
    d0 = -0.005  # m
    z = np.array([0.0, 0.0, d0])
    for _ in range(int(round(60.0 / H))):
        kf.step(z)
    x = kf.x
    assert x[IZS] - x[IZU] == pytest.approx(d0, rel=0.03)
    assert abs(x[IZR] - x[IZU]) < 0.01 * abs(d0)  # the tyre carries no part of it
    if q_b > 0:
        assert x[6:].sum() == pytest.approx(-NOMINAL.k_s * d0, rel=0.01)
        assert abs(x[IZR]) < 2 * abs(d0), x
    else:
        assert abs(x[IZR]) > 20 * abs(d0), x


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_the_rebuilds_of_the_start_re_filter(seed):
    """The damping's first identified value (1.6-2.02 s into the data) and the mass rebuilds
    at and after it re-filter the anchor from the start (Tuning.damping_refilter_span): with
    the 2 s span of a payload change those after 2 s did not (seeds 2 and 3 here), and the
    anchor kept the common velocity its wrong damping and mass gave it (raw road error 8 mm
    against 3 mm on ISO B-D at 40 km/h, docs/robustness.md)."""
    plant = NOMINAL.with_(c_s=0.7 * NOMINAL.c_s, k_s=0.85 * NOMINAL.k_s, k_t=0.9 * NOMINAL.k_t,
                          m_u=0.85 * NOMINAL.m_u)
    _, meas, _ = drive(plant, T=4.0, seed=seed)
    est = SuspensionEstimator()
    rebuilds = []  # (s, re-filtered) of each rebuild after the first model
    for k, z in enumerate(meas):
        before = (est.model_builds, est.refilters)
        est.step(z[0], z[1], z[2], SPEED, H)
        if k > 0 and est.model_builds != before[0]:
            rebuilds.append(((k + 1) * H, est.refilters - before[1]))
    assert rebuilds and all(r == 1 for _, r in rebuilds), rebuilds
    assert est.mass_est.damping_identified


def on_test_road(road, plant, v, T, seed, watch=None, **told):
    """(t, raw road error against reference_profile, road_height_std, the estimator) of the default
    estimator told the nominal vehicle and ``told`` on the linear ``plant`` over the test road
    ``road`` (harness.testroads) at v m/s for at most T s; ``watch(k, estimator)`` after step k."""
    from suspension_estimation.harness.testroads import make_road

    s, h = make_road(road)
    n = int(round(min(T, (s[-1] - 1.0) / v) / H))
    zr = np.interp(v * H * np.arange(n + 1), s, h)
    car = QuarterCar(plant, SensorNoise(), noise_seed=seed)
    car.settle(zr[0])
    est = SuspensionEstimator(**told)
    out, std = np.empty(n), np.empty(n)
    for k in range(n):
        car.step(zr[k + 1], H)
        o = est.step(*car.measured, v, H)
        out[k], std[k] = o["road_height_est"], o["road_height_std"]
        if watch is not None:
            watch(k, est)
    t = H * np.arange(1, n + 1)
    return t, out - reference_profile(v * t, zr[1:]), std, est


@pytest.mark.parametrize("road, k_s, told_k_s, seed", [("sag", 17000.0, 17000.0, 1), ("sag", 17000.0, 17000.0, 2),
                                                     ("curves", 0.85 * NOMINAL.k_s, NOMINAL.k_s, 2)])
def test_no_late_rebuild_moves_the_road_on_a_sag(road, k_s, told_k_s, seed):
    """After the start episode the identified damping wanders by a few % (1997-2062 N.s/m on
    the sag at 72 km/h) and the since-change mass by tenths of a % (484.0 -> 481.8 kg on the
    curves road); a road filter rebuilt at such a value during a sag's vertical motion moved the
    road's low-frequency level (against the former time-domain reference: raw error 18.3 mm rms
    against 5.3 mm on the sag, noise seed 1; 10.8 against 2.6 mm on the curves, seed 2). Outside
    a re-filter episode only a change beyond Tuning.damping_rebuild_tol_late or
    mass_rebuild_tol_late rebuilds. Raw error against the profile after 10 s, noise seeds 1-4:
    0.17-0.39 mm on the sag, 0.25-0.34 mm on the curves."""
    late, builds = [], [0]

    def watch(k, est):
        if est.model_builds != builds[0] and (k + 1) * H > est.cfg.tuning.damping_refilter_span:
            late.append(((k + 1) * H, est.m_model, est.c_model))
        builds[0] = est.model_builds

    t, err, _, _ = on_test_road(road, NOMINAL.with_(k_s=k_s), 72 / 3.6, 30.0, seed, watch, k_s=told_k_s)
    e = err[t > 10.0]
    assert not late, late
    assert 1e3 * np.sqrt(np.mean(e ** 2)) < 1.0


@pytest.mark.parametrize("factors, seed", [({"c_s": 0.7}, 1), ({"c_s": 0.7}, 2), ({"c_s": 1.3}, 1)])
def test_a_grade_from_the_start_with_the_damper_off(factors, seed):
    """A 3 % grade from the first step at 40 km/h (the car rises at 0.33 m/s from rest), the
    damper 30 % off: before the damping is identified (1.8 s) the anchor disagrees with the
    force-error filter, both in their start transients. Restarting the anchor from the
    force-error filter's state then (12 times) left it 85 mm off: raw error 48.6 mm rms,
    2-sigma coverage 0 (c_s -30 %, seed 1, against the former time-domain reference), against
    4.3 mm on the exact vehicle. Within the start the anchor is not restarted
    (anchored_road.START_DISAGREE_SPAN). Against the profile after 10 s, noise seeds 1-4: raw error
    0.17-0.21 mm (c_s -30 %), 0.12-0.30 mm (c_s +30 %, seeds 1-3), 0.10-0.14 mm (exact, seeds
    1-2); coverage 0.96-1.0."""
    plant = NOMINAL.with_(**{k: getattr(NOMINAL, k) * f for k, f in factors.items()})
    t, err, std, est = on_test_road("grade", plant, SPEED, 20.0, seed)
    keep = t > 10.0
    e = err[keep]
    assert 1e3 * np.sqrt(np.mean(e ** 2)) < 1.0
    assert np.mean(np.abs(e) <= 2 * std[keep]) > 0.9
    assert est.anchor_trusted


def _scaled_twin(case):
    """Two plants and roads that give the same three signals (docs/robustness.md, "Why no
    estimator can meet both targets there"): (vehicle, road, twin vehicle, twin road)."""
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=2)
    r = np.array([road.height(SPEED * k * H) for k in range(int(round(14.0 / H)))])
    if case == "k_t":  # k_t x 1.1 on the road z_u + (z_r - z_u) / 1.1
        lam, base = 1.1, NOMINAL
        twin = base.with_(k_t=lam * base.k_t)
    else:  # m_s, k_s, c_s x 1/0.85 on the road z_r + (lam - 1) m_s a_s / k_t
        lam, base = 1 / 0.85, NOMINAL.with_(k_s=0.85 * NOMINAL.k_s)
        twin = base.with_(m_s=lam * base.m_s, k_s=lam * base.k_s, c_s=lam * base.c_s)
    car = QuarterCar(base, SensorNoise(), noise_seed=102)
    z_u, a_s = np.zeros(len(r) + 1), np.zeros(len(r) + 1)
    for k, zr in enumerate(r):
        car.step(zr, H)
        z_u[k + 1], a_s[k + 1] = car.x[2], car.acc_true[0]
    mid = lambda s: 0.5 * (s[:-1] + s[1:])  # noqa: E731  (the road is held over each step)
    if case == "k_t":
        r_twin = mid(z_u) + (r - mid(z_u)) / lam
    else:
        r_twin = r + (lam - 1) * base.m_s * mid(a_s) / base.k_t
    return base, r, twin, r_twin


@pytest.mark.parametrize("case", ["k_t", "k_s"])
def test_a_wrong_tyre_or_spring_scale_gives_the_same_signals(case):
    """The identifiability floor: the plant with k_t x 1.1 (or m_s, k_s, c_s x 1/0.85) on a road
    that differs by 10 % of the tyre deflection (17.6 % of m_s a_s / k_t) gives the same sensor
    signals, so any estimator gives the same road and mass for both, while the true roads differ
    by about the floor's term (3-4 % of the HP road) and, for k_s, the true masses by 17.6 %."""
    base, r, twin, r_twin = _scaled_twin(case)
    runs = []
    for veh, road in ((base, r), (twin, r_twin)):
        car = QuarterCar(veh, SensorNoise(), noise_seed=102)
        meas = np.empty((len(road), 3))
        for k, zr in enumerate(road):
            car.step(zr, H)
            meas[k] = car.measured
        runs.append(meas)
    noise = SensorNoise()
    diff = np.std(runs[0] - runs[1], axis=0) / (noise.acc_sprung, noise.acc_unsprung, noise.deflection)
    assert np.all(diff < 0.3), diff  # measured 0.003 / 0.18-0.22 / 0.002 of the noise std
    (e0, _, m0), (e1, _, m1) = estimate(runs[0]), estimate(runs[1])
    cut = int(round(WARMUP / H))
    hp = lambda s: np.std(highpass(s, H)[cut:])  # noqa: E731
    true_gap, est_gap = hp(r - r_twin) / hp(r), hp(e0 - e1) / hp(r)
    assert 0.02 < true_gap < 0.06, true_gap  # measured 0.030 (k_t), 0.040 (k_s)
    assert est_gap < 0.2 * true_gap, (est_gap, true_gap)  # measured 0.0015, 0.0013
    assert abs(m0[-1] / m1[-1] - 1) < 0.01  # the same mass estimate for both
    if case == "k_s":  # so it is at least 7 % off for one of two masses 17.6 % apart
        assert max(abs(m0[-1] / base.m_s - 1), abs(m0[-1] / twin.m_s - 1)) > 0.07

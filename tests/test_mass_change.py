"""Sprung-mass RLS across payload changes (estimators/mass.py, Li et al. eqs. 15-24 plus our change
handling): settling after each step on several seeds, no spurious reset at a constant mass on a
smooth road, and the exactness of the regression restart. Plain Python (plant + road + core)."""
from __future__ import annotations

import numpy as np
import pytest

from suspension_estimation.estimators.mass import MassEstimator
from suspension_estimation.harness.metrics import settling_time
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE, PAPER001_VEHICLE

H = 1e-3  # s
SPEED = 11.1111  # m/s, 40 km/h
SCHEDULE = ((0.0, 260.0), (1.5, 450.0), (4.0, 350.0))  # s, kg: the vehicle-mass paper's case


def _run(seed: int, road_class: int, schedule, duration: float, vehicle, m_start: float,
         noise: SensorNoise = SensorNoise(0.02, 0.2, 1e-4)):
    """Road, plant and MassEstimator in the co-simulation order (road first, plant with the
    road's new value held over the step, then the estimator with the plant's new outputs).
    Returns times (s), fast estimates (kg) and the times of the detected changes (s)."""
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    plant = QuarterCar(vehicle.with_(m_s=schedule[0][1]), noise, 1000 + seed)
    plant.settle(road.height(0.0))
    me = MassEstimator(m_start, vehicle.k_s, vehicle.c_s, 0.995)
    n = int(round(duration / H))
    t = H * np.arange(n + 1)
    ts = np.array([s for s, _ in schedule])
    ms = np.array([m for _, m in schedule])
    m_true = ms[np.searchsorted(ts, t, side="right") - 1]
    est = np.empty(n + 1)
    est[0] = m_start
    resets = []
    for k in range(n):
        plant.step(road.height(SPEED * H * (k + 1)), H, float(m_true[k]))
        a, _, d = plant.measured
        before = me.resets
        est[k + 1] = me.update(float(a), float(d), H)
        if me.resets != before:
            resets.append(t[k + 1])
    return t, est, resets


@pytest.mark.parametrize("seed", [7, 10, 13])
def test_mass_steps_settle_within_half_a_second(seed):
    """ISO C, 40 km/h, 260 -> 450 kg at 1.5 s -> 350 kg at 4 s: within +-5 % in <= 0.5 s after
    each step (seed 7 took 0.80 s after the second step with the former residual-power test), one
    detected change per step and no other."""
    v = PAPER001_VEHICLE
    t, m, resets = _run(seed, 3, SCHEDULE, 6.0, v, 260.0)
    for (t0, m_true), t1 in zip(SCHEDULE[1:], (4.0, 6.0)):
        assert settling_time(t, m, m_true, t0, t1 + 1e-9) <= 0.5
    assert len(resets) == 2
    assert 1.5 < resets[0] < 1.65 and 4.0 < resets[1] < 4.15


@pytest.mark.parametrize("vehicle, m_true, m_start, seed", [
    (PAPER001_VEHICLE, 450.0, 450.0, 2),  # the former test reset at 0.84, 14.4 and 16.2 s here
    (DEFAULT_VEHICLE, 590.0, 410.0, 2),  # starting 44 % off: resets at 8.1 and 14.4 s formerly
])
def test_no_spurious_reset_at_constant_mass_on_iso_b(vehicle, m_true, m_start, seed):
    """ISO B (smooth: little excitation), constant mass, 20 s: after the first second no change
    is detected and the fast estimate stays within 3 %."""
    t, m, resets = _run(seed, 2, ((0.0, m_true),), 20.0, vehicle, m_start)
    assert [r for r in resets if r > 1.0] == []
    assert np.max(np.abs(m[t > 2.0] / m_true - 1.0)) < 0.03


@pytest.mark.parametrize("seed", [4, 7])
def test_restart_removes_pre_change_data_exactly(seed):
    """Noise-free sensors: after the restart at the detection the regression holds only
    post-change samples, so from 0.2 s to 1 s after each step the fast estimate is within 1 % of
    the new mass (0.01-0.31 % here). Without the restart the filters' memory of the old mass kept
    it 1.8-2.2 % off (seed 4) or caused a reset with a 32 % excursion (seed 7); without the
    d(t_r) S_2 term of the restarted deflection rate it is 4-18 % off."""
    v = PAPER001_VEHICLE
    t, m, resets = _run(seed, 3, SCHEDULE, 5.0, v, 260.0, noise=SensorNoise(0.0, 0.0, 0.0))
    assert len(resets) == 2
    for t0, m_true in SCHEDULE[1:]:
        late = (t >= t0 + 0.2) & (t < t0 + 1.0)
        assert np.max(np.abs(m[late] / m_true - 1.0)) < 0.01


def test_noise_variance_of_the_filtered_regressors_is_the_simulated_one():
    """MassEstimator's noise-only variances of F[a_s] and F[d'] (discrete Lyapunov equation of
    its state-variable filter) equal the sample variances of the same filters run on white
    noise of the stated std (200 s at 1 ms: the sample variance is good to ~2 %)."""
    me = MassEstimator(410.0, 2e4, 2e3, acc_noise_std=0.05, defl_noise_std=1e-4)
    rng = np.random.default_rng(7)
    n = 200_000
    a, d = 0.05 * rng.standard_normal(n), 1e-4 * rng.standard_normal(n)
    fa, fdd = np.empty(n), np.empty(n)
    for k in range(n):
        me.update(a[k], d[k], 1e-3)
        fa[k], fdd[k] = me.xa[1], me.xd[2]
    assert np.var(fa[5000:]) == pytest.approx(me._noise_fa, rel=0.05)
    assert np.var(fdd[5000:]) == pytest.approx(me._noise_fdd, rel=0.05)


@pytest.mark.parametrize("speed", [0.0, 20.0])
def test_sensor_noise_alone_identifies_nothing(speed):
    """A flat road or standstill: the sensors give their noise only. The mass and the damping
    hold their nominal values (least squares of noise on noise falls towards zero: the mass
    reached its 41 kg bound in 15 s before), the road filter is not rebuilt (it was, about 20
    times a second, at each new wrong mass) and the excitation reads about 1 on the flat road;
    standing (below Tuning.standstill_speed) the regression is not fed at all."""
    from suspension_estimation.estimators import SuspensionEstimator

    car = QuarterCar(DEFAULT_VEHICLE.with_(m_s=500.0), SensorNoise(), noise_seed=11)
    car.settle(0.0)
    est = SuspensionEstimator()
    for _ in range(15_000):
        car.step(0.0, 1e-3)
        out = est.step(*car.measured, speed, 1e-3)
    me = est.mass_est
    assert out["sprung_mass_est"] == 410.0 and est.m_model == 410.0 and me.damping == est.cfg.c_s
    assert est.model_builds == 1
    assert (me.excitation == 0.0 if speed == 0.0 else 0.5 < me.excitation < 2.0) and not me.excited_slow
    assert 2 * out["mass_std"] > 90.0  # it says the 500 kg body is not identified

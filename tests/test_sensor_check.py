"""Self-diagnosis (estimators/sensor_check.py): status 3 when the innovations show a sensor error
the filter cannot absorb, with a road_height_std that then covers the error; never on sensors
within the calibration allowance."""
from __future__ import annotations

import numpy as np
import pytest

from fmu_driver import Driven
from suspension_estimation.estimators.sensor_check import CONSISTENT, INCONSISTENT, InnovationCheck
from suspension_estimation.harness.metrics import reference_profile
from suspension_estimation.plant.profile_band import class_band_rms
from suspension_estimation.plant.sensors import SensorErrors
from test_road_profile import H, drive, estimate

STATUS_SENSOR = 3
ONSET = 8.0  # s


def run(errors: SensorErrors, seconds: float, seed: int = 1, fault=None, **kw):
    """(t, distance, status, road error against the reference profile, road_height_std) of the
    default estimator on the exact vehicle, ISO C at 40 km/h; ``fault(t, meas)`` alters the
    measurements in place."""
    t, s, meas, zr, v = drive(seed, seconds, errors)
    if fault is not None:
        fault(t, meas)
    out = estimate(meas, v, **kw)
    err = out["road_height_est"] - reference_profile(s, zr, 91.44)
    return t, s, out["status"], err, out["road_height_std"]


@pytest.mark.parametrize("seed", [1, 2])
def test_no_alarm_within_the_allowance(seed):
    """Every sensor error at the end of its range together: innovations explained, status never 3."""
    errors = SensorErrors(deflection_offset=5e-3, acc_sprung_bias=0.1, acc_unsprung_bias=0.5, acc_sprung_scale=1.03,
                          acc_unsprung_scale=0.97, acc_sprung_delay=2e-3, acc_unsprung_delay=2e-3)
    t, s, status, err, std = run(errors, 20.0, seed)
    assert not np.any(status == STATUS_SENSOR)


def _dead_deflection(t, meas):
    meas[t >= ONSET, 2] = np.random.default_rng(5).normal(0.0, 1e-4, int(np.sum(t >= ONSET)))


def _flipped_body(t, meas):
    meas[t >= ONSET, 0] *= -1.0


@pytest.mark.parametrize("fault", [_dead_deflection, _flipped_body], ids=["dead deflection sensor", "sign flipped"])
def test_fault_flagged_within_two_seconds_and_covered(fault):
    t, s, status, err, std = run(SensorErrors(), 16.0, fault=fault)
    assert not np.any(status[t < ONSET] == STATUS_SENSOR)
    flagged = np.flatnonzero(status == STATUS_SENSOR)
    assert flagged.size and t[flagged[0]] - ONSET <= 2.0
    after = t >= ONSET + 2.0
    assert np.all(status[after] == STATUS_SENSOR)  # held: the profile carries the error for its cut-off length
    assert np.mean(np.abs(err[after]) <= 2.0 * std[after]) >= 0.95
    # the std is then what is known without the sensors: at least the band rms of ISO C's upper limit
    assert np.all(std[after] >= class_band_rms(3))


@pytest.mark.parametrize("errors", [SensorErrors(acc_sprung_delay=0.01), SensorErrors(acc_unsprung_bias=3.0)],
                         ids=["10 ms body skew", "wheel bias 3 m/s2"])
def test_errors_beyond_the_range_flagged_from_the_start(errors):
    t, s, status, err, std = run(errors, 10.0)
    late = t >= 5.0
    assert np.all(status[late] == STATUS_SENSOR)
    assert np.mean(np.abs(err[late]) <= 2.0 * std[late]) >= 0.95


def test_innovation_mean_is_scored_by_its_own_std():
    """White innovations of covariance S: the window's mean over its std (the exponential average's
    variance S a / (2 - a)) is standard normal; a mean of 0.4 sqrt(S) over a 1 s window at 1 kHz
    (16 stds) trips a limit of 8 within the window, and the state holds for ``hold`` metres."""
    rng = np.random.default_rng(3)
    h, n = 1e-3, 20000
    zero = np.zeros((2, 2))
    check = InnovationCheck(2, 2, 0.0, 0.0, window=1.0, limit=1e6, hold=5.0, mean_channels=(1,), mean_limit=8.0)
    S = np.diag([1.0, 4.0])
    z = []
    for k in range(n):
        y = rng.standard_normal(2) * np.sqrt(np.diag(S))
        assert check.update(y, S, np.zeros(2), zero, zero, np.eye(2), h, 0.01) == CONSISTENT
        if k > 2000 and k % 200 == 0:  # 0.2 s apart: nearly independent samples of the average
            z.append(float(check.mean_ratio[0]))
    assert 0.8 < np.sqrt(np.mean(np.square(z))) < 1.2
    for k in range(1000):
        y = rng.standard_normal(2) * np.sqrt(np.diag(S)) + np.array([0.0, 0.4 * 2.0])
        if check.update(y, S, np.zeros(2), zero, zero, np.eye(2), h, 0.01) == INCONSISTENT:
            break
    assert k < 1000 and check.mean_ratio[0] > 8.0
    for k in range(400):  # 4 m at 0.01 m a step: still held; at 5 m back
        check.update(rng.standard_normal(2) * np.sqrt(np.diag(S)), S, np.zeros(2), zero, zero, np.eye(2), h, 0.01)
    assert check.state == INCONSISTENT


def _body_bias_step(t, meas):
    meas[t >= ONSET, 0] += 1.0


def test_a_body_bias_beyond_the_range_is_flagged_from_the_start_and_covered():
    """A body accelerometer 0.5 m/s2 off (5x the range) from the start: its innovations' variance is
    that of ideal sensors, but the wheel's innovations keep a mean (the whole car read as
    accelerating) that the mean test sees within 2 s of the check's start."""
    t, s, status, err, std = run(SensorErrors(acc_sprung_bias=0.5), 12.0)
    flagged = np.flatnonzero(status == STATUS_SENSOR)
    assert flagged.size and t[flagged[0]] <= 3.0 + 2.0
    late = t >= 6.0
    assert np.all(status[late] == STATUS_SENSOR)
    assert np.mean(np.abs(err[late]) <= 2.0 * std[late]) >= 0.95


def test_a_body_bias_stepping_mid_run_is_flagged():
    """A body-accelerometer bias stepping by 1 m/s2 (10x the range) mid-run: the force-error filter
    reads it as a force and the anchor is kept (bias_step.py); the bias its force states take up
    passes bias_step.BIAS_LIMIT and flags it 0.4 s after the step (seeds 1-3); from then on +-2 std
    covers the error. Before the anchor was kept: flagged 2 s after the step by the
    wheel's innovation mean, the profile decimetres off."""
    t, s, status, err, std = run(SensorErrors(), 16.0, fault=_body_bias_step)
    assert not np.any(status[t < ONSET] == STATUS_SENSOR)
    flagged = np.flatnonzero(status == STATUS_SENSOR)
    assert flagged.size and t[flagged[0]] - ONSET <= 2.0
    after = t >= t[flagged[0]]
    assert np.all(status[after] == STATUS_SENSOR)
    assert np.mean(np.abs(err[after]) <= 2.0 * std[after]) >= 0.95
    assert np.sqrt(np.mean(err[after] ** 2)) > 0.005  # the error it covers is real (ideal: 0.2 mm)


@pytest.mark.parametrize("seed, channel, size", [(1, 0, 0.1), (2, 0, 0.1), (1, 0, -0.2), (3, 0, -0.2), (1, 2, 5e-3)])
def test_a_body_bias_or_deflection_zero_stepping_mid_run_is_absorbed_and_covered(seed, channel, size):
    """A body-accelerometer bias or a deflection zero stepping mid-run by a size the filter absorbs
    from the start, or twice that. The anchor's innovations are alike for both; the force-error
    filter's deflection innovations tell them apart (bias_step.py): after a body step the anchor
    is kept, after a deflection step it is restarted and dropped. Restarting it after a
    body step left the profile 40 / 79 mm rms off (0.1 / 0.2 m/s2) with +-2 std covering 5-10 %;
    seeds 1-6 now: 2.1-4.4 mm, covered on 99-100 %; the deflection step 1.1-1.7 mm, 97-100 %."""
    def step(t, meas):
        meas[t >= ONSET, channel] += size

    t, s, status, err, std = run(SensorErrors(), 16.0, seed=seed, fault=step)
    after = t >= ONSET
    assert np.sqrt(np.mean(err[after] ** 2)) < 6e-3
    assert np.mean(np.abs(err[after]) <= 2.0 * std[after]) >= 0.9


def test_a_deflection_offset_does_not_show_in_the_default_filters_innovations():
    """Physics of the design: the default filter's slow force-bias state takes a constant deflection
    offset as a constant suspension force (k_s x offset), so its innovations stay those of ideal
    sensors and no innovation test can see it, even at 6x the range (its cost is in the mass and
    the profile: docs/real-sensors.md). The KF (code 0), with no such state, shows it plainly."""
    nis = {}
    for code in (0, 2):
        for name, errors in (("ideal", SensorErrors()), ("offset", SensorErrors(deflection_offset=0.03))):
            t, s, meas, zr, v = drive(1, 12.0, errors)
            out = estimate(meas, v, road_estimator=code, mass_estimator=0)
            late = t >= 6.0
            nis[code, name] = float(np.mean(out["nis"][late]))
            if code == 2:
                assert not np.any(out["status"] == STATUS_SENSOR)
    assert abs(nis[2, "offset"] / nis[2, "ideal"] - 1.0) < 0.05
    assert nis[0, "offset"] > 10.0 * nis[0, "ideal"]


@pytest.mark.parametrize("fault", [_dead_deflection, _body_bias_step])
def test_through_the_fmu(dist, fault):
    """The FMU reports status 3 after a sensor dies, or a body bias steps beyond the range (the
    anchor kept, bias_step.py), with the core's profile to the bit."""
    t, s, meas, zr, v = drive(1, 11.0)
    fault(t, meas)
    core = estimate(meas, v)
    d = Driven(dist / "SuspensionEstimator.fmu")
    try:
        status, road = [], []
        for z, sp in zip(meas, v):
            d.step(H, acc_sprung=z[0], acc_unsprung=z[1], susp_deflection=z[2], vehicle_speed=sp)
            status.append(d.get("status"))
            road.append(d.get("road_height_est"))
    finally:
        d.close()
    assert np.array_equal(np.array(status), core["status"])
    assert np.array_equal(np.array(road), core["road_height_est"])
    assert status[-1] == STATUS_SENSOR


def test_a_saved_state_with_the_anchor_kept_replays_in_a_second_instance(dist):
    """The FMU state holds the kept anchor's judge (bias_step.BiasStep) and the gap's profile: a
    state saved 1 s after a 1 m/s2 body step, restored into a second instance, replays the profile,
    its std and the status to the bit."""
    t, s, meas, zr, v = drive(1, 10.0)
    _body_bias_step(t, meas)
    k_save = int(round((ONSET + 1.0) / H))

    def advance(d, k0, k1):
        rows = []
        for k in range(k0, k1):
            d.step(H, acc_sprung=meas[k, 0], acc_unsprung=meas[k, 1], susp_deflection=meas[k, 2],
                   vehicle_speed=v[k])
            rows.append([d.get("road_height_est"), d.get("road_height_std"), d.get("status")])
        return np.array(rows)

    d = Driven(dist / "SuspensionEstimator.fmu")
    other = Driven(dist / "SuspensionEstimator.fmu", name="other")
    try:
        advance(d, 0, k_save)
        blob = d.fmu.serializeFMUstate(d.fmu.getFMUstate())
        t_save = d.t
        first = advance(d, k_save, len(t))
        assert first[0, 2] == STATUS_SENSOR  # kept and flagged when saved
        other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(blob))
        other.t = t_save
        assert np.array_equal(advance(other, k_save, len(t)), first)
    finally:
        d.close()
        other.close()

"""Bad signals through the built FMUs: bursts of NaN, Inf and 100 g outliers on either
acceleration, a frozen sensor, a communication step changing mid-run.

The bursts are injected into the estimator's inputs. ISORoad -> QuarterCar is co-simulated once
(harness CoSimulation, 1 ms) and its measurements are replayed into SuspensionEstimator.fmu as
per-step inputs, the undisturbed ones and copies with a burst. The replay of the undisturbed
measurements is the closed loop road -> plant -> estimator bit for bit (checked below: the
estimator does not feed back, and an input array holds at step k what the plant computed in step
k of the Gauss-Seidel loop), so every disturbed run has an undisturbed twin on the very same road,
sensor noise and seeds.
"""
from __future__ import annotations

import numpy as np
import pytest

from suspension_estimation.suspension_fmi.contract import SUSPENSION_ESTIMATOR
from suspension_estimation.harness.cosim import CoSimulation, System
from suspension_estimation.harness.metrics import highpass, reference_profile, road_scores

H = 1e-3  # s
V = 11.1111  # m/s, 40 km/h
T = 7.0  # s of road and plant
SEED = 3
WIRES = ("acc_sprung", "acc_unsprung", "susp_deflection")
REAL_OUTPUTS = [v.name for v in SUSPENSION_ESTIMATOR if v.causality == "output" and v.type == "Real"]
RECORD = [f"e.{o}" for o in REAL_OUTPUTS] + ["e.status"]
G = 9.80665  # m/s^2
K0, K1 = 3000, 3050  # the burst replaces the samples of steps K0 .. K1-1: 50 ms from t = 3.0 s
RECOVERY = (1.0, 2.0)  # s after the burst's end: the window in which the error must be back

# (channel, kind): NaN / Inf replace the samples, "100g" adds +100 g to them
BURSTS = [("acc_sprung", "nan"), ("acc_sprung", "inf"), ("acc_sprung", "100g"),
          ("acc_unsprung", "nan"), ("acc_unsprung", "-inf"), ("acc_unsprung", "100g")]

def _estimator(dist, meas: dict[str, np.ndarray], params: dict | None = None) -> np.ndarray:
    """SuspensionEstimator.fmu fed ``meas`` (one value per step for each of WIRES)."""
    n = len(meas[WIRES[0]])
    inputs = {"e.vehicle_speed": V, **{f"e.{w}": meas[w] for w in WIRES}}
    with CoSimulation(System({"e": dist / "SuspensionEstimator.fmu"}, []),
                      parameters={f"e.{k}": v for k, v in (params or {}).items()},
                      inputs=inputs, record=RECORD) as sim:
        return sim.run(n * H, H)


def _closed_loop_system(dist) -> System:
    components = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu",
                  "e": dist / "SuspensionEstimator.fmu"}
    connections = ([("vehicle_speed", "road.vehicle_speed"), ("vehicle_speed", "e.vehicle_speed"),
                    ("road.road_height", "plant.road_height")] + [(f"plant.{w}", f"e.{w}") for w in WIRES])
    return System(components, connections)


@pytest.fixture(scope="module")
def drive(dist):
    """Road and plant once; the undisturbed estimator replay; disturbed replays on demand (cached)."""
    components = {"road": dist / "ISORoad.fmu", "plant": dist / "QuarterCar.fmu"}
    connections = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "plant.road_height")]
    with CoSimulation(System(components, connections), parameters={"road.seed": SEED, "plant.noise_seed": SEED},
                      inputs={"vehicle_speed": V},
                      record=["road.road_height", "road.distance"] + [f"plant.{w}" for w in WIRES]) as sim:
        res = sim.run(T, H)
    meas = {w: np.array(res[f"plant.{w}"][1:]) for w in WIRES}  # the value of step k at index k
    cache: dict = {}

    def burst(channel: str, kind: str) -> np.ndarray:
        if (channel, kind) not in cache:
            m = {w: v.copy() for w, v in meas.items()}
            if kind == "100g":
                m[channel][K0:K1] += 100 * G
            else:
                m[channel][K0:K1] = float(kind)
            cache[channel, kind] = _estimator(dist, m)
        return cache[channel, kind]

    # the truth of road_height_est: the profile of the elevation (harness.metrics.reference_profile)
    truth = reference_profile(res["road.distance"], res["road.road_height"])
    return {"time": res["time"], "truth": truth, "meas": meas, "clean": _estimator(dist, meas), "burst": burst}


def test_replay_is_the_closed_loop(dist, drive):
    """The replayed undisturbed run equals the co-simulated closed loop bit for bit (first 1 s)."""
    with CoSimulation(_closed_loop_system(dist), parameters={"road.seed": SEED, "plant.noise_seed": SEED},
                      inputs={"vehicle_speed": V}, record=RECORD) as sim:
        loop = sim.run(1.0, H)
    for name in RECORD:
        np.testing.assert_array_equal(loop[name][1:], drive["clean"][name][1:1001], err_msg=name)
    assert np.all(drive["clean"]["e.status"] == 0)


@pytest.mark.parametrize("channel, kind", BURSTS)
def test_burst_keeps_every_output_finite_without_reinitialising(drive, channel, kind):
    res = drive["burst"](channel, kind)
    for name in REAL_OUTPUTS:
        assert np.all(np.isfinite(res[f"e.{name}"])), name
    assert not np.any(res["e.status"] == 2)


@pytest.mark.parametrize("channel, kind", BURSTS)
def test_burst_is_rejected_and_predicted_through(drive, channel, kind):
    """status = 1 for every sample of the burst (row k + 1 holds the outputs of step k), 0 again
    from 10 ms after it."""
    status = drive["burst"](channel, kind)["e.status"]
    during = status[K0 + 1:K1 + 1]
    assert np.all(during == 1), f"rejected {np.mean(during == 1):.0%} of the burst"
    assert np.all(status[K1 + 11:] == 0)


def _recovery(drive, channel: str, kind: str, hp: bool) -> float:
    """RMS over RECOVERY of the burst's effect on the road estimate, d = est(burst) - est(clean),
    relative to the RMS of the undisturbed run's road error over the same window (both high-passed
    first if ``hp``, with the 0.5 Hz zero-phase filter of harness.metrics over the whole record)."""
    t, truth, clean = drive["time"], drive["truth"], drive["clean"]["e.road_height_est"]
    est = drive["burst"](channel, kind)["e.road_height_est"]
    f = (lambda x: highpass(x, H)) if hp else (lambda x: x)
    d, e = f(est) - f(clean), f(clean) - f(truth)
    t_end = t[K1]
    s = (t > t_end + RECOVERY[0]) & (t <= t_end + RECOVERY[1])
    return float(np.sqrt(np.mean(d[s] ** 2)) / np.sqrt(np.mean(e[s] ** 2)))


@pytest.mark.parametrize("channel, kind", BURSTS)
def test_in_band_road_error_is_back_within_1s(drive, channel, kind):
    """1 s after a 50 ms burst the road error is back at the undisturbed level, in band.

    Criterion: over 1-2 s after the burst's end, RMS(HP(est_burst) - HP(est_clean)) <= 10 % of
    RMS(HP(est_clean) - HP(truth)), HP the project's 0.5 Hz high-pass (harness.metrics). The error
    of the disturbed run is the undisturbed error plus that difference, so by the triangle
    inequality its RMS is then within +-10 % of the undisturbed run's: "returns to the undisturbed
    level" with no luck of cancellation. Bounding the difference rather than comparing two error
    levels also fails a burst that leaves a different error of the same size. Measured: 2.3 %
    (body channel) and 2.5 % (wheel channel) of the undisturbed 0.15 mm."""
    ratio = _recovery(drive, channel, kind, hp=True)
    assert ratio <= 0.10, f"HP deviation {ratio:.1%} of the undisturbed HP error 1-2 s after the burst"


@pytest.mark.parametrize("channel, kind", BURSTS)
def test_raw_road_estimate_is_back_within_1s(drive, channel, kind):
    """The same criterion on the raw road estimate (what a user reads from road_height_est): the
    RMS deviation from the undisturbed estimate over 1-2 s after the burst <= 10 % of the
    undisturbed raw error RMS against the profile (0.16 mm here, the profile's own band: a kick
    the burst gives the filter's level would have to leave the band within 1 s). Measured: 2.7 %
    (body channel) and 4.1 % (wheel channel)."""
    ratio = _recovery(drive, channel, kind, hp=False)
    assert ratio <= 0.10, f"raw deviation {ratio:.1%} of the undisturbed raw error 1-2 s after the burst"


@pytest.mark.parametrize("channel", WIRES)
def test_frozen_sensor_is_flagged(drive, dist, channel):
    """A sensor stuck at its value of t = 3 s for the rest of the run: status 0 before; after
    ``frozen_time`` (50 ms) of bit-identical values, status 1 at every step, the outputs finite,
    the road estimate in band still within 20 % of the road (the other channels carry it:
    HP error 2.8 / 11.4 / 2.2 % of the HP profile after 3.5 s with the body / wheel /
    deflection channel frozen) and nis finite and non-negative (it keeps the last update's
    value when nothing is used)."""
    m = {w: v.copy() for w, v in drive["meas"].items()}
    m[channel][K0:] = m[channel][K0]
    res = _estimator(dist, m)
    status = res["e.status"]
    assert np.all(status[1:K0 + 1] == 0)
    assert np.all(status[K0 + 52:] == 1), np.flatnonzero(status[K0 + 52:] != 1)[:5]
    for name in REAL_OUTPUTS:
        assert np.all(np.isfinite(res[f"e.{name}"])), name
    assert np.all(res["e.nis"] >= 0)
    t = drive["time"]
    sel = t > 3.5
    hp_err = highpass(res["e.road_height_est"], H) - highpass(drive["truth"], H)  # truth: the profile
    assert np.std(hp_err[sel]) < 0.2 * np.std(highpass(drive["truth"], H)[sel])


def test_changed_step_size_stays_within_20pct_of_fixed_step(dist):
    """Closed loop road -> plant -> estimator (default parameters) with the communication step
    1 ms for 4 s, 5 ms for 4 s, 2 ms for 4 s, against the same loop at a fixed 1 ms: the HP road
    error-STD % after a 3 s warm-up within 20 % of the fixed-step run's. Both are scored on the
    10 ms grid common to every segment (the 5 ms part has no samples in between), against the
    profile of the road at the recorded distances. Road and noise seeds 1-3: 1.75-2.02 % against
    1.86-2.04 % (ratio 0.94-1.02)."""
    def scores(steps: np.ndarray) -> dict[str, float]:
        with CoSimulation(_closed_loop_system(dist), parameters={"road.seed": SEED, "plant.noise_seed": SEED},
                          inputs={"vehicle_speed": V},
                          record=["road.road_height", "road.distance", "e.road_height_est"]) as sim:
            res = sim.run(float(np.sum(steps)), steps)
        t = res["time"]
        grid = np.arange(0.01, t[-1] - 1e-9, 0.01)
        idx = np.searchsorted(t, grid - 1e-9)
        assert np.allclose(t[idx], grid, atol=1e-9)
        return road_scores(grid, res["e.road_height_est"][idx], res["road.road_height"][idx], warmup=3.0,
                           distance=res["road.distance"][idx])

    fixed = np.full(12000, 1e-3)
    varying = np.concatenate([np.full(4000, 1e-3), np.full(800, 5e-3), np.full(2000, 2e-3)])
    e_fixed = scores(fixed)["err_std_hp_pct"]
    e_var = scores(varying)["err_std_hp_pct"]
    assert e_var <= 1.2 * e_fixed, (e_fixed, e_var)

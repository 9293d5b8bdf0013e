"""The co-simulation master (harness/cosim.py) driving the built FMUs: Gauss-Seidel without lag,
parameters by name of every type, time-varying inputs, refusals, variable steps, CSV."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from suspension_estimation.harness.cosim import CoSimulation, SimulationError, System, read_csv, write_csv
from suspension_estimation.harness.ssp import ROAD_PLANT, ROAD_PLANT_ESTIMATOR, ensure_system_ssp, read_ssp

H = 1e-3  # s
V = 11.1111  # m/s


@pytest.fixture(scope="module")
def road_plant(dist) -> System:
    return read_ssp(ensure_system_ssp(dist, ROAD_PLANT), fmu_dir=dist)


@pytest.fixture(scope="module")
def full(dist) -> System:
    if not (dist / "SuspensionEstimator.fmu").is_file():
        pytest.skip("SuspensionEstimator.fmu is not built yet")
    return read_ssp(ensure_system_ssp(dist, ROAD_PLANT_ESTIMATOR), fmu_dir=dist)


def simulate(system, stop=0.2, step=H, **kwargs) -> np.ndarray:
    kwargs.setdefault("inputs", {"vehicle_speed": V})
    with CoSimulation(system, **kwargs) as sim:
        return sim.run(stop, step)


def test_gauss_seidel_no_connection_lags_a_step(full):
    wires = [("ISORoad.road_height", "QuarterCar.road_height"),
             ("QuarterCar.acc_sprung", "SuspensionEstimator.acc_sprung"),
             ("QuarterCar.acc_unsprung", "SuspensionEstimator.acc_unsprung"),
             ("QuarterCar.susp_deflection", "SuspensionEstimator.susp_deflection")]
    assert full.order == ["ISORoad", "QuarterCar", "SuspensionEstimator"]
    r = simulate(full, record=[n for w in wires for n in w] + ["SuspensionEstimator.vehicle_speed"])
    assert len(r) == 201 and r["time"][-1] == pytest.approx(0.2)
    for out, inp in wires:
        # the input each FMU held over the step ending at t is the output computed at t, at every t
        assert np.array_equal(r[out], r[inp]), (out, inp)
        assert np.ptp(r[out][1:]) > 0, out  # and it is a signal, not a constant
    assert np.all(r["SuspensionEstimator.vehicle_speed"] == V)


def test_a_backward_order_lags_one_step(road_plant):
    lagged = System(road_plant.components, road_plant.connections, order=["QuarterCar", "ISORoad"])
    r = simulate(lagged, record=["ISORoad.road_height", "QuarterCar.road_height"])
    assert np.array_equal(r["QuarterCar.road_height"][1:], r["ISORoad.road_height"][:-1])


def test_parameters_by_name_of_every_type_land(road_plant, full, tmp_path):
    rec = ["ISORoad.road_height", "QuarterCar.acc_sprung", "QuarterCar.acc_sprung_true",
           "QuarterCar.susp_deflection", "QuarterCar.z_s", "QuarterCar.z_u"]
    base = simulate(road_plant, record=rec)
    # Integer: two ISO classes up is 4x the elevation (Gd ~ 4^(class-1)), same seed, same shape
    e = simulate(road_plant, parameters={"ISORoad.road_class": 5}, record=rec)
    assert np.std(e["ISORoad.road_height"]) / np.std(base["ISORoad.road_height"]) == pytest.approx(4.0, rel=1e-6)
    # Real: no sensor noise -> the measurements are the true values
    quiet = simulate(road_plant, record=rec, parameters={
        "QuarterCar.acc_sprung_noise_std": 0.0, "QuarterCar.acc_unsprung_noise_std": 0.0,
        "QuarterCar.defl_noise_std": 0.0})
    assert np.array_equal(quiet["QuarterCar.acc_sprung"], quiet["QuarterCar.acc_sprung_true"])
    assert np.allclose(quiet["QuarterCar.susp_deflection"], quiet["QuarterCar.z_s"] - quiet["QuarterCar.z_u"],
                       rtol=0, atol=1e-15)
    assert not np.array_equal(base["QuarterCar.acc_sprung"], base["QuarterCar.acc_sprung_true"])
    # String: a measured profile replaces the synthetic road (a ramp of 1 mm per m)
    profile = tmp_path / "ramp.csv"
    profile.write_text("".join(f"{d},{1e-3 * d}\n" for d in range(0, 101)))
    ramp = simulate(road_plant, stop=0.1, parameters={"ISORoad.profile_file": str(profile)},
                    record=["ISORoad.road_height", "ISORoad.distance"])
    assert np.allclose(ramp["ISORoad.road_height"], 1e-3 * ramp["ISORoad.distance"], rtol=0, atol=1e-12)
    # Boolean: without mass feedback the estimator is a different filter
    rec_e = ["SuspensionEstimator.road_height_est"]
    on = simulate(full, stop=1.5, record=rec_e, inputs={"vehicle_speed": V, "QuarterCar.sprung_mass": 300.0})
    off = simulate(full, stop=1.5, record=rec_e, inputs={"vehicle_speed": V, "QuarterCar.sprung_mass": 300.0},
                   parameters={"SuspensionEstimator.mass_feedback": False})
    assert not np.array_equal(on[rec_e[0]], off[rec_e[0]])


def test_unknown_names_are_refused_before_any_step(road_plant):
    with pytest.raises(KeyError, match="no variable 'k_x'"):
        CoSimulation(road_plant, parameters={"QuarterCar.k_x": 1.0})
    with pytest.raises(KeyError, match="no instance 'Car'"):
        CoSimulation(road_plant, record=["Car.z_s"])
    with pytest.raises(KeyError, match="has no such input"):
        CoSimulation(road_plant, inputs={"speed": 3.0})
    with pytest.raises(ValueError, match="already fed by the connection"):
        CoSimulation(road_plant, inputs={"QuarterCar.road_height": 0.0})


def test_time_varying_inputs_are_sampled_at_the_step_start(road_plant):
    mass = lambda t: np.where(t < 0.1, 410.0, 300.0)  # noqa: E731 - a payload change at 0.1 s
    speed = np.linspace(5.0, 15.0, 200)  # one value per step
    r = simulate(road_plant, inputs={"vehicle_speed": speed, "QuarterCar.sprung_mass": mass},
                 record=["QuarterCar.sprung_mass", "ISORoad.distance", "ISORoad.vehicle_speed"])
    t = r["time"]
    assert np.array_equal(r["QuarterCar.sprung_mass"][1:], mass(t[:-1]))  # held over [t_k, t_k+1)
    assert np.array_equal(r["ISORoad.vehicle_speed"][1:], speed)
    assert r["ISORoad.distance"][-1] == pytest.approx(np.sum(speed) * H, rel=1e-12)


def test_variable_step_sizes(road_plant):
    steps = np.r_[np.full(50, 1e-3), np.full(25, 2e-3), np.full(100, 0.5e-3)]
    r = simulate(road_plant, stop=None, step=steps, record=["ISORoad.distance", "QuarterCar.z_s"])
    assert np.allclose(np.diff(r["time"]), steps, rtol=0, atol=1e-15)
    assert r["time"][-1] == pytest.approx(0.15)
    assert r["ISORoad.distance"][-1] == pytest.approx(V * 0.15, rel=1e-12)
    fixed = simulate(road_plant, stop=0.15, record=["QuarterCar.z_s"])
    # the plant copes with the changing step: same response at the common time 0.15 s within 1 %
    assert r["QuarterCar.z_s"][-1] == pytest.approx(fixed["QuarterCar.z_s"][-1], rel=1e-2)


def test_a_discard_stops_with_instance_time_and_log_and_keeps_the_record(road_plant):
    speed = lambda t: np.where(t < 0.05 - H / 2, V, -1.0)  # noqa: E731 - negative from 0.05 s on
    with CoSimulation(road_plant, inputs={"vehicle_speed": speed}, record=["ISORoad.distance"]) as sim:
        with pytest.raises(SimulationError) as info:
            sim.run(0.2, H)
    e = info.value
    assert e.instance == "ISORoad"
    assert e.time == pytest.approx(0.05)
    assert "ISORoad" in str(e) and "t = 0.05 s" in str(e) and "vehicle_speed" in str(e)
    assert any("vehicle_speed" in m for _, m in e.messages)
    assert e.result["time"][-1] == pytest.approx(0.05) and len(e.result) == 51
    assert e.result["ISORoad.distance"][-1] == pytest.approx(0.05 * V)


def test_a_bad_parameter_is_refused_at_initialization(road_plant):
    with CoSimulation(road_plant, parameters={"QuarterCar.k_s": -1.0}, inputs={"vehicle_speed": V}) as sim:
        with pytest.raises(SimulationError) as info:
            sim.run(0.1, H)
    e = info.value
    assert e.instance == "QuarterCar" and e.time == 0.0
    assert "k_s" in str(e) and "\n" not in str(e)
    assert len(e.result) == 0


def test_csv_round_trip(road_plant, tmp_path):
    r = simulate(road_plant, stop=0.05, record=["ISORoad.road_height", "QuarterCar.acc_sprung", "QuarterCar.z_s"])
    back = read_csv(write_csv(tmp_path / "r.csv", r))
    assert back.dtype.names == r.dtype.names
    for n in r.dtype.names:
        assert np.array_equal(back[n], r[n]), n
    assert (tmp_path / "r.csv").read_text().splitlines()[0] == \
        '"time","ISORoad.road_height","QuarterCar.acc_sprung","QuarterCar.z_s"'


def test_csv_round_trip_keeps_integers(full, tmp_path):
    r = simulate(full, stop=0.02, record=["SuspensionEstimator.status", "SuspensionEstimator.road_class_est"])
    assert r.dtype["SuspensionEstimator.status"] == np.int64
    back = read_csv(write_csv(tmp_path / "i.csv", r))
    assert np.array_equal(back["SuspensionEstimator.status"], r["SuspensionEstimator.status"])


def test_fmus_are_extracted_once_and_cleaned_up(road_plant):
    sim = CoSimulation(road_plant, record=["ISORoad.road_height"])
    tmp = sim._tmp
    assert len(list(tmp.iterdir())) == 2
    sim.close()
    assert not Path(tmp).exists()


def test_an_instance_with_a_rate_steps_on_point_samples_and_equals_its_core(full):
    """``rates``: the estimator stepped every 10th 1 ms step over 10 ms, on the plant's outputs at
    the end of its step (a logger sampling at 100 Hz beside a plant stepped at 1 kHz): its
    outputs equal the plain-Python core fed those samples at h = 10 ms, and hold in between."""
    from suspension_estimation.estimators import SuspensionEstimator

    meas = ["QuarterCar.acc_sprung", "QuarterCar.acc_unsprung", "QuarterCar.susp_deflection"]
    outs = ["SuspensionEstimator.road_height_est", "SuspensionEstimator.road_height_std",
            "SuspensionEstimator.sprung_mass_est"]
    r = simulate(full, stop=1.0, record=meas + outs, rates={"SuspensionEstimator": 10})
    core = SuspensionEstimator()
    got, want = [], []
    for k in range(10, len(r), 10):
        o = core.step(*(float(r[m][k]) for m in meas), V, 10e-3)
        want.append([o[v.split(".")[1]] for v in outs])
        got.append([r[v][k] for v in outs])
        for j in range(k + 1, min(k + 10, len(r))):  # held until its next step
            assert all(r[v][j] == r[v][k] for v in outs)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-15)
    assert np.ptp(np.array(got)[:, 0]) > 0


def test_rates_are_checked(full):
    with pytest.raises(KeyError, match="no instance 'Nobody'"):
        CoSimulation(full, rates={"Nobody": 2})
    with pytest.raises(ValueError, match="whole number >= 1"):
        CoSimulation(full, rates={"SuspensionEstimator": 2.5})
    with pytest.raises(ValueError, match="Gauss-Seidel"):
        CoSimulation(full, rates={"SuspensionEstimator": 2}, coupling="jacobi")
    with pytest.raises(ValueError, match="not a whole number of the 7 steps"):
        simulate(full, stop=0.2, inputs={"vehicle_speed": V}, rates={"SuspensionEstimator": 7})

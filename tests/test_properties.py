"""Property tests (hypothesis): the cores and the FMUs on random valid vehicles, road classes,
speeds and step sizes, and the FMUs on random invalid parameters.

Valid vehicles are drawn log-uniformly from a box of road-vehicle corners (a small car's corner
to a loaded truck's) and, with any assumed sensor noise, from the whole of the contract's ranges
(plant/vehicle.py VEHICLE_RANGES, plant/quarter_car.py NOISE_STD_RANGES), ends included. Two
tests pin stiff vehicles (a wheel time constant far below the step).
Every run is derandomized and keeps no example database, so CI sees the same examples each time.
"""
from __future__ import annotations

import dataclasses
import math
import shutil
import tempfile

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from suspension_estimation.estimators import SuspensionEstimator
from suspension_estimation.estimators.suspension import EstimatorConfig
from suspension_estimation.suspension_fmi.contract import CONTRACTS, Var
from suspension_estimation.harness.cosim import STATUS, LogSink
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.quarter_car import NOISE_STD_RANGES, QuarterCar, SensorNoise
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import VEHICLE_RANGES, Vehicle

CORE = settings(derandomize=True, database=None, deadline=None, max_examples=12,
                suppress_health_check=[HealthCheck.too_slow])
FMU = settings(CORE, max_examples=12)

# (low, high) of the drawn road-vehicle corners, SI units: kg, kg, N/m, N/m, N.s/m
BOX = {"m_s": (150.0, 3000.0), "m_u": (20.0, 300.0), "k_s": (1e4, 3e5), "k_t": (1e5, 2e6), "c_s": (500.0, 2e4)}
M_S_LOW, M_S_HIGH = VEHICLE_RANGES["m_s"][:2]  # kg: the physical bound of a mass estimate
NOISE_NAMES = ("acc_sprung_noise_std", "acc_unsprung_noise_std", "defl_noise_std")


def log_uniform(low: float, high: float) -> st.SearchStrategy[float]:
    # clipped: exp(log(x)) can land an ulp outside [low, high]
    return st.floats(math.log(low), math.log(high)).map(lambda u: min(max(math.exp(u), low), high))


vehicles = st.builds(Vehicle, **{k: log_uniform(*v) for k, v in BOX.items()})


def _over_range(name: str) -> st.SearchStrategy[float]:
    """An end of VEHICLE_RANGES[name] or a log-uniform value inside (c_s from 1 N.s/m)."""
    lo, hi = VEHICLE_RANGES[name][:2]
    return st.one_of(st.sampled_from([lo, hi]), log_uniform(max(lo, 1.0), hi))


any_vehicles = st.builds(Vehicle, **{k: _over_range(k) for k in BOX})
# m/s2, m/s2, m: an end of NOISE_STD_RANGES or a log-uniform value inside (seven to ten decades)
any_noise = st.tuples(*(st.one_of(st.sampled_from(NOISE_STD_RANGES[n]), log_uniform(*NOISE_STD_RANGES[n]))
                        for n in NOISE_NAMES))
classes = st.integers(1, 6)  # A..F
speeds = st.floats(2.0, 40.0)  # m/s
steps = st.sampled_from([1e-3, 2e-3, 5e-3])  # s
seeds = st.sampled_from([1, 2])  # few: each synthetic road builds 16 MB of nodes (cached)


def _assert_spd(P: np.ndarray) -> None:
    """Symmetric to rounding and positive semi-definite to rounding."""
    scale = np.abs(P).max()
    assert np.isfinite(scale)
    assert np.abs(P - P.T).max() <= 1e-9 * scale
    assert np.linalg.eigvalsh(0.5 * (P + P.T)).min() >= -1e-12 * scale


def _drive(v: Vehicle, road_class: int, speed: float, h: float, seed: int, T: float,
           true_mass: float | None = None, check_every: int = 25, noise: SensorNoise = SensorNoise(),
           **estimator):
    """Plant and estimator cores for T s; checks the covariance along the way; returns the
    estimator and the (steps, outputs) dict of arrays."""
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    car = QuarterCar(v, noise, noise_seed=seed)
    car.settle(road.height(0.0))  # at rest on the road, as QuarterCar.fmu starts (no step at t = 0)
    est = SuspensionEstimator(m_s_nominal=v.m_s, m_u=v.m_u, k_s=v.k_s, k_t=v.k_t, c_s=v.c_s, **estimator)
    n = int(round(T / h))
    out: dict[str, list] = {}
    for k in range(n):
        car.step(road.height(speed * k * h), h, true_mass)
        o = est.step(*car.measured, speed, h)
        for key, value in o.items():
            out.setdefault(key, []).append(value)
        if k % check_every == 0:
            _assert_spd(est.kf.P)
    _assert_spd(est.kf.P)
    return est, {k: np.array(v) for k, v in out.items()}


# --- cores -------------------------------------------------------------------------------------
@CORE
@given(v=vehicles, road_class=classes, speed=speeds, h=steps, seed=seeds,
       mass_ratio=st.floats(0.7, 1.4))
def test_estimator_core_on_random_vehicles(v, road_class, speed, h, seed, mass_ratio):
    """1.2 s on a random vehicle whose true sprung mass is 0.7-1.4 x the one the estimator
    assumes: P symmetric PSD throughout, every output finite, road_height_std > 0, never
    re-initialised, and the mass estimate always inside the physical range of the contract,
    [10, 2e4] kg. Where the road excites the body (class C or rougher, >= 5 m/s) its mean over
    the last 0.4 s is also within a factor 1.5 of the true mass; on a smooth road at walking pace
    the RLS sees mostly sensor noise and swings widely at first (class A, 2 m/s: 0.1-2.1 x)."""
    true_mass = mass_ratio * v.m_s
    _, out = _drive(v, road_class, speed, h, seed, T=1.2, true_mass=true_mass, check_every=50)
    for key, values in out.items():
        assert np.all(np.isfinite(values)), key
    assert np.all(out["road_height_std"] > 0)
    assert not np.any(out["status"] == 2)
    mass = out["sprung_mass_est"]
    assert np.all((mass >= M_S_LOW) & (mass <= M_S_HIGH)), (mass.min(), mass.max())
    if road_class >= 3 and speed >= 5.0:
        settled = float(np.mean(mass[-int(round(0.4 / h)):]))
        assert true_mass / 1.5 < settled < 1.5 * true_mass, (settled, true_mass)


@settings(CORE, max_examples=40)
@given(v=any_vehicles, noise=any_noise, road_class=classes, speed=speeds, h=steps, seed=seeds)
def test_estimator_core_over_the_whole_ranges(v, noise, road_class, speed, h, seed):
    """Any vehicle inside VEHICLE_RANGES and any assumed sensor noise inside NOISE_STD_RANGES
    (ends included; the plant's noise the same): 0.6 s keep P symmetric PSD, every output
    finite and the mass estimate inside the range of m_s. (The wider ranges before, e.g. a
    1 kg wheel on a 1e9 N/m tyre or a 1e7 N.s/m damper, lost P's symmetry and definiteness.)"""
    assert v.problems() == []
    kw = dict(zip(NOISE_NAMES, noise))
    assert EstimatorConfig(m_s_nominal=v.m_s, m_u=v.m_u, k_s=v.k_s, k_t=v.k_t, c_s=v.c_s, **kw).problems() == []
    _, out = _drive(v, road_class, speed, h, seed, T=0.6, noise=SensorNoise(*noise), **kw)
    for key, values in out.items():
        assert np.all(np.isfinite(values)), key
    mass = out["sprung_mass_est"]
    assert np.all((mass >= M_S_LOW) & (mass <= M_S_HIGH)), (mass.min(), mass.max())


@CORE
@given(v=vehicles, h=steps, seed=seeds, scale=st.floats(0.1, 10.0))
def test_plant_core_is_linear_and_finite(v, h, seed, scale):
    """The noise-free quarter car on a random vehicle: finite states, and the response to a
    road scaled by a is a times the response (linear plant, exact discretisation)."""
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=seed)
    quiet = SensorNoise(acc_sprung=0.0, acc_unsprung=0.0, deflection=0.0)
    a, b = QuarterCar(v, quiet), QuarterCar(v, quiet)
    for k in range(int(round(1.0 / h))):
        r = road.height(10.0 * k * h)
        a.step(r, h)
        b.step(scale * r, h)
        assert np.all(np.isfinite(a.x)) and np.all(np.isfinite(a.measured))
    np.testing.assert_allclose(b.x, scale * a.x, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(b.measured, scale * np.asarray(a.measured), rtol=1e-9, atol=1e-12)


@CORE
@given(road_class=st.integers(1, 7), seed=seeds, s=st.lists(st.floats(0.0, 5e4), min_size=1, max_size=20))
def test_road_core_is_a_function_of_distance(road_class, seed, s):
    """Heights are finite and depend only on the distance (any order of evaluation, any speed);
    one class up is exactly twice the elevation (Gd(n0) x 4, same seed)."""
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    rougher = SyntheticRoad(iso8608.class_psd_n0(road_class + 1), seed=seed)
    fwd = [road.height(x) for x in s]
    back = [road.height(x) for x in reversed(s)][::-1]
    assert all(math.isfinite(x) for x in fwd)
    assert fwd == back
    np.testing.assert_allclose([rougher.height(x) for x in s], 2.0 * np.array(fwd), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("v", [Vehicle(m_s=10.0, m_u=1.0, k_s=1e7, k_t=1e8, c_s=1e5),
                               Vehicle(m_s=2e4, m_u=1.0, k_s=1e7, k_t=1e8, c_s=1e5),
                               Vehicle(m_s=2e4, m_u=5e3, k_s=100.0, k_t=1e3, c_s=0.0)])
@pytest.mark.parametrize("h", [1e-3, 5e-3])
def test_estimator_at_the_corners_of_the_ranges(v, h):
    """Corners of VEHICLE_RANGES: the stiffest wheel (1 kg on 1e8 N/m, damped at c_s/m_u =
    1e5 1/s: a 10 us time constant) under a light or a heavy body, and the softest heavy
    vehicle: 2 s keep P symmetric PSD and every output finite."""
    assert v.problems() == []
    _, out = _drive(v, road_class=1, speed=6.0, h=h, seed=1, T=2.0)
    for key, values in out.items():
        assert np.all(np.isfinite(values)), key


ILL_CONDITIONED = [  # (vehicle, sensor noise stds, speed m/s): corners found by hypothesis
    *[(Vehicle(m_s=10.0, m_u=1.0, k_s=100.0, k_t=1e8, c_s=0.0), (1e-4, a_u, 1e-7), 2.0) for a_u in (0.3, 1.0, 3.0)],
    (Vehicle(m_s=10.0, m_u=1.0, k_s=148.41, k_t=7150.9, c_s=1e5), (1e-4, 1e-4, 1e-7), 39.0)]


@pytest.mark.parametrize("v,noise,speed", ILL_CONDITIONED)
@pytest.mark.parametrize("h", [1e-3, 2e-3, 5e-3])
def test_road_height_std_is_never_zero_on_an_ill_conditioned_filter(v, noise, speed, h):
    """Corners that gave road_height_std = 0 exactly. (1) A 1 kg wheel on a 1e8 N/m tyre, no
    damper, deflection read to 0.1 um: the variance built up since a start from rest (a term of
    the earlier std) was P - A^k P A'^k, which rounding took to 0. (2) A 1 kg wheel damped at 1e5 N.s/m on a soft
    tyre: the filter's P loses its definiteness to rounding (P_zr ~ -1e42), and a non-positive
    P_zr now gives an infinite std instead of the 0 it was clipped to."""
    _, out = _drive(v, 1, speed, h, 1, T=0.3, noise=SensorNoise(*noise), check_every=10 ** 9,
                    **dict(zip(NOISE_NAMES, noise)))
    assert np.all(out["road_height_std"] > 0), out["road_height_std"].min()


def test_stiff_discretisation_is_finite_and_psd():
    """Q_d of a wheel damped far faster than the step: a vehicle that diverged (P eigenvalues
    +-1e194) before Q_d was built by squaring (Van Loan's expm(-A h) ~ 1e222) matches the quadrature of expm(A s) Qc expm(A s)' over the step to
    1e-10 of max|Q_d|; the corner m_s = 1e5 kg, m_u = 1 kg, k_s = 1e8 N/m, k_t = 1e9 N/m,
    c_s = 1e7 N.s/m (beyond the contract's ranges, whose ends were these before; expm(-A h)
    overflows) gives a finite Phi = expm(A h) and a symmetric PSD Q_d."""
    from scipy.integrate import quad_vec
    from scipy.linalg import expm

    from suspension_estimation.estimators.model import discretise, noise_intensity, state_matrix

    gd = iso8608.class_psd_n0(6)
    v = Vehicle(m_s=797.37, m_u=15.66, k_s=1.0764e6, k_t=15743.0, c_s=3.9336e6)
    A, Qc, h = state_matrix(v, 6.0), noise_intensity(gd, 6.0), 2e-3
    _, Q = discretise(A, Qc, h)
    ref = quad_vec(lambda s: expm(A * s) @ Qc @ expm(A * s).T, 0.0, h, epsabs=0.0, epsrel=1e-12)[0]
    assert np.abs(Q - ref).max() <= 1e-10 * np.abs(ref).max()
    _assert_spd(Q)
    v = Vehicle(m_s=1e5, m_u=1.0, k_s=1e8, k_t=1e9, c_s=1e7)
    A, Qc, h = state_matrix(v, 20.0), noise_intensity(gd, 20.0), 1e-3
    Phi, Q = discretise(A, Qc, h)
    np.testing.assert_array_equal(Phi, expm(A * h))
    _assert_spd(Q)


# --- FMUs --------------------------------------------------------------------------------------
class Unzipped(dict):
    """{model: (model description, folder)}, printed by its models only: hypothesis prints every
    argument of a falsifying example, and the model descriptions' repr ran to 7,500 lines."""

    def __repr__(self) -> str:
        return f"<extracted FMUs: {', '.join(self)}>"


@pytest.fixture(scope="module")
def unzipped(dist):
    """Each FMU extracted once for the module: {model: (model description, folder)}."""
    out = Unzipped()
    for model in CONTRACTS:
        fmu = dist / f"{model}.fmu"
        out[model] = (read_model_description(str(fmu)), extract(str(fmu), unzipdir=tempfile.mkdtemp()))
    yield out
    for _, folder in out.values():
        shutil.rmtree(folder, ignore_errors=True)


class Instance:
    """One FMU2Slave instance on an already extracted FMU, initialized with ``params``; its log in
    ``messages`` as (status name, text). The binary stays loaded (as in harness.cosim)."""

    def __init__(self, unzipped, model: str, params: dict):
        md, folder = unzipped[model]
        self.vars = {v.name: v for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=model, instanceName="p")
        self.sink = LogSink()
        self.messages = self.sink.messages
        self.fmu.instantiate(loggingOn=True, callbacks=self.sink.callbacks)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name, value in params.items():
            self.set(name, value)
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def set(self, name: str, value) -> None:
        var = self.vars[name]
        setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger, "Boolean": self.fmu.setBoolean,
                  "String": self.fmu.setString}[var.type]
        setter([var.valueReference], [value])

    def get(self, names: list[str]) -> list[float]:
        return self.fmu.getReal([self.vars[n].valueReference for n in names])

    def step(self, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h

    def close(self) -> None:
        try:
            self.fmu.terminate()
        except FMICallException:
            pass
        self.fmu.fmi2FreeInstance(self.fmu.component)
        self.sink.close()


ESTIMATOR_REALS = [v.name for v in CONTRACTS["SuspensionEstimator"] if v.causality == "output" and v.type == "Real"]


def _drive_fmu(unzipped, v: Vehicle, road_class: int, speed: float, h: float, seed: int, T: float,
               noise: tuple[float, float, float] = dataclasses.astuple(SensorNoise())) -> None:
    """SuspensionEstimator.fmu configured for vehicle v and sensor noise ``noise`` and fed that
    vehicle's measured signals (plant core) for T s: every doStep ok, nothing logged as an
    error, every Real output finite, road_height_std > 0, the mass estimate inside m_s's range."""
    road = SyntheticRoad(iso8608.class_psd_n0(road_class), seed=seed)
    car = QuarterCar(v, SensorNoise(*noise), noise_seed=seed)
    car.settle(road.height(0.0))
    e = Instance(unzipped, "SuspensionEstimator", {"m_s_nominal": v.m_s, "m_u": v.m_u, "k_s": v.k_s,
                                                   "k_t": v.k_t, "c_s": v.c_s, **dict(zip(NOISE_NAMES, noise))})
    try:
        e.set("vehicle_speed", speed)
        for k in range(int(round(T / h))):
            car.step(road.height(speed * k * h), h)
            for name, value in zip(("acc_sprung", "acc_unsprung", "susp_deflection"), car.measured):
                e.set(name, float(value))
            e.step(h)
            out = dict(zip(ESTIMATOR_REALS, e.get(ESTIMATOR_REALS)))
            assert all(math.isfinite(x) for x in out.values()), out
            assert out["road_height_std"] > 0
            assert M_S_LOW <= out["sprung_mass_est"] <= M_S_HIGH
        assert not [m for s, m in e.messages if s in ("error", "fatal")], e.messages
    finally:
        e.close()


@FMU
@given(v=vehicles, road_class=classes, speed=speeds, h=steps, seed=seeds)
def test_estimator_fmu_on_random_vehicles(unzipped, v, road_class, speed, h, seed):
    """The FMU on a random road vehicle for 0.5 s (see _drive_fmu)."""
    _drive_fmu(unzipped, v, road_class, speed, h, seed, T=0.5)


@settings(FMU, max_examples=8)
@given(v=any_vehicles, noise=any_noise, road_class=classes, speed=speeds, h=steps, seed=seeds)
def test_estimator_fmu_over_the_whole_ranges(unzipped, v, noise, road_class, speed, h, seed):
    """The FMU on any vehicle and sensor noise its contract accepts, 0.3 s (see _drive_fmu)."""
    _drive_fmu(unzipped, v, road_class, speed, h, seed, T=0.3, noise=noise)


def _invalid(var: Var) -> st.SearchStrategy:
    """Values outside ``var.allowed``: beyond either end (or on an excluded end), NaN, +-Inf for
    a Real; any integer not in the enumeration for a mode selector."""
    a = var.allowed
    if isinstance(a, dict):
        return st.integers(-10, 20).filter(lambda x: x not in a)
    low, high, *incl = a
    lo_in, hi_in = (incl + [True, True])[:2]
    below = st.floats(max_value=low, exclude_max=lo_in, allow_nan=False, allow_infinity=False)
    above = st.floats(min_value=high, exclude_min=hi_in, allow_nan=False, allow_infinity=False)
    if var.type == "Integer":  # an fmi2Integer is 32 bits: nothing lies above 2^31 - 1
        sides = [st.integers(min_value=-2 ** 31, max_value=int(math.ceil(low)) - 1)]
        if high < 2 ** 31 - 1:
            sides.append(st.integers(min_value=int(math.floor(high)) + 1, max_value=2 ** 31 - 1))
        return st.one_of(sides)
    return st.one_of(below, above, st.sampled_from([math.nan, math.inf, -math.inf]))


# every parameter of every FMU that has a range; String parameters are checked by their own tests
BOUNDED = [(model, var) for model, contract in CONTRACTS.items() for var in contract
           if var.causality == "parameter" and var.allowed is not None and var.type in ("Real", "Integer")]


@settings(FMU, max_examples=40)  # cheap: no stepping beyond two refused steps
@given(data=st.data())
def test_invalid_parameter_is_refused_naming_it(unzipped, data):
    """A random parameter of a random FMU set outside its range: the instance logs an error
    naming the variable and its range when initialization ends, every doStep returns fmi2Discard
    (never fmi2Fatal, never a crash), and the instance can be terminated and freed."""
    model, var = data.draw(st.sampled_from(BOUNDED), label="parameter")
    value = data.draw(_invalid(var), label="value")
    inst = Instance(unzipped, model, {var.name: value})
    try:
        assert any(s == "error" and var.name in m and "range" in m for s, m in inst.messages), inst.messages
        for _ in range(2):
            with pytest.raises(FMICallException) as info:
                inst.step(1e-3)
            assert STATUS[info.value.status] == "discard"
        assert not any(s == "fatal" for s, _ in inst.messages)
    finally:
        inst.close()

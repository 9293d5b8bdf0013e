"""The estimator interface (estimators/interface.py): the registry is the contract's list of codes,
bad combinations are refused by name, and ``SuspensionEstimator`` composes a registered
``RoadFilter`` (sample checks, status, re-initialisation, RLS mass fed back, outputs)."""
from __future__ import annotations

import importlib
import math

import numpy as np
import pytest

from suspension_estimation.estimators import interface
from suspension_estimation.estimators.interface import MASS_ESTIMATORS, ROAD_ESTIMATORS, Code, RoadFilter
from suspension_estimation.estimators.kalman import LinearKF
from suspension_estimation.estimators.model import DiscreteModel, ModelNoise, RoadModel, measurement_covariance
from suspension_estimation.estimators.suspension import EstimatorConfig, SuspensionEstimator
from suspension_estimation.harness.metrics import reference_profile, road_scores
from suspension_estimation.plant import iso8608
from suspension_estimation.suspension_fmi import contract
from suspension_estimation.suspension_fmi.contract import SUSPENSION_ESTIMATOR

from test_estimators_core import simulate


class ExactKF(RoadFilter):
    """The exact-model KF at the mass it is told (a RoadFilter for the tests)."""

    def __init__(self, cfg):
        super().__init__(cfg)
        self.m_s, self.kf, self.masses = float(cfg.m_s_nominal), None, []
        self.R = measurement_covariance(cfg.acc_sprung_noise_std, cfg.acc_unsprung_noise_std, cfg.defl_noise_std)

    def _build(self, speed, h):
        m = DiscreteModel.build(self.cfg.vehicle(self.m_s), max(speed, 0.1), iso8608.class_psd_n0(6), h,
                                RoadModel(), ModelNoise(), True, 0, False)
        x = None if self.kf is None else self.kf.x
        self.kf = LinearKF(6, 3, fast=False)
        self.kf.set_model(m.Phi, m.Q, m.H, self.R)
        self.kf.stationary()
        if x is not None:
            self.kf.x = x
        self.h, self.speed = h, speed
        self.model_builds += 1

    def step(self, z, rows, speed, h):
        if self.kf is None or h != self.h or self.m_s != self._built_m:
            self._built_m = self.m_s
            self._build(speed, h)
        if rows is None:
            self.kf.step(z)
        else:
            self.kf.predict_only()
            if len(rows):
                self.kf.update_rows(z, rows)
        self.x = self.kf.x.tolist()
        self.road_variance = float(self.kf.P[4, 4])
        self.nis = float(self.kf.nis)

    def set_mass(self, m_s):
        self.m_s = m_s
        self.masses.append(m_s)

    def reset(self):
        self.kf.x = np.zeros(6)
        self.x = [0.0] * 6


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setitem(ROAD_ESTIMATORS, 90, Code("test KF", "test_interface:ExactKF"))
    monkeypatch.setattr(interface, "composed_factory",
                        lambda road, mass: ExactKF if road == 90 else None)
    import suspension_estimation.estimators.suspension as suspension
    monkeypatch.setattr(suspension, "composed_factory", interface.composed_factory)
    return 90


def test_every_code_of_the_contract_is_implemented():
    """The registry takes the codes and names from the contract; each is the KF family's or has
    a factory, and every factory's class exists."""
    assert interface.unimplemented_codes() == []
    for c in (*ROAD_ESTIMATORS.values(), *MASS_ESTIMATORS.values()):
        if c.factory is not None:
            module, cls = c.factory.split(":")
            assert issubclass(getattr(importlib.import_module(f"suspension_estimation.estimators.{module}"), cls),
                              RoadFilter)


def test_the_contract_lists_every_registered_code():
    var = {v.name: v for v in SUSPENSION_ESTIMATOR}
    for name, codes, meanings in (("road_estimator", ROAD_ESTIMATORS, contract.ROAD_ESTIMATORS),
                                  ("mass_estimator", MASS_ESTIMATORS, contract.MASS_ESTIMATORS)):
        assert var[name].allowed == {k: c.name for k, c in codes.items()}
        assert {k: n for k, (n, _) in meanings.items()} == var[name].allowed
        for k, (_, meaning) in meanings.items():
            assert f"{k} = {meaning}" in var[name].description


def test_unknown_codes_and_bad_combinations_are_refused_by_name(monkeypatch):
    with pytest.raises(ValueError, match=r"road_estimator = 77 is outside the allowed values \{0 = Kalman"):
        SuspensionEstimator(road_estimator=77)
    with pytest.raises(ValueError, match="mass_estimator = 2.5 must be an integer"):
        SuspensionEstimator(mass_estimator=2.5)
    monkeypatch.setitem(MASS_ESTIMATORS, 91, Code("joint", None, roads=(0,)))
    with pytest.raises(ValueError, match=r"mass_estimator = 91 \(joint\) gives the road itself and needs "
                                         r"road_estimator in \{0\}, not 2"):
        SuspensionEstimator(mass_estimator=91)


def test_a_registered_filter_is_composed(registered):
    """410 kg plant, the estimator told 330 kg: the RLS finds the mass and feeds it to the filter.
    The outputs are the filter's states, and road_height_est the profile of its road (a filter
    of the registry: no reference taken off, high-passed in distance): HP error 2.1-2.5 % over
    seeds 1-5 (the test: 2), gain 1.004-1.010."""
    speed = 40 / 3.6
    t, meas, truth, ms = simulate(road_class=3, T=8.0, seed=2)
    est = SuspensionEstimator(EstimatorConfig(road_estimator=registered, m_s_nominal=330.0))
    f = est.composed
    assert isinstance(f, ExactKF)
    bad = {1000: (math.nan, 0), 2000: (1e300 * 1e300, 1)}  # a NaN sample; an infinite one
    out, roads = [], []
    for k, z in enumerate(meas):
        z = z.copy()
        if k in bad:
            z[bad[k][1]] = bad[k][0]
        o = dict(est.step(z[0], z[1], z[2], speed, 1e-3 * (1 + 1e-12 * (k % 3))))  # with jitter
        out.append(o)
        roads.append(f.x[4])
        assert o["z_u_est"] == f.x[2] and o["z_s_est"] == f.x[0] and o["status"] == (1 if k in bad else 0)
        assert o["z_u_est"] - o["tire_deflection_est"] == pytest.approx(f.x[4], rel=0, abs=1e-15)
    assert f.model_builds == len(f.masses) + 1  # the jitter rebuilds nothing; each fed-back mass does
    assert abs(out[-1]["sprung_mass_est"] / 410.0 - 1) < 0.02
    assert f.masses and abs(f.masses[-1] / 410.0 - 1) < 0.02
    profile = np.array([o["road_height_est"] for o in out])
    np.testing.assert_allclose(profile, reference_profile(speed * t, np.array(roads)), rtol=0, atol=1e-12)
    sc = road_scores(t, profile, truth[:, 4], warmup=4.0, distance=speed * t)
    assert sc["err_std_hp_pct"] < 4.0 and 0.95 < sc["gain_hp"] < 1.05, sc
    # a non-finite state re-initialises (status 2) and the estimate goes on finite
    f.step = lambda *a: setattr(f, "x", [math.nan] * 6)
    o = est.step(*meas[-1], 40 / 3.6, 1e-3)
    assert o["status"] == 2 and math.isfinite(o["road_height_est"])


def test_estimator_config_is_the_contract_parameters():
    """EstimatorConfig holds exactly the FMU's parameters, with the contract's defaults; every
    other knob is a fixed choice in estimators/tuning.py, not a parameter."""
    from dataclasses import fields

    params = {v.name: v.start for v in SUSPENSION_ESTIMATOR if v.causality == "parameter"}
    cfg = EstimatorConfig()
    assert {f.name for f in fields(cfg)} - {"tuning"} == set(params)
    for name, start in params.items():
        assert getattr(cfg, name) == start, name


def test_the_core_refuses_what_the_contract_refuses():
    """Each ranged parameter of the contract: the core takes both ends of its range (or values
    just inside an open end) and refuses a value beyond each, naming it; the FMU's check and the
    core's cannot drift apart."""
    for v in SUSPENSION_ESTIMATOR:
        if v.causality != "parameter" or not isinstance(v.allowed, tuple) or v.type not in ("Real", "Integer"):
            continue
        lo, hi, lo_in, hi_in = (*v.allowed, True, True)[:4]
        step = 1 if v.type == "Integer" else 1e-9 * max(abs(lo), abs(hi), 1.0)
        for value, ok in ((lo if lo_in else lo + step, True), (hi if hi_in else hi - step, True),
                          (lo - step if lo_in else lo, False), (hi + step if hi_in else hi, False)):
            if not math.isfinite(value):
                continue
            try:
                SuspensionEstimator(**{v.name: value})
                msgs = []
            except ValueError as e:
                msgs = str(e).split("; ")
            named = [m for m in msgs if m.startswith(v.name + " ") and ("range" in m or " in [" in m)]
            assert bool(named) != ok, (v.name, value, named)

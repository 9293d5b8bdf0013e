"""The quarter-car estimator on each corner of the half car, against the same estimator on a
quarter car of that corner (docs/half-car.md, "The quarter-car estimator on a corner").

    .venv/bin/python benchmarks/half_car_corners.py [--classes B,C,D] [--speeds 40,80] [--seeds 3]
        [--duration 60] [--noise 1] [--told-noise 1] [--fmu-check] [--apparent-mass] [--observer]

Plant: plant.HalfCar with its defaults (passive, no actuator force) on an ISO 8608 road, the
rear tyre one wheelbase behind the front one (the road at distance - wheelbase). On each corner
a SuspensionEstimator in its default configuration, told that corner's quarter car
(``corner_vehicle``: m_s_nominal the static corner load, m_u, k_s, k_t, c_s of the axle), fed the
body acceleration above the axle, the wheel acceleration and the deflection. Baseline: the same
estimator on plant.QuarterCar with that corner's vehicle on the road under that wheel. Scores
after the 10 s warm-up, means over seeds: HP road error std % (harness.metrics.road_scores:
road_height_est, the profile, against metrics.reference_profile of the road under the wheel),
mean sprung-mass error % against the static corner load;
PASS when the half car's HP error is within RATIO times the quarter car's.

The road is stepped as the FMUs' Gauss-Seidel master steps it (ISORoad before the plant): the
plant's step k holds the road at the end of the step, distance v (k + 1) h, and the plants start
at rest on the road at distance 0 (-wheelbase for the rear). ``--fmu-check`` runs one cell
(ISO C, 40 km/h, seed 1) also through HalfCar.fmu, ISORoad.fmu and two SuspensionEstimator.fmu
instances (harness.cosim; ``python build.py`` first) and prints both. ``--apparent-mass`` prints
m_eff(f) = F_susp / a_body of each corner (``apparent_mass``) against the corner load, and the
road error pitch coupling alone costs a quarter-car model of the corner (``coupling_error``).
``--observer`` also scores the half car's own observer (estimators.half_car_imm.HalfCarObserver,
HalfCarEstimator.fmu's core, its defaults: IMMAKF5 on the real car's sensors, told the car) on the
same runs: HP error std % of its road_height_front_est / road_height_rear_est.
``--noise`` scales the plants' sensor noise (both plants, and what the estimators are told);
``--told-noise`` scales what the estimators are told on top (< 1: they trust the sensors more
than their noise warrants), and the table adds the ±2 road_height_std coverage.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from suspension_estimation.estimators import SuspensionEstimator  # noqa: E402
from suspension_estimation.harness.metrics import HP_CUTOFF, HP_ORDER, road_scores  # noqa: E402
from suspension_estimation.plant import iso8608  # noqa: E402
from suspension_estimation.plant.half_car import (DEFAULT_HALF_CAR, HalfCar, HalfCarParams, damping_matrix,  # noqa: E402
                                                  input_matrix, mass_matrix, stiffness_matrix)
from suspension_estimation.plant.quarter_car import QuarterCar, SensorNoise  # noqa: E402
from suspension_estimation.plant.road import SyntheticRoad  # noqa: E402
from suspension_estimation.plant.vehicle import Vehicle  # noqa: E402

H = 1e-3  # s
WARMUP = 10.0  # s
RATIO = 1.3  # target: HP error on the half car's corner within this factor of the quarter car's
CORNERS = ("front", "rear")
DIST = Path(__file__).resolve().parents[1] / "dist"


def corner_load(p: HalfCarParams, corner: str) -> float:
    """Static sprung load (kg) on one corner: the lever rule, m_s l_r / L front, m_s l_f / L rear."""
    return p.m_s * (p.l_r if corner == "front" else p.l_f) / p.wheelbase


def corner_vehicle(p: HalfCarParams, corner: str) -> Vehicle:
    """The quarter car of one corner of the half car: its static load (kg) and that axle's
    m_u (kg), k_s, k_t (N/m), c_s (N.s/m)."""
    f = corner == "front"
    return Vehicle(m_s=corner_load(p, corner), m_u=p.m_uf if f else p.m_ur, k_s=p.k_f if f else p.k_r,
                   k_t=p.k_tf if f else p.k_tr, c_s=p.c_f if f else p.c_r)


def drive_half_car(p: HalfCarParams, cls: int, speed: float, duration: float, seed: int,
                   noise: SensorNoise = SensorNoise()) -> dict:
    """Run the half car on ISO class ``cls`` (1 = A) road ``seed`` at ``speed`` m/s for
    ``duration`` s. Returns t (s, end of each step), per corner its measurements (n x 3:
    body acceleration m/s2, wheel acceleration m/s2, deflection m) and the road under its tyre (m)."""
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    L = p.wheelbase
    car = HalfCar(p, noise, noise_seed=1000 + seed)
    car.settle(road.height(0.0), road.height(-L))
    n = int(round(duration / H))
    meas, zr = np.empty((n, 6)), np.empty((n, 2))
    for k in range(n):
        s = speed * (k + 1) * H
        zr[k] = road.height(s), road.height(s - L)
        car.step(zr[k, 0], zr[k, 1], H)
        meas[k] = car.measured
    t = np.arange(1, n + 1) * H
    return {"t": t, "front": (meas[:, [0, 2, 4]], zr[:, 0]), "rear": (meas[:, [1, 3, 5]], zr[:, 1])}


def drive_quarter_car(v: Vehicle, cls: int, speed: float, duration: float, seed: int,
                      behind: float = 0.0, noise: SensorNoise = SensorNoise()) -> tuple[np.ndarray, np.ndarray]:
    """The quarter car ``v`` on the same road, ``behind`` m behind the front tyre: its measurements
    (n x 3, as drive_half_car's) and the road under it (m)."""
    road = SyntheticRoad(iso8608.class_psd_n0(cls), seed=seed)
    car = QuarterCar(v, noise, noise_seed=1000 + seed)
    car.settle(road.height(-behind))
    n = int(round(duration / H))
    meas, zr = np.empty((n, 3)), np.empty(n)
    for k in range(n):
        zr[k] = road.height(speed * (k + 1) * H - behind)
        car.step(zr[k], H)
        meas[k] = car.measured
    return meas, zr


def estimate(meas: np.ndarray, v: Vehicle, speed: float, told: SensorNoise = SensorNoise(),
             std: bool = False) -> tuple[np.ndarray, ...]:
    """Road estimate (m) and sprung-mass estimate (kg) per step of the default SuspensionEstimator
    told the quarter car ``v`` and the sensor noise ``told``, fed ``meas`` (n x 3) at ``speed``
    m/s; with ``std`` also road_height_std (m)."""
    est = SuspensionEstimator(m_s_nominal=v.m_s, m_u=v.m_u, k_s=v.k_s, k_t=v.k_t, c_s=v.c_s,
                              acc_sprung_noise_std=told.acc_sprung, acc_unsprung_noise_std=told.acc_unsprung,
                              defl_noise_std=told.deflection)
    out = np.array([(o["road_height_est"], o["sprung_mass_est"], o["road_height_std"])
                    for o in (est.step(z[0], z[1], z[2], speed, H) for z in meas)])
    return (out[:, 0], out[:, 1], out[:, 2]) if std else (out[:, 0], out[:, 1])


def scores(t: np.ndarray, road_est: np.ndarray, mass_est: np.ndarray, road: np.ndarray,
           load: float, distance: np.ndarray, road_std: np.ndarray | None = None) -> tuple[float, ...]:
    """(HP road error std %, mean sprung-mass error % against ``load`` kg) after the warm-up;
    ``distance``: m travelled at each sample; with ``road_std`` (m) also the share of samples
    whose profile error is within +-2 of it."""
    r = road_scores(t, road_est, road, road_std, warmup=WARMUP, distance=distance)
    out = (r["err_std_hp_pct"], float(100 * (np.mean(mass_est[t >= WARMUP]) / load - 1)))
    return out if road_std is None else (*out, r["coverage_2sigma"])


def scaled(noise: SensorNoise, factor: float) -> SensorNoise:
    return SensorNoise(factor * noise.acc_sprung, factor * noise.acc_unsprung, factor * noise.deflection)


def cell(p: HalfCarParams, cls: int, speed: float, duration: float, seeds: range, noise: float = 1.0,
         told: float = 1.0) -> dict:
    """Per corner the means over ``seeds`` of (HP % half car, HP % quarter car, mass % half car,
    mass % quarter car, coverage half car, coverage quarter car): the plants' sensor noise
    ``noise`` times SensorNoise(), the estimators told ``told`` times that."""
    plant_noise = scaled(SensorNoise(), noise)
    told_noise = scaled(plant_noise, told)
    runs = {c: [] for c in CORNERS}
    for seed in seeds:
        half = drive_half_car(p, cls, speed, duration, seed, plant_noise)
        for c in CORNERS:
            v = corner_vehicle(p, c)
            meas, road = half[c]
            d = speed * half["t"]
            est_h = estimate(meas, v, speed, told_noise, std=True)
            hc = scores(half["t"], est_h[0], est_h[1], road, v.m_s, d, est_h[2])
            qmeas, qroad = drive_quarter_car(v, cls, speed, duration, seed, 0.0 if c == "front" else p.wheelbase,
                                             plant_noise)
            est_q = estimate(qmeas, v, speed, told_noise, std=True)
            qc = scores(half["t"], est_q[0], est_q[1], qroad, v.m_s, d, est_q[2])
            runs[c].append((hc[0], qc[0], hc[1], qc[1], hc[2], qc[2]))
    return {c: np.mean(r, axis=0) for c, r in runs.items()}


def observer_cell(p: HalfCarParams, cls: int, speed: float, duration: float, seeds: range) -> dict:
    """Per corner the mean over ``seeds`` of the HP road error std % of the half car's observer
    (HalfCarObserver at its defaults) on the runs of ``drive_half_car``."""
    from suspension_estimation.estimators.half_car_imm import HalfCarObserver

    runs = {c: [] for c in CORNERS}
    for seed in seeds:
        half = drive_half_car(p, cls, speed, duration, seed)
        t = half["t"]
        (fm, fr), (rm, rr) = half["front"], half["rear"]
        meas = np.column_stack([fm[:, 0], rm[:, 0], fm[:, 1], rm[:, 1], fm[:, 2], rm[:, 2]])  # its sensor order
        obs = HalfCarObserver(p)
        out = [obs.step(z, (0.0, 0.0), speed, H) for z in meas]
        for c, road in (("front", fr), ("rear", rr)):
            est = np.array([o[f"road_height_{c}_est"] for o in out])
            runs[c].append(road_scores(t, est, road, warmup=WARMUP, distance=speed * t)["err_std_hp_pct"])
    return {c: float(np.mean(r)) for c, r in runs.items()}


def corner_response(p: HalfCarParams, f: np.ndarray, speed: float,
                    corner: str) -> tuple[np.ndarray, np.ndarray]:
    """(body displacement above the axle m, suspension force on the body there N, pushing it up),
    complex, per m of road, at the frequencies f (Hz) of a road travelled at ``speed`` m/s: the
    half car's transfer functions, the rear tyre meeting the road wheelbase / speed later."""
    M, C, K, F = mass_matrix(p), damping_matrix(p), stiffness_matrix(p), input_matrix(p)
    front = corner == "front"
    arm = p.l_f if front else -p.l_r  # the body point above the axle: z + arm theta
    k, c, wheel = (p.k_f, p.c_f, 2) if front else (p.k_r, p.c_r, 3)
    body, force = np.empty(len(f), complex), np.empty(len(f), complex)
    for i, fi in enumerate(f):
        w = 2 * np.pi * fi
        u = [1.0, np.exp(-1j * w * p.wheelbase / speed), 0.0, 0.0]  # road under the front, rear tyre
        q = np.linalg.solve(-w * w * M + 1j * w * C + K, F @ u)
        body[i] = q[0] + arm * q[1]
        force[i] = (k + 1j * w * c) * (q[wheel] - body[i])
    return body, force


def apparent_mass(p: HalfCarParams, f: np.ndarray, speed: float, corner: str) -> np.ndarray:
    """Apparent sprung mass (kg, complex) of one corner at frequencies f (Hz) on a road travelled at
    ``speed`` m/s: m_eff = F / a, the suspension force on the body at that axle (N) over the body's
    vertical acceleration above it (m/s2). Through the pitch inertia the body point also accelerates
    with the other axle's force, a_front = F_f (1/m + l_f^2/I) + F_r (1/m - l_f l_r/I), so m_eff
    moves with the ratio F_r / F_f and hence with f and the speed; with I = m l_f l_r (dynamic index
    1) the F_r term vanishes and m_eff is the static corner load at every f."""
    f = np.atleast_1d(np.asarray(f, float))
    body, force = corner_response(p, f, speed, corner)
    return force / (-(2 * np.pi * f) ** 2 * body)


def coupling_error(p: HalfCarParams, speed: float, corner: str,
                   m_model: float | None = None) -> tuple[float, float]:
    """What pitch coupling alone costs a quarter-car model of one corner, from the transfer
    functions on an ISO 8608 road (waviness 2, its band; the class cancels) at ``speed`` m/s.

    The quarter-car model balances the whole corner, m a_body + m_u a_wheel = k_t (z_r - z_u): on
    the half car the body point also moves with the other axle, so the road read from that balance
    is off by (m a_body - F_susp) / k_t = (m - m_eff(f)) a_body / k_t (the wheel's own equation is
    exact). Returns (the std of that error in the HP band over the HP road's std, %, with the model
    mass ``m_model`` kg, default the corner load; the mass m (kg) for which it is least: the real
    part of m_eff weighted by |a_body|^2 in the HP band)."""
    f = np.geomspace(0.05, 60.0, 2000)
    body, force = corner_response(p, f, speed, corner)
    acc = -(2 * np.pi * f) ** 2 * body
    n = f / speed  # cycle/m
    road = np.where((n >= iso8608.N_MIN) & (n <= iso8608.N_MAX), iso8608.psd(n, 1.0), 0.0) / speed
    hp = 1.0 / (1.0 + (HP_CUTOFF / f) ** (2 * HP_ORDER))  # |H|^2 of the Butterworth; filtfilt squares it
    weight = road * hp ** 2 * np.gradient(f)
    m_ls = float(np.sum(weight * np.real(force * np.conj(acc))) / np.sum(weight * np.abs(acc) ** 2))
    m = corner_load(p, corner) if m_model is None else m_model
    k_t = p.k_tf if corner == "front" else p.k_tr
    err = np.sum(weight * np.abs(m * acc - force) ** 2) / k_t ** 2
    return float(100 * np.sqrt(err / np.sum(weight))), m_ls


def dynamic_index(p: HalfCarParams) -> float:
    """pitch_inertia / (m_s l_f l_r): 1 when the axles move independently (a decoupled car)."""
    return p.pitch_inertia / (p.m_s * p.l_f * p.l_r)


def fmu_check(p: HalfCarParams, cls: int, speed: float, duration: float, seed: int) -> dict:
    """Per corner (HP % , mass %) of one run through HalfCar.fmu, ISORoad.fmu (wheelbase set) and
    two SuspensionEstimator.fmu instances on harness.cosim's Gauss-Seidel master, at the defaults
    of ``p`` (HalfCar.fmu's own defaults)."""
    from suspension_estimation.harness.cosim import CoSimulation, System

    comps = {"road": DIST / "ISORoad.fmu", "car": DIST / "HalfCar.fmu",
             "front": DIST / "SuspensionEstimator.fmu", "rear": DIST / "SuspensionEstimator.fmu"}
    conns = [("vehicle_speed", "road.vehicle_speed"), ("road.road_height", "car.road_height_front"),
             ("road.road_height_rear", "car.road_height_rear")]
    params = {"road.road_class": cls, "road.seed": seed, "road.wheelbase": p.wheelbase,
              "car.noise_seed": 1000 + seed}
    for c in CORNERS:
        conns += [("vehicle_speed", f"{c}.vehicle_speed"), (f"car.acc_body_{c}", f"{c}.acc_sprung"),
                  (f"car.acc_unsprung_{c}", f"{c}.acc_unsprung"), (f"car.susp_deflection_{c}", f"{c}.susp_deflection")]
        v = corner_vehicle(p, c)
        params.update({f"{c}.m_s_nominal": v.m_s, f"{c}.m_u": v.m_u, f"{c}.k_s": v.k_s, f"{c}.k_t": v.k_t,
                       f"{c}.c_s": v.c_s})
    record = ["road.road_height", "road.road_height_rear", "road.distance"] + [f"{c}.{x}" for c in CORNERS
                                                              for x in ("road_height_est", "sprung_mass_est")]
    system = System(components=comps, connections=conns, order=["road", "car", "front", "rear"])
    with CoSimulation(system, parameters=params, inputs={"vehicle_speed": speed}, record=record) as sim:
        r = sim.run(stop_time=duration, step_size=H)
    t = r["time"][1:]
    roads = {"front": r["road.road_height"][1:], "rear": r["road.road_height_rear"][1:]}
    return {c: scores(t, r[f"{c}.road_height_est"][1:], r[f"{c}.sprung_mass_est"][1:], roads[c],
                      corner_load(p, c), r["road.distance"][1:]) for c in CORNERS}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--classes", default="B,C,D", help="ISO classes of the grid ('' for none)")
    ap.add_argument("--speeds", default="40,80", help="km/h")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--duration", type=float, default=60.0, help="s (the first 10 s are not scored)")
    ap.add_argument("--noise", type=float, default=1.0, help="factor on the plants' sensor noise")
    ap.add_argument("--told-noise", type=float, default=1.0, help="factor on the noise the estimators are told")
    ap.add_argument("--fmu-check", action="store_true", help="also one run (ISO C, 40 km/h, seed 1) through the FMUs")
    ap.add_argument("--apparent-mass", action="store_true", help="also print m_eff(f) of each corner")
    ap.add_argument("--observer", action="store_true", help="also score the half car's own observer's road")
    a = ap.parse_args(argv)
    if a.duration <= WARMUP or a.seeds < 1 or not (0 < a.noise <= 100 and 0 < a.told_noise <= 100):
        print(f"error: --duration must exceed {WARMUP} s, --seeds be >= 1, --noise and --told-noise in (0, 100]",
              file=sys.stderr)
        return 1
    p = DEFAULT_HALF_CAR
    print(f"half car: defaults, dynamic index {dynamic_index(p):.3f}; corner loads front "
          f"{corner_load(p, 'front'):.1f} kg, rear {corner_load(p, 'rear'):.1f} kg; {a.seeds} seeds of {a.duration:g} s; "
          f"sensor noise x{a.noise:g}, told x{a.told_noise:g}\n")
    print("| ISO | km/h | corner | HP % half car | HP % quarter car | ratio | mass % half car | mass % quarter car | "
          f"+-2 std coverage half / quarter | HP within {RATIO}x |\n|---|---|---|---|---|---|---|---|---|---|")
    speeds = [float(v) for v in a.speeds.split(",")]
    for letter in filter(None, a.classes.split(",")):
        cls = "ABCDEFGH".index(letter.strip().upper()) + 1
        for kmh in speeds:
            res = cell(p, cls, kmh / 3.6, a.duration, range(1, a.seeds + 1), a.noise, a.told_noise)
            for c in CORNERS:
                hh, hq, mh, mq, ch, cq = res[c]
                print(f"| {letter.strip().upper()} | {kmh:g} | {c} | {hh:.2f} | {hq:.2f} | {hh / hq:.2f} | {mh:+.2f} | "
                      f"{mq:+.2f} | {ch:.2f} / {cq:.2f} | {'PASS' if hh <= RATIO * hq else 'MISS'} |", flush=True)
    if a.observer:
        print("\nthe half car's observer (HalfCarObserver, IMMAKF5), HP road error std %\n"
              "| ISO | km/h | front | rear |\n|---|---|---|---|")
        for letter in filter(None, a.classes.split(",")):
            cls = "ABCDEFGH".index(letter.strip().upper()) + 1
            for kmh in speeds:
                res = observer_cell(p, cls, kmh / 3.6, a.duration, range(1, a.seeds + 1))
                print(f"| {letter.strip().upper()} | {kmh:g} | {res['front']:.2f} | {res['rear']:.2f} |", flush=True)
    if a.fmu_check:
        speed = 40 / 3.6
        core = drive_half_car(p, 3, speed, a.duration, 1)
        fmu = fmu_check(p, 3, speed, a.duration, 1)
        print(f"\nISO C, 40 km/h, seed 1, {a.duration:g} s: cores against FMUs (HP %, mass %)")
        for c in CORNERS:
            v = corner_vehicle(p, c)
            meas, road = core[c]
            hp, m = scores(core["t"], *estimate(meas, v, speed), road, v.m_s, speed * core["t"])
            print(f"  {c}: cores {hp:.6f} {m:+.6f}   FMUs {fmu[c][0]:.6f} {fmu[c][1]:+.6f}")
    if a.apparent_mass:
        f = np.array([0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0, 5.0, 10.0])
        print("\napparent mass |m_eff(f)| kg (phase deg) against the corner load\n| km/h | corner | load | "
              + " | ".join(f"{x:g} Hz" for x in f) + " |\n|---|---|---|" + "---|" * len(f))
        for kmh in speeds:
            for c in CORNERS:
                m = apparent_mass(p, f, kmh / 3.6, c)
                print(f"| {kmh:g} | {c} | {corner_load(p, c):.0f} | "
                      + " | ".join(f"{abs(x):.0f} ({np.degrees(np.angle(x)):+.0f})" for x in m) + " |")
        print("\nroad error % of pitch coupling alone (coupling_error), the model at the corner load and at the "
              "best fixed mass\n| km/h | corner | load kg | at the load | best mass kg | at the best mass |\n"
              "|---|---|---|---|---|---|")
        for kmh in speeds:
            for c in CORNERS:
                at_load, best = coupling_error(p, kmh / 3.6, c)
                print(f"| {kmh:g} | {c} | {corner_load(p, c):.1f} | {at_load:.2f} | {best:.1f} "
                      f"({100 * (best / corner_load(p, c) - 1):+.1f} %) | {coupling_error(p, kmh / 3.6, c, best)[0]:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Calibrate the vehicle on a section of known profile: ``python -m suspension_estimation.harness
calibrate LOG --profile REF --mass KG --out vehicle.toml``.

The estimator needs ``m_u``, ``k_s``, ``k_t`` and ``c_s``, which its three signals alone cannot
identify (docs/robustness.md, the identifiability floor). With the road known they can be, as road
agencies calibrate response-type roughness meters on a section whose true profile they measured
(World Bank Technical Paper 46). The linear quarter car (plant/quarter_car.py)

    m_s a_s = -k_s d - c_s d',                       d = z_s - z_u
    m_u a_u =  k_s d + c_s d' - k_t (z_u - z_r)

is driven over the known road z_r(s), from rest on z_r(s_0), the road held over each sample
interval at its value at the interval's end (as QuarterCar.fmu is fed in the harness), and
discretised exactly. The wheel is at s = offset + delta + (1 + eps) x on the profile, x the
logged distance (the speed held over each step, as the FMUs count it), ``offset`` the given
placement and delta, eps its error and the speed's scale error, fitted. The response
y = (a_s, a_u, d) is fitted to the logged one by weighted least squares,

    min over theta = (ln m_u, ln k_s, ln k_t, ln c_s, delta, eps, b_s, b_u, d_0) of
        sum_k sum_j ((y_meas[k, j] - y_model[k, j](theta) - bias_j) / sigma_j)^2,

over the samples after ``settle`` seconds; sigma_j are the sensors' noise stds, b_s and b_u the
body and wheel accelerometers' biases and d_0 the deflection sensor's offset (nuisance
parameters, all identifiable: the model's mean accelerations and deflection are near zero).
Start values: the contract's vehicle scaled by m_s / 410 kg (the same natural frequencies), and
the placement that fits that vehicle best (delta from a grid over +-``search`` m, then delta, eps
and the biases fitted with the vehicle held).

Only ratios are identified: A and B hold m_u/m_s, k_s/m_s, k_t/m_s, c_s/m_s only, so m_s, m_u,
k_s, k_t and c_s all scaled by lambda give the same signals. The sprung mass ``m_s`` is
therefore given, and every value found scales with it. The 1-sigma uncertainties are
sqrt(diag(s^2 (J^T J)^-1)) at the optimum, J the Jacobian of the weighted residuals and
s^2 = (sum of squared weighted residuals) / (n - 9), the residual variance; they leave out the
given mass's own error (a mass x % off puts all four x % off).

The log is read by harness/estimate.py's ``read_log`` (CSV or MDF, ``--map`` and ``--unit`` as
for ``estimate``; a missing sample leaves its row out of the fit), the profile by
plant/profile_formats.py (CSV, ERD, OpenCRG) and played as ISORoad plays it (PCHIP).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import least_squares
from scipy.signal import lfilter

from ..plant.profile_formats import read_profile
from ..plant.quarter_car import SensorNoise, discretise, state_matrices
from ..plant.vehicle import DEFAULT_VEHICLE, VEHICLE_RANGES, Vehicle
from .estimate import Log, LogError, distance, read_log

SIGNALS = ("acc_sprung", "acc_unsprung", "susp_deflection")
UNITS = {"acc_sprung": "m/s2", "acc_unsprung": "m/s2", "susp_deflection": "m"}
PARAMETERS = {"m_u": "kg", "k_s": "N/m", "k_t": "N/m", "c_s": "N.s/m"}
# Most samples fitted: 10 min at 1 kHz (a calibration section is a few hundred metres). The fit
# holds a Jacobian of 3 x 9 doubles a sample, 130 MB at the limit.
MAX_ROWS = 600_000
SETTLE = 2.0  # s not scored at the start: the body mode's start transient decays as exp(-c_s t / 2 m_s)
SEARCH = 2.0  # m either side of the given placement searched for the start value of delta
SEARCH_STEP = 0.05  # m: well inside the local fit's reach (alone it converged from 0.3 m off in exploration)
MIN_LENGTH = 100.0  # m: a shorter section is warned about
MAX_REL_STD = 0.05  # a parameter with a larger relative 1-sigma is warned about


@dataclass
class Calibration:
    """What the fit found: ``vehicle`` (m_s as given), ``std`` the 1-sigma of each of m_u, k_s, k_t,
    c_s (their units), ``nuisance`` the sensor bias / offset and its 1-sigma (m/s2, m/s2, m),
    ``placement`` the profile distance of the log's start (m) and the scale true / logged distance,
    each with its 1-sigma, ``rms`` the residual rms per signal (its unit), the section's ``length``
    (m), mean ``speed`` (m/s) and ``duration`` (s), and ``warnings`` (empty when the section
    identifies the vehicle)."""

    vehicle: Vehicle
    std: dict[str, float]
    nuisance: dict[str, tuple[float, float]]
    placement: tuple[tuple[float, float], tuple[float, float]]
    rms: dict[str, float]
    noise: SensorNoise
    length: float
    speed: float
    duration: float
    settle: float
    warnings: list[str] = field(default_factory=list)
    sources: tuple[str, str] = ("log", "profile")


def simulate(vehicle: Vehicle, road: np.ndarray, h: float) -> np.ndarray:
    """(n, 3) noise-free acc_sprung (m/s2), acc_unsprung (m/s2), susp_deflection (m) of the linear
    quarter car starting at rest on road[0], row k at the end of a step of h s with road[k] held.

    Modal form of the exact discretisation: A = V diag(mu) V^-1, so q = V^-1 x advances as
    q[k+1] = exp(mu h) q[k] + (exp(mu h) - 1)/mu V^-1 B u[k], one first-order filter per mode;
    y = C x + D u with C the rows of a_s, a_u (of A) and d = z_s - z_u."""
    A, B = state_matrices(vehicle)
    C = np.array([A[1], A[3], [1.0, 0.0, -1.0, 0.0]])
    D = np.array([B[1], B[3], 0.0])
    u = np.asarray(road, float) - road[0]  # at rest on road[0]: the response to the change from it
    mu, V = np.linalg.eig(A)
    if np.linalg.cond(V) < 1e8:
        a = np.exp(mu * h)
        g = (a - 1) / mu * np.linalg.solve(V, B)
        CV = C @ V
        y = np.zeros((len(u), 3))
        for i in range(4):
            y += np.real(np.outer(lfilter([g[i]], [1.0, -a[i]], u), CV[:, i]))
    else:  # (nearly) repeated eigenvalues: step the state
        Ad, Bd = discretise(A, B, h)
        x, y = np.zeros(4), np.empty((len(u), 3))
        for k, uk in enumerate(u):
            x = Ad @ x + Bd * uk
            y[k] = C @ x
    return y + np.outer(u, D)


def calibrate(log: Log, profile: tuple[np.ndarray, np.ndarray], m_s: float, noise: SensorNoise = SensorNoise(),
              settle: float = SETTLE, offset: float = 0.0, search: float = SEARCH) -> Calibration:
    """Fit m_u, k_s, k_t, c_s (and the sensor offsets and the placement) of a quarter car of sprung
    mass ``m_s`` (kg) to ``log`` driven over ``profile`` (distance m, elevation m), its start at
    ``offset`` m of the profile to within ``search`` m; see the module doc."""
    if len(log.time) > MAX_ROWS:
        raise LogError(f"{log.path} holds {len(log.time)} samples, more than the {MAX_ROWS} a calibration fits: "
                       "cut it to the calibration section")
    if np.any(log.channels["vehicle_speed"] < 0):
        raise LogError(f"{log.path}: negative vehicle_speed at "
                       f"{log.time[np.flatnonzero(log.channels['vehicle_speed'] < 0)[0]]:.6g} s")
    if not VEHICLE_RANGES["m_s"][0] <= m_s <= VEHICLE_RANGES["m_s"][1]:
        raise LogError(f"--mass {m_s:g} kg is outside the contract's range of m_s "
                       f"[{VEHICLE_RANGES['m_s'][0]:g}, {VEHICLE_RANGES['m_s'][1]:g}] kg")
    sigma = np.array([noise.acc_sprung, noise.acc_unsprung, noise.deflection])
    if not np.all(sigma > 0):
        raise LogError(f"noise stds must be > 0, got {tuple(sigma)}")
    if not 0 <= search <= 100:
        raise LogError(f"--search {search:g} m is outside [0, 100] m")
    x, h = distance(log), log.step
    ps, pz = profile
    end = float(ps[-1] - ps[0])
    if not 0 <= offset <= offset + x[-1] <= end * (1 + 1e-12):
        raise LogError(f"the profile covers 0-{end:.3f} m; the log drives {offset:.3f}-{offset + x[-1]:.3f} m of it")
    meas = np.column_stack([log.channels[s] for s in SIGNALS])
    # a missing (NaN) measurement leaves its row out; the model still runs through it
    scored = (log.time - log.time[0] >= settle) & np.all(np.isfinite(meas), axis=1)
    if scored.sum() < 100:
        raise LogError(f"{log.path} has {scored.sum()} complete samples after the {settle:g} s of settling; "
                       "at least 100 are needed")
    meas = meas[scored]
    curve = PchipInterpolator(ps - ps[0], pz)  # the curve ISORoad plays (plant/road.py: MeasuredRoad)

    def road(delta: float, eps: float) -> np.ndarray:
        # clipped: a placement past the ends sees a flat road there, a poor fit the optimiser leaves
        return curve(np.clip(offset + delta + (1 + eps) * x, 0.0, end))

    names = list(PARAMETERS)
    start = DEFAULT_VEHICLE.with_(m_s=m_s, **{n: getattr(DEFAULT_VEHICLE, n) * m_s / DEFAULT_VEHICLE.m_s
                                                 for n in names})

    def vehicle_of(theta: np.ndarray) -> Vehicle:
        return start.with_(**{n: float(math.exp(v)) for n, v in zip(names, theta[:4])})

    def residuals(theta: np.ndarray) -> np.ndarray:
        y = simulate(vehicle_of(theta), road(theta[4], theta[5]), h)[scored]
        # the offsets are fitted in units of their noise std, like the residuals
        return ((meas - y) / sigma - theta[6:]).ravel()

    theta0 = np.log([getattr(start, n) for n in names])
    grid = [d for d in np.arange(-search, search + 1e-9, SEARCH_STEP) if 0 <= offset + d and offset + d + x[-1] <= end]

    def cost(delta: float) -> float:
        r = (meas - simulate(start, road(delta, 0.0), h)[scored]) / sigma
        return float(np.sum((r - r.mean(axis=0)) ** 2))

    delta0 = min(grid or [0.0], key=cost)
    bias0 = np.mean(meas - simulate(start, road(delta0, 0.0), h)[scored], axis=0) / sigma
    # the damper's range starts at 0, which has no log: 1e-4 of the start value is soft enough
    low = ([math.log(max(VEHICLE_RANGES[n][0], 1e-4 * getattr(start, n))) for n in names]
           + [-np.inf, -0.5] + [-np.inf] * 3)
    high = [math.log(VEHICLE_RANGES[n][1]) for n in names] + [np.inf, 0.5] + [np.inf] * 3  # eps within +-50 %
    # the placement first, at the start vehicle: fitted together from a placement with a drift,
    # the vehicle took up the misfit and ran off to the bounds
    place = least_squares(lambda p: residuals(np.concatenate([theta0, p])), np.concatenate([[delta0, 0.0], bias0]),
                          bounds=(low[4:], high[4:]), x_scale="jac")
    fit = least_squares(residuals, np.concatenate([theta0, place.x]), bounds=(low, high), x_scale="jac")
    r = fit.fun.reshape(-1, 3)
    s2 = 2 * fit.cost / (r.size - len(fit.x))
    norm = np.linalg.norm(fit.jac, axis=0)
    J = fit.jac / np.where(norm > 0, norm, 1.0)  # unit columns: the condition number is the parameters'
    if norm.min() > 0 and np.linalg.cond(J) < 1e10:
        sd = np.sqrt(s2 * np.diag(np.linalg.inv(J.T @ J))) / norm
    else:  # a flat road: the response does not depend on some parameters at all
        sd = np.full(len(fit.x), np.inf)

    vehicle = vehicle_of(fit.x)
    std = {n: getattr(vehicle, n) * sd[i] for i, n in enumerate(names)}  # d(ln p) = dp / p
    nuisance = {s: (float(fit.x[6 + j] * sigma[j]), float(sd[6 + j] * sigma[j])) for j, s in enumerate(SIGNALS)}
    delta, eps = fit.x[4:6]
    placement = ((float(offset + delta), float(sd[4])), (float(1 + eps), float(sd[5])))
    rms = {s: float(np.sqrt(np.mean(r[:, j] ** 2)) * sigma[j]) for j, s in enumerate(SIGNALS)}
    length, duration = float(x[-1]), float(log.time[-1] - log.time[0])
    cal = Calibration(vehicle, std, nuisance, placement, rms, noise, length, length / duration, duration, settle,
                      list(log.notes))
    if length < MIN_LENGTH:
        cal.warnings.append(f"the section is {length:.2f} m long, shorter than {MIN_LENGTH:g} m")
    loose = [f"{n} +-{100 * std[n] / getattr(vehicle, n):.1f} %" for n in names
             if not std[n] <= MAX_REL_STD * getattr(vehicle, n)]
    if loose:
        cal.warnings.append(f"the section is too short or too smooth to identify the vehicle: 1-sigma "
                            f"{', '.join(loose)} (over {100 * MAX_REL_STD:g} %)")
    poor = [f"{s} {rms[s]:.3g} against {sigma[j]:.3g}" for j, s in enumerate(SIGNALS) if rms[s] > 2 * sigma[j]]
    if poor:
        cal.warnings.append(f"the model does not fit the log to its noise (residual rms {', '.join(poor)}): a "
                            "profile placed more than --search off, a profile too coarse, a nonlinear suspension, "
                            "or noisier sensors than --noise says")
    first, last = offset + delta, offset + delta + (1 + eps) * x[-1]
    if first < -0.01 or last > end + 0.01:  # a few mm of flat road at an end change nothing
        cal.warnings.append(f"the fitted placement runs past the profile ({first:.3f}-{last:.3f} m of 0-{end:.3f} m)")
    if not fit.success:
        cal.warnings.append(f"the fit did not converge: {fit.message}")
    return cal


def summary_lines(cal: Calibration) -> list[str]:
    """The calibration in words: section, parameters with their 1-sigma, offsets, residuals."""
    v = cal.vehicle
    out = [f"calibrated on {cal.length:.1f} m at {cal.speed:.2f} m/s ({3.6 * cal.speed:.1f} km/h) mean, "
           f"{cal.duration:.1f} s, scored after {cal.settle:g} s (log {cal.sources[0]}, profile {cal.sources[1]})",
           f"sprung mass given: m_s_nominal = {v.m_s:g} kg (every value below scales with it)",
           "1-sigma from the fit's Jacobian, scaled by the residual variance:"]
    for n, unit in PARAMETERS.items():
        val, sd = getattr(v, n), cal.std[n]
        out.append(f"  {n:<4} = {val:12.6g} {unit:<6} +- {sd:.3g} ({100 * sd / val:.3f} %)")
    for s, (val, sd) in cal.nuisance.items():
        what = "offset" if s == "susp_deflection" else "bias"
        out.append(f"  {s} {what} {val:+.4g} {UNITS[s]} +- {sd:.2g}")
    (start, sd_start), (scale, sd_scale) = cal.placement
    out.append(f"  the log starts at {start:.4f} m of the profile +- {sd_start:.2g}; "
               f"true / logged distance {scale:.6f} +- {sd_scale:.2g}")
    sig = {"acc_sprung": cal.noise.acc_sprung, "acc_unsprung": cal.noise.acc_unsprung,
           "susp_deflection": cal.noise.deflection}
    out.append("residual rms: " + ", ".join(f"{s} {cal.rms[s]:.4g} {UNITS[s]} (noise std {sig[s]:g})"
                                            for s in SIGNALS))
    return out


def vehicle_toml(cal: Calibration) -> str:
    """The estimator's vehicle file: contract names and values, the summary as a comment header."""
    v = cal.vehicle
    head = ["Vehicle calibrated on a known profile (python -m suspension_estimation.harness calibrate)",
            *summary_lines(cal)]
    six = lambda x: repr(float(f"{x:.6g}"))  # noqa: E731  (a TOML float: 410.0, not the integer 410)
    body = [f"m_s_nominal = {six(v.m_s)}  # kg"] + [f"{n} = {six(getattr(v, n))}  # {u}" for n, u in PARAMETERS.items()]
    return "".join(f"# {line}\n" for line in head) + "\n".join(body) + "\n"


def run(log_path: str | Path, profile_path: str | Path, m_s: float, out: str | Path | None = None,
        offset: float = 0.0, noise: SensorNoise = SensorNoise(), settle: float = SETTLE, search: float = SEARCH,
        profile_units: str = "", names: dict[str, str] | None = None,
        units: dict[str, str] | None = None) -> Calibration:
    """Read, fit and (with ``out``) write the vehicle file: what the ``calibrate`` command does.
    ``names``, ``units``: of the log's columns, as harness/estimate.py's ``read_log`` takes them."""
    log = read_log(log_path, names, units)
    cal = calibrate(log, read_profile(profile_path, profile_units), m_s, noise, settle, offset, search)
    cal.sources = (Path(log_path).name, Path(profile_path).name + (f" from {offset:g} m" if offset else ""))
    if out is not None:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(vehicle_toml(cal))
    return cal

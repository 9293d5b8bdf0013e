"""Steady-state (frequency-domain) analysis of the road filter: a design tool, no simulation,
and the real raw road-error variance the estimator reports (``raw_error_variance``).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m suspension_estimation.estimators.steady_state              (old vs new design)
    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m suspension_estimation.estimators.steady_state --sampling   (acc_sampling 0 vs 1)

For a frozen Kalman gain K the filter is the LTI system x_k = (I - K H) Phi x_{k-1} + K y_k.
With the exact discrete plant (road held over the step, accelerations at the end of the step or
averaged over it, ``acc_sampling`` 0 / 1, as plant.QuarterCar) the road -> estimate transfer T(f)
and the sensor-noise -> estimate
transfers N_i(f) follow; with the ISO 8608 road PSD and the white sensor noises they give the
error spectrum, the raw and HP error-STD %, the in-band gain (as harness.metrics defines them:
zero-phase 0.5 Hz 4th-order Butterworth, i.e. |HP|^4 in power) and the honest raw error
variance to compare with the filter's own P[z_r, z_r].
"""
from __future__ import annotations

import numpy as np

from ..plant import iso8608
from ..plant.profile_band import band_response
from ..plant.quarter_car import HELD, LINEAR, discretise_linear_input, state_matrices
from ..plant.quarter_car import discretise as plant_discretise
from ..plant.vehicle import DEFAULT_VEHICLE, Vehicle

HP_CUTOFF, HP_ORDER = 0.5, 4  # as harness.metrics (not imported: estimators/ ships in the FMU)


def riccati(Phi, Q, H, R, P0, steps: int):
    """Run the covariance recursion ``steps`` times; return (K, P_post, P_prior)."""
    P = P0
    for _ in range(steps):
        Pp = Phi @ P @ Phi.T + Q
        S = H @ Pp @ H.T + R
        K = Pp @ H.T @ np.linalg.inv(S)
        I_KH = np.eye(len(P)) - K @ H
        P = I_KH @ Pp @ I_KH.T + K @ R @ K.T
        P = 0.5 * (P + P.T)
    return K, P, Pp


def iso_psd_time(f, gd_n0, speed, n_min=iso8608.N_MIN, n_max=iso8608.N_MAX):
    """One-sided road displacement PSD in time (m^2/Hz) of an ISO road at ``speed``."""
    n = np.asarray(f) / speed
    S = iso8608.psd(np.maximum(n, 1e-12), gd_n0) / speed
    return np.where((n >= n_min) & (n <= n_max), S, 0.0)


def plant_transfer(vehicle: Vehicle, h: float, zinv: np.ndarray, acc_sampling: int = 0,
                   road_input: str = HELD) -> np.ndarray:
    """(nf, 3) road -> [a_s, a_u, z_s - z_u] of plant.QuarterCar, z^-1 given (dimensionless
    per m of road: 1/s^2, 1/s^2, 1). ``road_input`` HELD: the road r_k is held over the step that
    ends at t_k; LINEAR: it moves from r_k-1 to r_k over that step, x_k = Ad x_k-1 +
    (Bd - G1) r_k-1 + G1 r_k (a road that is not held, sampled at the steps).
    ``acc_sampling`` 0: accelerations at the end of the step, C x_k + D r_k; 1: averaged over
    the step, (v_k - v_{k-1}) / h = (1 - z^-1) / h v_k (plant.QuarterCar.step)."""
    A4, B4 = state_matrices(vehicle)
    Ad, Bd = plant_discretise(A4, B4, h)
    zi = np.asarray(zinv)[:, None, None]
    if road_input == LINEAR:
        G1 = discretise_linear_input(A4, B4, h)
        rhs = (Bd - G1)[None, :, None] * zi + G1[None, :, None]
    else:
        rhs = np.broadcast_to(Bd[:, None], (len(zi), 4, 1))
    # x_k = (I - Ad z^-1)^-1 (input terms) r_k, all frequencies in one batched solve
    X = np.linalg.solve(np.eye(4) - Ad * zi, rhs)[..., 0]
    if acc_sampling == 1:
        d = (1 - zi[:, 0, 0]) / h
        return np.stack([d * X[:, 1], d * X[:, 3], X[:, 0] - X[:, 2]], axis=1)
    C = np.array([A4[1], A4[3], [1.0, 0.0, -1.0, 0.0]])
    D = np.array([B4[1], B4[3], 0.0])
    return X @ C.T + D


def filter_transfer(Phi, H, K, zinv, rows) -> np.ndarray:
    """(nf, len(rows), m): measurement -> chosen linear combinations (rows) of x_{k|k}."""
    n = Phi.shape[0]
    M = (np.eye(n) - K @ H) @ Phi
    zi = np.asarray(zinv)[:, None, None]
    Y = np.linalg.solve(np.eye(n) - M * zi, np.broadcast_to(K, (len(zi),) + K.shape))
    return np.asarray(rows) @ Y


def reference_highpass(f: np.ndarray, f_ref: float, zeta_ref: float) -> np.ndarray:
    """The common-mode reference's high-pass s^2 / (s^2 + 2 zeta w s + w^2), s = 2 pi i f (Hz),
    w = 2 pi f_ref: the transfer from the
    road to the filter's road estimate (road_profile.Unreference takes it off). 1 for f_ref 0."""
    s = 2j * np.pi * np.asarray(f, float)
    w = 2 * np.pi * f_ref
    return s * s / (s * s + 2 * zeta_ref * w * s + w * w) if f_ref > 0 else np.ones_like(s)


def _road_and_noise_transfers(Phi, H, K, h: float, f: np.ndarray, vehicle: Vehicle, acc_sampling: int,
                              row: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T (nf,), F (nf, channels), FG (nf, channels)): the road -> estimate transfer through the
    plant and the steady-state filter with gain K, the measurement -> estimate transfers (state
    ``row``), and each channel's part of T, F_i G_i (G: ``plant_transfer``)."""
    zinv = np.exp(-2j * np.pi * np.asarray(f, float) * h)
    G = plant_transfer(vehicle, h, zinv, acc_sampling)
    e = np.zeros((1, Phi.shape[0]))
    e[0, row] = 1.0
    F = filter_transfer(Phi, H, K, zinv, e)[:, 0, :]
    FG = F * G[:, :K.shape[1]]
    return FG.sum(1), F, FG


def road_transfer(Phi, H, K, h: float, f: np.ndarray, vehicle: Vehicle = DEFAULT_VEHICLE,
                  acc_sampling: int = 0, row: int = 4) -> np.ndarray:
    """Road -> estimate transfer T(f) (dimensionless, f in Hz) through the plant and the
    steady-state filter with gain K (state ``row``)."""
    return _road_and_noise_transfers(Phi, H, K, h, f, vehicle, acc_sampling, row)[0]


def reference_lag(Phi, H, K, h: float, f_ref: float, zeta_ref: float, vehicle: Vehicle = DEFAULT_VEHICLE,
                  acc_sampling: int = 0, row: int = 4) -> float:
    """Rate q (1/s) by which the filter's road estimate misses the reference's high-pass below
    the band: there T(f) = HP(f) (1 - q / s) to first order in q / s (the filter's common mode
    is set by the model's process noise, not by an exact double integration of the
    accelerations, which moves one of HP's two zeros from s = 0 to s = q). The estimate plus
    q int x dt then has the transfer HP (1 - q^2 / s^2), the estimator adds that integral.
    q is the mean of Re[s (HP / T - 1)] over 0.2-2 f_ref (default vehicle, ISO B model: 9.7e-4
    1/s at 40 km/h, within 3 % over that range; 3.5e-4 1/s at 72 km/h). 0 without a reference
    or when T is not finite."""
    if not f_ref > 0:
        return 0.0
    f = np.geomspace(0.2 * f_ref, 2.0 * f_ref, 5)
    T = road_transfer(Phi, H, K, h, f, vehicle, acc_sampling, row)
    s = 2j * np.pi * f
    q = float(np.mean((s * (reference_highpass(f, f_ref, zeta_ref) / T - 1)).real))
    return q if np.isfinite(q) else 0.0


def road_error_variance(Phi, H, K, h: float, gd_n0: float, speed: float, vehicle: Vehicle = DEFAULT_VEHICLE,
                        acc_sampling: int = 0, row: int = 4, nf: int = 400,
                        reference: tuple[float, float, float] | None = None) -> float:
    """Variance (m^2) of the road-height error that an ISO 8608 road leaves in the steady-state
    filter with gain K: the integral of |T(f) - 1|^2 S_r(f) over the ISO band (``analyse``'s
    road part on nf log-spaced frequencies; band N_MIN..N_MAX at ``speed`` m/s, cut at 0.999
    Nyquist). T is the road -> estimate transfer through the plant (``vehicle``, accelerations
    sampled per ``acc_sampling``) and the filter (state ``row``); the measurement channels are
    the first K.shape[1] of [a_s, a_u, z_s - z_u]. ``reference`` (f_ref Hz, zeta_ref, q 1/s):
    the error against the reference's high-pass of the road of the estimate corrected by
    q int x dt (``reference_lag``),
    |T (1 + q / s) - HP|^2, instead of |T - 1|^2 against the road itself."""
    v = max(abs(float(speed)), 0.1)
    f_lo, f_hi = iso8608.N_MIN * v, min(iso8608.N_MAX * v, 0.999 / (2 * h))
    if not f_hi > f_lo:
        return 0.0
    f = np.geomspace(f_lo, f_hi, nf)
    T = _road_and_noise_transfers(Phi, H, K, h, f, vehicle, acc_sampling, row)[0]
    if reference is None:
        err = T - 1
    else:
        f_ref, zeta_ref, q = reference
        err = T * (1 + q / (2j * np.pi * f)) - reference_highpass(f, f_ref, zeta_ref)
    return float(np.trapezoid(np.abs(err) ** 2 * iso_psd_time(f, gd_n0, v), f))


def raw_error_variance(Phi, H, K, R, h: float, gd_n0: float, speed: float, vehicle: Vehicle = DEFAULT_VEHICLE,
                       acc_sampling: int = 0, row: int = 4,
                       reference: tuple[float, float, float] | None = None) -> float:
    """Steady-state variance (m^2) of the raw road-height error of the filter with gain K on an
    ISO road (``road_error_variance``) with white sensor noise of covariance R: the sensor part
    is exact, S = A S A' + K R K' with A = (I - K H) Phi (discrete Lyapunov equation). This is
    the filter's real error when the vehicle is the model's, which its own P is not: P also
    carries the model noise (ModelNoise) and the road intensity of the class Q is set from.
    The Lyapunov equation is solved by doubling, S <- S + A^k S A^k', A^k <- A^k A^k: a sum of
    PSD terms, stable where the Kronecker solve of scipy's solve_discrete_lyapunov is
    ill-conditioned (stiff vehicles); NaN if it does not converge in 64 doublings."""
    A = (np.eye(Phi.shape[0]) - K @ H) @ Phi
    S = K @ R @ K.T
    for _ in range(64):
        add = A @ S @ A.T
        S = S + add
        if not np.isfinite(S[row, row]):
            return float("nan")
        if add[row, row] <= 1e-13 * S[row, row]:
            break
        A = A @ A
    else:
        return float("nan")
    return float(S[row, row]) + road_error_variance(Phi, H, K, h, gd_n0, speed, vehicle, acc_sampling, row,
                                                    reference=reference)


def band_error_budget(Phi, H, K, R, h: float, gd_n0: float, speed: float, cutoff: float,
                      vehicle: Vehicle = DEFAULT_VEHICLE, acc_sampling: int = 0, row: int = 4, nf: int = 600,
                      reference: tuple[float, float] | None = None) -> tuple[float, np.ndarray, np.ndarray]:
    """(var, V_g, V_tau) of the steady-state road-height error of the filter with gain K in the
    distance band of plant.profile_band (the error high-passed in distance at ``cutoff`` m, at
    ``speed`` m/s a high-pass in time at speed / cutoff Hz), on nf log-spaced frequencies from a
    twentieth of the band's corner to Nyquist; T, F_i as in ``road_error_variance``, divided by
    T_r, the reference's high-pass (``reference_highpass`` of ``reference`` = (f_ref, zeta_ref))
    that road_profile.Unreference takes off the estimate (1 without), B the band's response:

    - var (m^2): int |B|^2 (|T - 1|^2 S_r + sum_i |F_i|^2 S_n,i) df, the ISO 8608 road PSD S_r of
      ``gd_n0`` and the white sensor noises of R (one-sided PSD 2 h R_ii): the error of
      ``road_height_est`` when the vehicle is the model's and the sensors as R says;
    - V_g, V_tau (per channel): what a gain error g - 1 (m^2 per unit^2) or a delay tau (m^2/s^2)
      of that channel alone adds, to first order: its error is then (g - 1) y or -tau dy/dt, y its
      response to the road, so V = int |B|^2 |F_i G_i|^2 S_r (1 or (2 pi f)^2) df."""
    v = max(abs(float(speed)), 0.1)
    f = np.geomspace(0.05 * v / cutoff, 0.999 / (2 * h), nf)
    T, F, FG = _road_and_noise_transfers(Phi, H, K, h, f, vehicle, acc_sampling, row)
    if reference is not None:
        inv = 1.0 / reference_highpass(f, *reference)
        T, F, FG = T * inv, F * inv[:, None], FG * inv[:, None]
    B2 = np.abs(band_response(f / v, cutoff)) ** 2
    Sr = iso_psd_time(f, gd_n0, v)
    var = np.trapezoid(B2 * (np.abs(T - 1) ** 2 * Sr + (np.abs(F) ** 2 * (2 * h * np.diag(R))).sum(1)), f)
    E = (B2 * Sr)[:, None] * np.abs(FG) ** 2
    return float(var), np.trapezoid(E, f, axis=0), np.trapezoid(E * ((2 * np.pi * f) ** 2)[:, None], f, axis=0)


def band_error_variance(Phi, H, K, R, h: float, gd_n0: float, speed: float, cutoff: float,
                        vehicle: Vehicle = DEFAULT_VEHICLE, acc_sampling: int = 0, row: int = 4,
                        nf: int = 600, reference: tuple[float, float] | None = None) -> float:
    """var of ``band_error_budget`` (m^2): the band error from the road and the sensor noise."""
    return band_error_budget(Phi, H, K, R, h, gd_n0, speed, cutoff, vehicle, acc_sampling, row, nf, reference)[0]


def analyse(Phi, H, K, R_true, h, gd_n0, speed, vehicle=DEFAULT_VEHICLE, road_row=None,
            f=None, n_min=iso8608.N_MIN, acc_sampling=0, road_input=HELD):
    """Spectral scores of the steady-state filter (K) on an ISO road: dict + spectra.

    ``acc_sampling`` says how the PLANT samples its accelerations (0 end of step, 1 averaged),
    ``road_input`` how its road moves over a step (``plant_transfer``); the filter (Phi, H, K)
    may assume either. The plant adds white noise of R_true to the
    sampled or averaged value alike (plant.QuarterCar). Keys: raw_pct, hp_pct, gain_hp,
    err_var_raw (m^2), hp_signal_pct / hp_noise_pct (the HP error from the road, |T - 1|, and
    from the sensor noise alone), and the spectra."""
    if f is None:
        f = np.concatenate([np.geomspace(1e-3, 0.999 / (2 * h), 6000)])
    zinv = np.exp(-2j * np.pi * f * h)
    if road_row is None:
        road_row = np.zeros(Phi.shape[0])
        road_row[4] = 1.0
    G = plant_transfer(vehicle, h, zinv, acc_sampling, road_input)
    F = filter_transfer(Phi, H, K, zinv, np.atleast_2d(road_row))[:, 0, :]
    T = np.einsum("fi,fi->f", F, G)
    Sr = iso_psd_time(f, gd_n0, speed, n_min=n_min)
    Sn = 2 * h * np.diag(R_true)  # one-sided white noise PSD per channel
    Snoise = (np.abs(F) ** 2 * Sn).sum(1)
    Se = np.abs(T - 1) ** 2 * Sr + Snoise
    Sest = np.abs(T) ** 2 * Sr + Snoise
    from scipy.signal import butter, sosfreqz

    sos = butter(HP_ORDER, HP_CUTOFF, btype="highpass", fs=1 / h, output="sos")
    _, hp = sosfreqz(sos, worN=f, fs=1 / h)
    w = np.abs(hp) ** 4  # filtfilt: |HP|^2 in amplitude
    integ = lambda s: np.trapezoid(s, f)  # noqa: E731
    return {
        "raw_pct": 100 * np.sqrt(integ(Se) / integ(Sr)),
        "hp_pct": 100 * np.sqrt(integ(w * Se) / integ(w * Sr)),
        "hp_signal_pct": 100 * np.sqrt(integ(w * np.abs(T - 1) ** 2 * Sr) / integ(w * Sr)),
        "hp_noise_pct": 100 * np.sqrt(integ(w * Snoise) / integ(w * Sr)),
        "gain_hp": np.sqrt(integ(w * Sest) / integ(w * Sr)),
        "err_var_raw": integ(Se),
        "f": f, "T": T, "Se": Se, "Sr": Sr, "w": w, "Snoise": Snoise,
    }


def _report_current():
    from .model import DiscreteModel, RoadModel, measurement_covariance

    h, V = 1e-3, 40 / 3.6
    Rm = measurement_covariance(0.02, 0.2, 1e-4)
    gdC = iso8608.class_psd_n0(3)
    for label, road, cls_q, secs in [("old n_lo=1e-4, Q of F, 60 s", RoadModel(f_ref=0.0), 6, 60),
                                     ("old n_lo=1e-4, Q of F, 400 s", RoadModel(f_ref=0.0), 6, 400),
                                     ("old n_lo=0.011, Q of C, 60 s", RoadModel(n_lo=0.011, f_ref=0.0), 3, 60),
                                     ("new (f_ref 0.01 Hz), Q of F, 120 s", RoadModel(), 6, 120)]:
        m = DiscreteModel.build(DEFAULT_VEHICLE, V, iso8608.class_psd_n0(cls_q), h, road)
        P0 = np.diag([1e-4, 1e-4, 1e-4, 1e-4, 1e-2, 1e-1]) ** 2
        K, P, _ = riccati(m.Phi, m.Q, m.H, Rm, P0, int(secs / h))
        a = analyse(m.Phi, m.H, K, Rm, h, gdC, V)
        f, T = a["f"], a["T"]
        sel = [np.argmin(abs(f - x)) for x in (0.05, 0.15, 0.3, 0.5, 1.0, 3.0)]
        print(f"{label}: raw {a['raw_pct']:.1f} %  HP {a['hp_pct']:.2f} %  gain {a['gain_hp']:.3f}  "
              f"sqrt(P_zr) {np.sqrt(P[4, 4]) * 1e3:.2f} mm vs true raw err {np.sqrt(a['err_var_raw']) * 1e3:.2f} mm")
        print("   |T| at 0.05/0.15/0.3/0.5/1/3 Hz:", " ".join(f"{abs(T[i]):.3f}" for i in sel))




def steady_gain(m, R, P0=None):
    """Steady-state Kalman gain and posterior covariance of a DiscreteModel (DARE)."""
    from scipy.linalg import solve_discrete_are

    P = solve_discrete_are(m.Phi.T, m.H.T, m.Q, R)
    K = P @ m.H.T @ np.linalg.inv(m.H @ P @ m.H.T + R)
    Ppost = (np.eye(len(P)) - K @ m.H) @ P
    return K, 0.5 * (Ppost + Ppost.T)


def sweep(road=None, q_class=None, classes=(1, 2, 3, 4, 5), speeds=(10.0, 40 / 3.6, 20.0, 30.0),
          h=1e-3, vehicle=DEFAULT_VEHICLE, acc_sampling=0, road_hold=None):
    """Steady-state scores of one configuration over ISO classes and speeds (no simulation).

    q_class None: the model intensity of the true class (online class); else that fixed class.
    ``acc_sampling`` of plant and filter alike; ``road_hold`` None = the estimator's default
    (held road in the model only with acc_sampling 1).
    Prints HP %, in-band gain, raw %, and the honesty ratio sqrt(P_zr) / true raw error."""
    from .model import DiscreteModel, RoadModel, measurement_covariance

    road = road or RoadModel()
    Rm = measurement_covariance(0.02, 0.2, 1e-4)
    rows = []
    for cls in classes:
        for V in speeds:
            hold = acc_sampling == 1 if road_hold is None else bool(road_hold)
            m = DiscreteModel.build(vehicle, V, iso8608.class_psd_n0(q_class or cls), h, road,
                                    acc_sampling=acc_sampling, road_hold=hold)
            K, P = steady_gain(m, Rm)
            a = analyse(m.Phi, m.H, K, Rm, h, iso8608.class_psd_n0(cls), V,
                        f=np.geomspace(1e-3, 0.45 / h, 2500), acc_sampling=acc_sampling)
            rows.append((cls, V, a["hp_pct"], a["gain_hp"], a["raw_pct"],
                         np.sqrt(P[4, 4] / a["err_var_raw"])))
            print(f"ISO {'ABCDE'[cls - 1]} {V:5.1f} m/s: HP {a['hp_pct']:5.2f} %  gain {a['gain_hp']:.3f}  "
                  f"raw {a['raw_pct']:5.1f} %  sqrt(P_zr)/err {rows[-1][-1]:.2f}")
    return rows


def compare_sampling(classes=(2, 3, 4), steps=(1e-2, 1e-3), speed=40 / 3.6, vehicle=DEFAULT_VEHICLE,
                     q_class=6):
    """Steady-state HP / raw error of point-sampled (acc_sampling 0, continuous road model) and
    step-averaged (acc_sampling 1, held road) accelerations, each with its matching model and
    the same sensor noise per sample (0.02 / 0.2 m/s^2, 0.1 mm). Returns rows
    (class, h, acc_sampling, hp %, hp signal %, hp noise %, raw %, gain, sqrt(P_zr) m, err m)."""
    from .model import DiscreteModel, RoadModel, measurement_covariance

    Rm = measurement_covariance(0.02, 0.2, 1e-4)
    rows = []
    for cls in classes:
        for h in steps:
            for acc in (0, 1):
                m = DiscreteModel.build(vehicle, speed, iso8608.class_psd_n0(max(cls, q_class)), h,
                                        RoadModel(), acc_sampling=acc, road_hold=acc == 1)
                K, P = steady_gain(m, Rm)
                a = analyse(m.Phi, m.H, K, Rm, h, iso8608.class_psd_n0(cls), speed,
                            f=np.geomspace(1e-3, 0.499 / h, 4000), acc_sampling=acc)
                rows.append((cls, h, acc, a["hp_pct"], a["hp_signal_pct"], a["hp_noise_pct"],
                             a["raw_pct"], a["gain_hp"], float(np.sqrt(P[4, 4])),
                             float(np.sqrt(a["err_var_raw"]))))
    return rows


if __name__ == "__main__":
    import sys

    if "--sampling" in sys.argv:
        for c, h, acc, hp, hs, hn, raw, g, sp, err in compare_sampling():
            print(f"ISO {'ABCDEFGH'[c - 1]} {1e3 * h:g} ms acc_sampling {acc}: HP {hp:.2f} % "
                  f"(road {hs:.2f}, noise {hn:.2f})  raw {raw:.1f} %  gain {g:.3f}  "
                  f"sqrt(P_zr) {1e3 * sp:.2f} mm vs err {1e3 * err:.2f} mm")
    else:
        _report_current()

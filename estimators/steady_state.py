"""Steady-state (frequency-domain) analysis of the road filter: a design tool, no simulation.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python -m estimators.steady_state   (old vs new design)

For a frozen Kalman gain K the filter is the LTI system x_k = (I - K H) Phi x_{k-1} + K y_k.
With the exact discrete plant (road held over the step, outputs at the end of the step, as
plant.QuarterCar) the road -> estimate transfer T(f) and the sensor-noise -> estimate
transfers N_i(f) follow; with the ISO 8608 road PSD and the white sensor noises they give the
error spectrum, the raw and HP error-STD %, the in-band gain (as harness.metrics defines them:
zero-phase 0.5 Hz 4th-order Butterworth, i.e. |HP|^4 in power) and the honest raw error
variance to compare with the filter's own P[z_r, z_r].
"""
from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfreqz

from plant import iso8608
from plant.quarter_car import discretise as plant_discretise
from plant.quarter_car import state_matrices
from plant.vehicle import DEFAULT_VEHICLE, Vehicle

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


def plant_transfer(vehicle: Vehicle, h: float, zinv: np.ndarray) -> np.ndarray:
    """(nf, 3) road -> [a_s, a_u, z_s - z_u] of plant.QuarterCar (acc_sampling 0), z^-1 given."""
    A4, B4 = state_matrices(vehicle)
    Ad, Bd = plant_discretise(A4, B4, h)
    C = np.array([A4[1], A4[3], [1.0, 0.0, -1.0, 0.0]])
    D = np.array([B4[1], B4[3], 0.0])
    out = np.empty((len(zinv), 3), complex)
    I4 = np.eye(4)
    for i, zi in enumerate(zinv):
        # y_k = C x_{k+1} + D r_k,  x_{k+1} = (I - Ad z^-1)^-1 Bd r_k
        out[i] = C @ np.linalg.solve(I4 - Ad * zi, Bd) + D
    return out


def filter_transfer(Phi, H, K, zinv, rows) -> np.ndarray:
    """(nf, len(rows), 3): measurement -> chosen linear combinations (rows) of x_{k|k}."""
    n = Phi.shape[0]
    M = (np.eye(n) - K @ H) @ Phi
    out = np.empty((len(zinv), len(rows), K.shape[1]), complex)
    for i, zi in enumerate(zinv):
        out[i] = rows @ np.linalg.solve(np.eye(n) - M * zi, K)
    return out


def analyse(Phi, H, K, R_true, h, gd_n0, speed, vehicle=DEFAULT_VEHICLE, road_row=None,
            f=None, n_min=iso8608.N_MIN):
    """Spectral scores of the steady-state filter (K) on an ISO road: dict + spectra."""
    if f is None:
        f = np.concatenate([np.geomspace(1e-3, 0.999 / (2 * h), 6000)])
    zinv = np.exp(-2j * np.pi * f * h)
    if road_row is None:
        road_row = np.zeros(Phi.shape[0])
        road_row[4] = 1.0
    G = plant_transfer(vehicle, h, zinv)
    F = filter_transfer(Phi, H, K, zinv, np.atleast_2d(road_row))[:, 0, :]
    T = np.einsum("fi,fi->f", F, G)
    Sr = iso_psd_time(f, gd_n0, speed, n_min=n_min)
    Sn = 2 * h * np.diag(R_true)  # one-sided white noise PSD per channel
    Snoise = (np.abs(F) ** 2 * Sn).sum(1)
    Se = np.abs(T - 1) ** 2 * Sr + Snoise
    Sest = np.abs(T) ** 2 * Sr + Snoise
    sos = butter(HP_ORDER, HP_CUTOFF, btype="highpass", fs=1 / h, output="sos")
    _, hp = sosfreqz(sos, worN=f, fs=1 / h)
    w = np.abs(hp) ** 4  # filtfilt: |HP|^2 in amplitude
    integ = lambda s: np.trapezoid(s, f)  # noqa: E731
    return {
        "raw_pct": 100 * np.sqrt(integ(Se) / integ(Sr)),
        "hp_pct": 100 * np.sqrt(integ(w * Se) / integ(w * Sr)),
        "gain_hp": np.sqrt(integ(w * Sest) / integ(w * Sr)),
        "err_var_raw": integ(Se),
        "f": f, "T": T, "Se": Se, "Sr": Sr, "w": w, "Snoise": Snoise,
    }


def _report_current():
    from estimators.model import DiscreteModel, RoadModel, measurement_covariance

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
          h=1e-3, vehicle=DEFAULT_VEHICLE):
    """Steady-state scores of one configuration over ISO classes and speeds (no simulation).

    q_class None: the model intensity of the true class (online class); else that fixed class.
    Prints HP %, in-band gain, raw %, and the honesty ratio sqrt(P_zr) / true raw error."""
    from estimators.model import DiscreteModel, RoadModel, measurement_covariance

    road = road or RoadModel()
    Rm = measurement_covariance(0.02, 0.2, 1e-4)
    rows = []
    for cls in classes:
        for V in speeds:
            m = DiscreteModel.build(vehicle, V, iso8608.class_psd_n0(q_class or cls), h, road)
            K, P = steady_gain(m, Rm)
            a = analyse(m.Phi, m.H, K, Rm, h, iso8608.class_psd_n0(cls), V,
                        f=np.geomspace(1e-3, 0.45 / h, 2500))
            rows.append((cls, V, a["hp_pct"], a["gain_hp"], a["raw_pct"],
                         np.sqrt(P[4, 4] / a["err_var_raw"])))
            print(f"ISO {'ABCDE'[cls - 1]} {V:5.1f} m/s: HP {a['hp_pct']:5.2f} %  gain {a['gain_hp']:.3f}  "
                  f"raw {a['raw_pct']:5.1f} %  sqrt(P_zr)/err {rows[-1][-1]:.2f}")
    return rows


if __name__ == "__main__":
    _report_current()

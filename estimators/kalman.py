"""Linear Kalman filter (filterpy-identical, with a stationary steady-state mode) and MME&KF.

``LinearKF`` performs exactly filterpy.kalman.KalmanFilter's predict/update (Joseph-form
covariance update, symmetrised) in plain numpy; a test proves both identical to 1e-9.

Stationary start. With fixed F, Q, H, R the covariance recursion does not depend on the data
and converges to the solution of the discrete algebraic Riccati equation (DARE). ``stationary()``
sets P to that fixed point (the filter's stationary posterior covariance, solved by doubling):
a filter started there stays there, so its gain is constant. When
``freeze_tol`` > 0 the gain is then FROZEN: a step is x <- F x; x <- x + K (z - H x), with no
covariance arithmetic, identical to the full recursion started at the same P within its
rounding (tested to 1e-9) and several times cheaper. A skipped or partial update
(``predict_only``, ``update_rows``) leaves the fixed point; the full recursion then runs until
the posterior covariance is back within ``freeze_tol`` (relative, max-norm) of the fixed point,
where the gain freezes again. The full recursion itself wanders from the fixed point by its
rounding (~3e-12 of max|P| over 20 s here), so a tolerance much below 1e-9 never refreezes.
Without a fixed point (an unstable or undetectable model) the
filter freezes when P_post moves less than ``freeze_tol`` over ``freeze_steps`` steps.

``MMEKF`` is the MME&KF of Wang, Dong, Qin, Gu, *Road profile estimation for suspension system
based on the minimum model error criterion combined with a Kalman filter* (J. Vibroengineering
2017), eqs. 16-21; see its docstring for the choices of G, W and the linearisation.
"""
from __future__ import annotations

import numpy as np


def stationary_covariance(F: np.ndarray, Q: np.ndarray, H: np.ndarray, R: np.ndarray,
                          max_doublings: int = 64) -> tuple[np.ndarray, np.ndarray] | None:
    """(P_prior, P_post) at the fixed point of the covariance recursion (paper 000 eqs. 11-14):
    P_prior = F P_post F' + Q, P_post = (I - K H) P_prior (I - K H)' + K R K',
    K = P_prior H' (H P_prior H' + R)^-1. None if the recursion has no finite fixed point.

    Solved by the structure-preserving doubling algorithm (Chu, Fan, Lin, Wang 2004) for
    P = F P (I + G P)^-1 F' + Q, G = H' R^-1 H: iterate k is the prior covariance after 2^k
    recursion steps from P = Q, so ~20 doublings reach the fixed point of a slow (0.01 Hz) mode
    at a 1 ms step. It is as accurate here as scipy.linalg.solve_discrete_are and 10-20x
    faster (1 ms against 13-23 ms for 8 states), which matters because the model is rebuilt
    (and its fixed point solved) at every mass update of the joint estimator."""
    n = len(F)
    I = np.eye(n)
    A = F.T.copy()
    G = H.T @ np.linalg.solve(R, H)
    X = Q.copy()
    with np.errstate(all="ignore"):
        for _ in range(max_doublings):
            try:
                W = np.linalg.inv(I + G @ X)
            except np.linalg.LinAlgError:
                return None
            AW = A @ W
            X_new = X + A.T @ X @ W @ A
            G = G + AW @ G @ A.T
            A = AW @ A
            if not np.all(np.isfinite(X_new)):
                return None
            done = np.max(np.abs(X_new - X)) <= 1e-15 * np.max(np.abs(X_new))
            X = X_new
            if done:
                break
        else:
            return None
    # Validation: the doubling can stop at garbage that looks converged when I + G X is
    # ill-conditioned (a measurement coefficient ~1e7 in H against its noise: G ~ 1e20,
    # cond(I + G X) ~ 1e19): an iterate asymmetric by 1e-3 of its size, a fixed point that one
    # recursion step moves by 1e-2 to 0.3 of its size. Such a result is refused (None), like a
    # missing fixed point. A valid one is symmetric to rounding and reproduced by one recursion
    # step to rounding (~1e-13 of max|P_prior| for the default vehicle, 4e-11 for a wheel damped
    # at c_s/m_u = 2.5e5 1/s, up to ~1e-5 on stiff vehicles whose filter still works); the
    # tolerance of both checks is 1e-4 (relative, max-norm).
    scale = np.max(np.abs(X))
    if not np.isfinite(scale) or np.max(np.abs(X - X.T)) > 1e-4 * scale:
        return None
    Pp = 0.5 * (X + X.T)
    K = Pp @ H.T @ np.linalg.inv(H @ Pp @ H.T + R)
    I_KH = I - K @ H
    P = I_KH @ Pp @ I_KH.T + K @ R @ K.T
    P = 0.5 * (P + P.T)
    if np.min(np.linalg.eigvalsh(P)) < -1e-12 * np.max(np.abs(P)):
        return None
    if np.max(np.abs(F @ P @ F.T + Q - Pp)) > 1e-4 * np.max(np.abs(Pp)):
        return None
    return np.ascontiguousarray(Pp), np.ascontiguousarray(P)


class LinearKF:
    """x_k = F x_{k-1} + w (cov Q),  z_k = H x_k + v (cov R); paper 000 eqs. 10-14.

    Attributes follow filterpy: x (n,), P, F, Q, H, R, y (innovation), S, SI, K; plus ``nis``
    (normalised innovation squared y' S^-1 y of the last update, dimensionless).
    """

    def __init__(self, dim_x: int, dim_z: int, freeze_tol: float = 0.0, freeze_steps: int = 50,
                 fast: bool = True):
        self.dim_x, self.dim_z = dim_x, dim_z
        self.x = np.zeros(dim_x)
        self.P = np.eye(dim_x)
        self.F = np.eye(dim_x)
        self.Q = np.eye(dim_x)
        self.H = np.zeros((dim_z, dim_x))
        self.R = np.eye(dim_z)
        self.y = np.zeros(dim_z)
        self.S = np.eye(dim_z)
        self.SI = np.eye(dim_z)
        self.K = np.zeros((dim_x, dim_z))
        self.nis = 0.0
        self._I = np.eye(dim_x)
        self.freeze_tol = float(freeze_tol)  # back at the fixed point within it (0: never)
        self.freeze_steps = int(freeze_steps)
        self.fast = bool(fast)  # use the frozen gain at the fixed point (False: the full recursion)
        self.stationary_now = False  # P is at the fixed point (frozen or not)
        self.frozen = False
        self._calm = 0
        self._P_last: np.ndarray | None = None  # the last P_post (no fixed point known)
        self._P_prior_ss: np.ndarray | None = None
        self._P_post_ss: np.ndarray | None = None
        self.P_post: np.ndarray | None = None
        self._ss: tuple[np.ndarray, np.ndarray] | None = None  # (P_prior, P_post) fixed point
        self._ss_gain: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # K, S, SI there
        self._M: np.ndarray | None = None  # the frozen step as one matrix (see _freeze)
        self._buf = np.zeros(dim_x + dim_z)

    def set_model(self, F: np.ndarray, Q: np.ndarray, H: np.ndarray | None = None,
                  R: np.ndarray | None = None) -> None:
        """Replace the model matrices (the covariance and state are kept); unfreezes and
        forgets the fixed point of the previous model."""
        self.F, self.Q = F, Q
        if H is not None:
            self.H = H
        if R is not None:
            self.R = R
        self._ss = self._ss_gain = self._M = None
        self.unfreeze()

    def stationary(self) -> bool:
        """Set P to the stationary posterior covariance of the current model (see the module
        doc) and, with ``fast``, freeze the gain. False (P unchanged) without a fixed point."""
        if self._ss is None:
            ss = stationary_covariance(self.F, self.Q, self.H, self.R)
            if ss is None:
                return False
            Pp = ss[0]
            S = self.H @ Pp @ self.H.T + self.R
            SI = np.linalg.inv(S)
            self._ss, self._ss_gain = ss, (np.ascontiguousarray(Pp @ self.H.T @ SI), S, SI)
        self.P = self.P_post = self._ss[1]
        self._freeze()
        return True

    def share_fixed_point(self, other: "LinearKF") -> None:
        """Take ``other``'s fixed point (same model: F, Q, H, R) instead of solving for it again."""
        self._ss, self._ss_gain = other._ss, other._ss_gain

    @property
    def stationary_innovation_variance(self) -> np.ndarray | None:
        """diag(S) at the model's fixed point once ``stationary()`` has found it, else None."""
        return None if self._ss_gain is None else np.diag(self._ss_gain[1])

    @property
    def stationary_solution(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(K, P_post) at the model's fixed point once ``stationary()`` has found it, else None."""
        return None if self._ss is None else (self._ss_gain[0], self._ss[1])

    def _freeze(self) -> None:
        self.stationary_now = True
        if self.fast:
            self.frozen = True
            self._P_prior_ss, self._P_post_ss = self._ss
            self.K, self.S, self.SI = self._ss_gain
            if self._M is None:
                # one matrix for the whole frozen step: [x_k; w_k; y_k] = M [x_{k-1}; z_k] with
                # x_k = (I - K H) F x_{k-1} + K z_k, the innovation y_k = z_k - H F x_{k-1} and
                # its whitened form w_k = L^-1 y_k, S = L L', so that nis = |w_k|^2
                n, m = self.dim_x, self.dim_z
                Li = np.linalg.inv(np.linalg.cholesky(self.S))
                HF = self.H @ self.F
                M = np.zeros((n + 2 * m, n + m))
                M[:n, :n] = (self._I - self.K @ self.H) @ self.F
                M[:n, n:] = self.K
                M[n:n + m, :n] = -Li @ HF
                M[n:n + m, n:] = Li
                M[n + m:, :n] = -HF
                M[n + m:, n:] = np.eye(m)
                self._M, self._buf = M, np.zeros(n + m)

    def unfreeze(self) -> None:
        """The covariance leaves the fixed point: the full recursion from here on."""
        self.frozen = self.stationary_now = False
        self._calm = 0

    def start_at(self, x: np.ndarray, P: np.ndarray | None = None) -> None:
        """Start over from state ``x`` and, if given, covariance ``P`` (the current one else):
        the full recursion from here (``stationary()`` goes to the fixed point instead)."""
        self.x = x
        if P is not None:
            self.P = P
        self.P_post = None
        self.unfreeze()

    def state_sum(self) -> float:
        """The sum of x and, unless the gain is frozen (P then the fixed point), of P: not finite
        when either holds a value that is not (a diverged filter)."""
        return sum(self.x.tolist()) + (0.0 if self.frozen else float(self.P.sum()))

    def restore(self, x: np.ndarray, P: np.ndarray, stationary: bool) -> None:
        """Put back a state saved as (x, P, stationary_now) before an undone update."""
        self.x, self.P = x, P
        if stationary:
            self._freeze()
        else:
            self.unfreeze()

    def predict(self) -> None:
        """x = F x,  P = F P F' + Q (paper 000 eq. 11)."""
        self.x = self.F @ self.x
        if self.frozen:
            self.P = self._P_prior_ss
        else:
            self.P = self.F @ self.P @ self.F.T + self.Q

    def predict_only(self) -> None:
        """A step without a measurement: the covariance grows, so the steady state is left."""
        if self.frozen:
            self.unfreeze()
            self.P = self._P_post_ss
        self.predict()

    def innovation(self, z: np.ndarray) -> np.ndarray:
        return z - self.H @ self.x

    def step(self, z: np.ndarray) -> None:
        """``predict()`` then ``update(z)``; the frozen case without the method calls."""
        if self.frozen:
            n, buf = self.dim_x, self._buf
            buf[:n] = self.x
            buf[n:] = z
            v = self._M @ buf
            self.x = v[:n]
            w = v[n:n + self.dim_z]
            self.y = v[n + self.dim_z:]
            self.nis = float(w @ w)
            self.P = self._P_post_ss
            return
        self.predict()
        self.update(z)

    def update(self, z: np.ndarray, y: np.ndarray | None = None) -> None:
        """Kalman gain, state and Joseph-form covariance update (paper 000 eqs. 12-14).

        ``y`` may pass a precomputed innovation z - H x (MME&KF adds its direct term to it).
        """
        y = self.innovation(z) if y is None else y
        self.y = y
        if self.frozen:
            self.x = self.x + self.K @ y
            self.nis = float(y @ self.SI @ y)
            self.P = self._P_post_ss
            return
        P = self.P
        PHT = P @ self.H.T
        self.S = self.H @ PHT + self.R
        self.SI = np.linalg.inv(self.S)
        self.K = PHT @ self.SI
        self.x = self.x + self.K @ y
        I_KH = self._I - self.K @ self.H
        P_new = I_KH @ P @ I_KH.T + self.K @ self.R @ self.K.T
        # the Joseph form is symmetric in exact arithmetic only: on an ill-conditioned P
        # (eigenvalues over 1e12) its rounding asymmetry builds up step by step
        P_new = 0.5 * (P_new + P_new.T)
        self.nis = float(y @ self.SI @ y)
        self.P_post = self.P = P_new
        if self.freeze_tol > 0 and not self.stationary_now:
            self._maybe_freeze(P, P_new)

    def _maybe_freeze(self, P_prior: np.ndarray, P_new: np.ndarray) -> None:
        if self._ss is not None:
            ref = self._ss[1]
            if np.max(np.abs(P_new - ref)) <= self.freeze_tol * np.max(np.abs(ref)):
                self.P = self.P_post = ref
                self._freeze()
            return
        old = self._P_last
        self._P_last = P_new
        if old is not None and np.max(np.abs(P_new - old)) <= self.freeze_tol * np.max(np.abs(P_new)):
            self._calm += 1
            if self._calm >= self.freeze_steps:
                self._ss = (P_prior, P_new)
                S = self.H @ P_prior @ self.H.T + self.R
                SI = np.linalg.inv(S)
                self._ss_gain = (P_prior @ self.H.T @ SI, S, SI)
                self._freeze()
        else:
            self._calm = 0

    def update_rows(self, z: np.ndarray, rows: np.ndarray, y: np.ndarray | None = None) -> None:
        """Update with the measurement rows ``rows`` only (the others rejected or missing):
        H, R and z restricted to them, Joseph form; unfreezes (the covariance leaves its steady
        state). ``nis`` is that of the rows used."""
        self.unfreeze()
        H, R = self.H[rows], self.R[np.ix_(rows, rows)]
        y = (z[rows] - H @ self.x) if y is None else y[rows]
        P = self.P
        PHT = P @ H.T
        S = H @ PHT + R
        SI = np.linalg.inv(S)
        K = PHT @ SI
        self.x = self.x + K @ y
        I_KH = self._I - K @ H
        P_new = I_KH @ P @ I_KH.T + K @ R @ K.T
        self.P = self.P_post = 0.5 * (P_new + P_new.T)
        self.nis = float(y @ SI @ y)


class MMEKF(LinearKF):
    """MME&KF: the model error d_k is solved from the minimum-model-error criterion and injected
    into the prediction (paper 000 eqs. 16-21).

    Choices (the paper leaves them partly open):

    * G (6 x 1) = e_{v_s}: a sprung-mass error changes only the body equation,
      m_true a_s = F_susp, so the model error is one additive body acceleration d (m/s^2),
      v_s' = A[1] x + d. The paper's G (a copy of A with m_b scaled by the sector bound f_1i)
      and its d (six equal entries f_1i/m_b dm_b) reduce to the same single direction.
    * Linearisation (eqs. 17-19): with h linear, S_k + y^p_k = H (I + T A) x_{k-1|k-1}; we use
      the exact H Phi x_{k-1|k-1}. The effect of d on the predicted output is
      D = H Gamma + E, where Gamma = int_0^T expm(A s) ds G is the exact held-input version of
      the paper's T G, and E = e_{a_s} is the DIRECT feed-through: the measured body
      acceleration is v_s' itself and contains d. Without E, D = T c/m_s ~ 5e-3 and d is
      essentially unobservable in one step.
    * d_k = -(D' R^-1 D + W)^-1 D' R^-1 (H Phi x - y_k)  (eq. 19), W (1x1, (m/s^2)^-2) settable;
      eq. 20's innovation-covariance rule is used for its default: W = 1 / sigma_d^2 with
      sigma_d the body-acceleration model error expected from the mass range.
    * Prediction x_{k|k-1} = Phi x + Gamma d_k (eq. 21, first line), P_{k|k-1} = Phi P Phi' + Q;
      the predicted output includes the direct term, y_{k|k-1} = H x_{k|k-1} + E d_k, so the
      update does not count d twice.
    """

    def __init__(self, dim_x: int, dim_z: int, W: float = 10.0, direct: bool = True, **kw):
        super().__init__(dim_x, dim_z, **kw)
        self.W = np.atleast_2d(float(W)) if np.ndim(W) == 0 else np.asarray(W, float)
        self.G = np.zeros((dim_x, 1))
        self._M_mme: np.ndarray | None = None  # the frozen step's matrix (_freeze)
        self.G[1, 0] = 1.0
        # direct feed-through of d into the measured body acceleration: present for a point
        # sample at the end of the step; for an acceleration averaged over the step
        # ((v_k - v_{k-1}) / h) the effect of d is already in H Gamma, so E = 0
        self.E = np.zeros((dim_z, 1))
        if direct:
            self.E[0, 0] = 1.0
        self.Gamma = self.G.copy()
        self.d = np.zeros(1)
        self._L = None

    def set_model(self, F, Q, H=None, R=None, Gamma: np.ndarray | None = None) -> None:
        super().set_model(F, Q, H, R)
        if Gamma is not None:
            self.Gamma = Gamma
        self._L = None

    def _gain(self) -> np.ndarray:
        if self._L is None:  # (D' R^-1 D + W)^-1 D' R^-1, constant for a model
            D = self.H @ self.Gamma + self.E
            RI = np.linalg.inv(self.R)
            self._L = np.linalg.solve(D.T @ RI @ D + self.W, D.T @ RI)
        return self._L

    def _freeze(self) -> None:
        super()._freeze()
        if self.frozen:
            # the frozen MME&KF step is linear in (x_{k-1}, z_k) too:
            # x_p = (F - Gamma L H F) x + Gamma L z,  y = z - H x_p - E d,  x_k = x_p + K y,
            # with d = L (z - H F x); rows: x_k, the whitened innovation L_S^-1 y, and d
            n, m = self.dim_x, self.dim_z
            L, G, E, K = self._gain(), self.Gamma, self.E, self.K
            HF = self.H @ self.F
            Ax, Az = self.F - G @ L @ HF, G @ L
            Cx, Cz = -self.H @ Ax + E @ L @ HF, np.eye(m) - self.H @ Az - E @ L
            Li = np.linalg.inv(np.linalg.cholesky(self.S))
            M = np.zeros((n + m + 1, n + m))
            M[:n, :n], M[:n, n:] = Ax + K @ Cx, Az + K @ Cz
            M[n:n + m, :n], M[n:n + m, n:] = Li @ Cx, Li @ Cz
            M[n + m, :n], M[n + m, n:] = -(L @ HF)[0], L[0]
            self._M_mme = M

    def step(self, z: np.ndarray) -> None:
        """One MME&KF step with measurement z at k (eq. 19 for d_k, then eq. 21)."""
        if self.frozen:
            n, m, buf = self.dim_x, self.dim_z, self._buf
            buf[:n] = self.x
            buf[n:] = z
            v = self._M_mme @ buf
            self.x = v[:n]
            w = v[n:n + m]
            self.nis = float(w @ w)
            self.d = v[n + m:]
            self.P = self._P_post_ss
            return
        x0 = self.F @ self.x
        self.d = self._gain() @ (z - self.H @ x0)
        self.predict()
        self.x = self.x + self.Gamma @ self.d
        y = z - self.H @ self.x - self.E @ self.d
        self.update(z, y)

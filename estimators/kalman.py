"""Linear Kalman filter (filterpy-identical, with a frozen steady-state mode) and MME&KF.

``LinearKF`` performs exactly filterpy.kalman.KalmanFilter's predict/update (Joseph-form
covariance update) in plain numpy; a test proves both identical to 1e-9. Once the Riccati
recursion has converged (the posterior covariance moves less than ``freeze_tol`` relative over
``freeze_steps`` consecutive steps with an unchanged model), it freezes the gain: the state
then runs x <- Phi x; x <- x + K (z - H x), which is identical to the full recursion within
the convergence tolerance and about 3x cheaper. Any model change or skipped update unfreezes.

``MMEKF`` is the MME&KF of Wang, Dong, Qin, Gu, *Road profile estimation for suspension system
based on the minimum model error criterion combined with a Kalman filter* (J. Vibroengineering
2017), eqs. 16-21; see its docstring for the choices of G, W and the linearisation.
"""
from __future__ import annotations

import numpy as np


class LinearKF:
    """x_k = F x_{k-1} + w (cov Q),  z_k = H x_k + v (cov R); paper 000 eqs. 10-14.

    Attributes follow filterpy: x (n,), P, F, Q, H, R, y (innovation), S, SI, K; plus ``nis``
    (normalised innovation squared y' S^-1 y of the last update, dimensionless).
    """

    def __init__(self, dim_x: int, dim_z: int, freeze_tol: float = 0.0, freeze_steps: int = 50):
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
        self.freeze_tol = float(freeze_tol)  # 0 disables the steady-state mode
        self.freeze_steps = int(freeze_steps)
        self.frozen = False
        self._calm = 0
        self._P_prior_ss: np.ndarray | None = None
        self.P_post: np.ndarray | None = None

    def set_model(self, F: np.ndarray, Q: np.ndarray, H: np.ndarray | None = None,
                  R: np.ndarray | None = None) -> None:
        """Replace the model matrices (the covariance and state are kept); unfreezes."""
        self.F, self.Q = F, Q
        if H is not None:
            self.H = H
        if R is not None:
            self.R = R
        self.unfreeze()

    def unfreeze(self) -> None:
        self.frozen = False
        self._calm = 0

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
        self.predict()

    def innovation(self, z: np.ndarray) -> np.ndarray:
        return z - self.H @ self.x

    def update(self, z: np.ndarray, y: np.ndarray | None = None) -> None:
        """Kalman gain, state and Joseph-form covariance update (paper 000 eqs. 12-14).

        ``y`` may pass a precomputed innovation z - H x (MME&KF adds its direct term to it).
        """
        y = self.innovation(z) if y is None else y
        self.y = y
        if self.frozen:
            self.x = self.x + self.K @ y
            self.nis = float(y @ self.SI @ y)
            return
        P = self.P
        PHT = P @ self.H.T
        self.S = self.H @ PHT + self.R
        self.SI = np.linalg.inv(self.S)
        self.K = PHT @ self.SI
        self.x = self.x + self.K @ y
        I_KH = self._I - self.K @ self.H
        P_new = I_KH @ P @ I_KH.T + self.K @ self.R @ self.K.T
        self.nis = float(y @ self.SI @ y)
        if self.freeze_tol > 0:
            old = self.P_post
            if old is not None and np.max(np.abs(P_new - old)) <= self.freeze_tol * np.max(np.abs(P_new)):
                self._calm += 1
                if self._calm >= self.freeze_steps:
                    self.frozen = True
                    self._P_prior_ss = P
            else:
                self._calm = 0
        self.P_post = P_new
        self.P = P_new


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
        self.P = I_KH @ P @ I_KH.T + K @ R @ K.T
        self.P_post = self.P
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

    def step(self, z: np.ndarray) -> None:
        """One MME&KF step with measurement z at k (eq. 19 for d_k, then eq. 21)."""
        x0 = self.F @ self.x
        self.d = self._gain() @ (z - self.H @ x0)
        self.predict()
        self.x = self.x + self.Gamma @ self.d
        y = z - self.H @ self.x - self.E @ self.d
        self.update(z, y)

"""Linear half car (pitch plane), advanced exactly over each step with the inputs held.

Paper 002 (the half car of its eqs. 1-4), with passive dampers beside its actuators. Coordinates
upwards from static equilibrium: heave z (m) of the body at its centre of gravity, pitch theta
(rad, nose up positive, eq. 3), front and rear wheel displacements z_uf, z_ur (m). The body
points above the axles move as (eq. 3, small angles)

    z_bf = z + l_f theta,    z_br = z - l_r theta.

The suspension forces on the body, positive pushing body and wheel apart (eq. 2 with dampers):

    F_f = f_f + k_f (z_uf - z_bf) + c_f (v_uf - v_bf)
    F_r = f_r + k_r (z_ur - z_br) + c_r (v_ur - v_br)

and the equations of motion (eq. 1):

    m_s  z''     =  F_f + F_r
    I_y  theta'' =  l_f F_f - l_r F_r
    m_uf z_uf''  = -F_f + k_tf (q_f - z_uf)
    m_ur z_ur''  = -F_r + k_tr (q_r - z_ur)

Sign correction: the paper prints the pitch equation as I_y theta'' + L_f F_f - L_r F_r = 0,
i.e. I_y theta'' = -l_f F_f + l_r F_r. With theta nose-up (eq. 3) a force pushing the body up at
the front axle lifts the nose, so the moment is +l_f F_f: the printed equation, and with it row 2
of eq. 4's B and D, have the opposite sign. As printed B is not symmetric and the pitch mode is
unstable; with row 2 negated (``stiffness_matrix``, ``input_matrix``) B is the symmetric
stiffness matrix J' diag(k_f, k_r, k_tf, k_tr) J of the four springs' elongations J q.

In matrix form M q'' + C q' + K q = F u with q = [z, theta, z_uf, z_ur] and the inputs
u = [q_f, q_r, f_f, f_r] (road heights under the tyres m, actuator forces N); the state is
x = [q, q'] and over a step of length h the inputs are held (zero-order hold), advanced by the
matrix exponential of the augmented system as plant/quarter_car.py does. Gravity is balanced by
the static preloads; when the sprung mass changes the suspension is assumed levelled, so the
equilibrium does not move (the CG position and the pitch inertia stay those of the parameters).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import expm

from .quarter_car import SensorNoise
from .step_size import same_step
from .suspension_forces import G
from .vehicle import VEHICLE_RANGES, check_range


@dataclass(frozen=True)
class HalfCarParams:
    """One side of a passenger car in the pitch plane (one wheel per axle). SI units.

    Defaults: a mid-size front-engined sedan of 1500 kg, wheelbase 2.7 m (docs/half-car.md has
    the reasoning behind each): per corner the project's quarter car (plant/vehicle.py: k_s,
    k_t, c_s, m_u), the rear spring softer for the lighter rear corner.
    """

    m_s: float = 672.0  # sprung mass of the side, kg: (1500 kg - 4 wheels of 39 kg) / 2
    pitch_inertia: float = 968.0  # I_y of the side's sprung mass, kg m2: m_s (1.2 m)^2
    l_f: float = 1.1  # CG to front axle, m: 59 % of the sprung weight on the front axle
    l_r: float = 1.6  # CG to rear axle, m (wheelbase 2.7 m)
    m_uf: float = 39.0  # front unsprung mass, kg (the quarter car's m_u)
    m_ur: float = 39.0  # rear unsprung mass, kg
    k_f: float = 20000.0  # front spring, N/m (the quarter car's k_s: 1.13 Hz on 398 kg)
    k_r: float = 17000.0  # rear spring, N/m (1.25 Hz on 274 kg: Olley's rear ~10 % above the front)
    c_f: float = 2000.0  # front damper, N.s/m (the quarter car's c_s: damping ratio 0.35)
    c_r: float = 1500.0  # rear damper, N.s/m (damping ratio 0.35 on the rear corner)
    k_tf: float = 183000.0  # front tyre, N/m (the quarter car's k_t)
    k_tr: float = 183000.0  # rear tyre, N/m

    def with_(self, **changes: float) -> "HalfCarParams":
        return replace(self, **changes)

    @property
    def wheelbase(self) -> float:
        return self.l_f + self.l_r

    def static_tyre_loads(self) -> tuple[float, float]:
        """Static tyre forces (N) front and rear: the sprung weight split by the lever rule plus
        each wheel's weight."""
        L = self.wheelbase
        return (G * (self.m_s * self.l_r / L + self.m_uf), G * (self.m_s * self.l_f / L + self.m_ur))

    def problems(self) -> list[str]:
        """Messages for every parameter outside its allowed range (empty when valid)."""
        out = [msg for name, (lo, hi, lo_in) in HALF_CAR_RANGES.items()
               if (msg := check_range(name, getattr(self, name), lo, hi, lo_in))]
        if not out and not self.wheelbase > 0:
            out.append(f"l_f + l_r = {self.wheelbase!r} m: the wheelbase must be positive")
        return out


DEFAULT_HALF_CAR = HalfCarParams()

# Allowed ranges (low, high, low_inclusive), as plant/vehicle.py's: masses, springs, tyres and
# dampers per corner are the quarter car's; the CG lies between the axles (a CG outside them puts
# a negative static load on a wheel); from a scaled rig (a 10 kg body 0.1 m long, ~0.1 kg m2) to
# a truck's side (2e4 kg, radius of gyration ~7 m).
HALF_CAR_RANGES: dict[str, tuple[float, float, bool]] = {
    "m_s": VEHICLE_RANGES["m_s"],  # kg
    "pitch_inertia": (0.1, 1e6, True),  # kg m2
    "l_f": (0.0, 10.0, True),  # m
    "l_r": (0.0, 10.0, True),  # m
    "m_uf": VEHICLE_RANGES["m_u"],
    "m_ur": VEHICLE_RANGES["m_u"],
    "k_f": VEHICLE_RANGES["k_s"],  # N/m
    "k_r": VEHICLE_RANGES["k_s"],
    "c_f": VEHICLE_RANGES["c_s"],  # N.s/m, 0 = no damper (the paper's car)
    "c_r": VEHICLE_RANGES["c_s"],
    "k_tf": VEHICLE_RANGES["k_t"],  # N/m
    "k_tr": VEHICLE_RANGES["k_t"],
}


def mass_matrix(p: HalfCarParams) -> np.ndarray:
    """M of eq. 4 (its A): diag(m_s, I_y, m_uf, m_ur)."""
    return np.diag([p.m_s, p.pitch_inertia, p.m_uf, p.m_ur])


def stiffness_matrix(p: HalfCarParams) -> np.ndarray:
    """K (N/m, N, N m): eq. 4's B with row 2 negated (the pitch sign, module doc); symmetric."""
    kf, kr, lf, lr = p.k_f, p.k_r, p.l_f, p.l_r
    return np.array([
        [kf + kr, kf * lf - kr * lr, -kf, -kr],
        [kf * lf - kr * lr, kf * lf ** 2 + kr * lr ** 2, -kf * lf, kr * lr],
        [-kf, -kf * lf, kf + p.k_tf, 0.0],
        [-kr, kr * lr, 0.0, kr + p.k_tr],
    ])


def damping_matrix(p: HalfCarParams) -> np.ndarray:
    """C: the suspension part of K with the dampers for the springs (the tyres undamped)."""
    cf, cr, lf, lr = p.c_f, p.c_r, p.l_f, p.l_r
    return np.array([
        [cf + cr, cf * lf - cr * lr, -cf, -cr],
        [cf * lf - cr * lr, cf * lf ** 2 + cr * lr ** 2, -cf * lf, cr * lr],
        [-cf, -cf * lf, cf, 0.0],
        [-cr, cr * lr, 0.0, cr],
    ])


def input_matrix(p: HalfCarParams) -> np.ndarray:
    """F (4x4): the generalised forces of u = [q_f, q_r, f_f, f_r]; its columns are eq. 4's -C
    and -D, D with row 2 negated (the pitch sign, module doc)."""
    return np.array([
        [0.0, 0.0, 1.0, 1.0],
        [0.0, 0.0, p.l_f, -p.l_r],
        [p.k_tf, 0.0, -1.0, 0.0],
        [0.0, p.k_tr, 0.0, -1.0],
    ])


def state_matrices(p: HalfCarParams) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (8x8) and B (8x4) with x' = A x + B u, x = [q, q'], u = [q_f, q_r, f_f, f_r]."""
    Minv = np.diag(1.0 / np.diag(mass_matrix(p)))
    A = np.zeros((8, 8))
    A[:4, 4:] = np.eye(4)
    A[4:, :4] = -Minv @ stiffness_matrix(p)
    A[4:, 4:] = -Minv @ damping_matrix(p)
    B = np.zeros((8, 4))
    B[4:] = Minv @ input_matrix(p)
    return A, B


def natural_frequencies(p: HalfCarParams) -> np.ndarray:
    """Damped natural frequencies (Hz) of the four modes, ascending, from the eigenvalues of A
    (an overdamped mode, which has none, is left out)."""
    lam = np.linalg.eigvals(state_matrices(p)[0])
    return np.sort(lam[lam.imag > 0].imag) / (2 * np.pi)


class HalfCar:
    """The plant: true states, true and measured outputs of the half car.

    Measured: body accelerations above the front and rear axles, wheel accelerations and the
    two suspension deflections (body point minus wheel), each with white noise of the
    ``SensorNoise`` std of its kind; accelerations at the end of the step (QuarterCar's
    ``acc_sampling`` 0). ``tire_force`` is the total (static + dynamic) tyre force; the linear
    tyre pulls when it would leave the road, ``tire_contact`` says so.

    The state advanced is ``dx``, the deviation from the equilibrium ``x0`` that ``settle``
    found, driven by the inputs' deviation from the ones it settled on: at rest every deviation
    stays exactly 0, so the deflections read 0 on any road level.
    """

    def __init__(self, params: HalfCarParams = DEFAULT_HALF_CAR, noise: SensorNoise = SensorNoise(),
                 noise_seed: int = 1):
        if problems := params.problems():
            raise ValueError("; ".join(problems))
        self.params = params
        self.m_s = params.m_s
        self.noise = noise
        self.rng = np.random.default_rng(noise_seed)
        self.x0 = np.zeros(8)  # static equilibrium [q, q'] (m, rad, m/s, rad/s)
        self.u0 = np.zeros(4)  # the inputs it is the equilibrium of
        self.defl0 = (0.0, 0.0)  # its suspension deflections (m): the actuator forces' only
        self.dx = np.zeros(8)
        self.du = np.zeros(4)
        self.acc_true = (0.0, 0.0, 0.0, 0.0)  # body front, body rear, wheel front, wheel rear (m/s2)
        self.measured = (0.0,) * 6  # the four accelerations (m/s2), deflections front, rear (m)
        self._key: tuple[float, float] | None = None
        self._A = self._B = self._Ad = self._Bd = None
        self._noise: list[list[float]] = []
        self._noise_i = 0
        self.discretisations = 0  # matrix exponentials computed (one per step size and mass)

    def settle(self, road_front: float, road_rear: float, force_front: float = 0.0,
               force_rear: float = 0.0) -> None:
        """Put the car at rest in static equilibrium (K q = F u) on the road heights (m) under
        its tyres with the actuator forces (N) applied. On the road alone the car rests rigidly
        on it: z = (l_r q_f + l_f q_r) / L, theta = (q_f - q_r) / L, wheels on the road,
        deflections 0; the forces add K^-1 F_f [f_f, f_r], which leaves the tyre forces static."""
        p = self.params
        L = p.wheelbase
        rigid = [(p.l_r * road_front + p.l_f * road_rear) / L, (road_front - road_rear) / L, road_front, road_rear]
        forced = np.linalg.solve(stiffness_matrix(p), input_matrix(p)[:, 2:] @ [force_front, force_rear])
        self.x0 = np.concatenate([np.add(rigid, forced), np.zeros(4)])
        self.u0 = np.array([road_front, road_rear, force_front, force_rear], dtype=float)
        self.defl0 = _deflections(p, forced)
        self.dx = np.zeros(8)
        self.du = np.zeros(4)
        self.acc_true = (0.0, 0.0, 0.0, 0.0)
        self.measured = (0.0, 0.0, 0.0, 0.0, *self.defl0)

    def _matrices(self, m_s: float, h: float) -> None:
        self._A, self._B = state_matrices(self.params.with_(m_s=m_s))
        self._Ad, self._Bd = discretise(self._A, self._B, h)
        self._key = (m_s, h)
        self.discretisations += 1

    def step(self, road_front: float, road_rear: float, h: float, m_s: float | None = None,
             force_front: float = 0.0, force_rear: float = 0.0) -> None:
        """Advance by h seconds with the road heights (m), the sprung mass (kg) and the actuator
        forces (N) held. A step that differs from the previous one by rounding only
        (plant.step_size) reuses its discretisation. Raises ValueError, the state unchanged,
        if the result is not finite."""
        if not 0.0 < h < math.inf:
            raise ValueError(f"step h = {h!r} s is not a finite positive number")
        if self._key is not None:
            h = same_step(h, self._key[1])
        m_s = self.m_s if m_s is None else m_s
        if self._key != (m_s, h):
            self._matrices(m_s, h)
        du = np.array([road_front, road_rear, force_front, force_rear], dtype=float) - self.u0
        dx = self._Ad @ self.dx + self._Bd @ du
        acc = self._A[4:] @ dx + self._B[4:] @ du  # at the end of the step, the inputs held
        if not (np.all(np.isfinite(dx)) and np.all(np.isfinite(acc)) and np.all(np.isfinite(self.x0 + dx))):
            raise ValueError(f"the half car's state is not finite after a step of {h!r} s")
        self.dx, self.du, self.m_s = dx, du, m_s
        lf, lr = self.params.l_f, self.params.l_r
        a_z, a_th, a_uf, a_ur = acc.tolist()
        self.acc_true = (a_z + lf * a_th, a_z - lr * a_th, a_uf, a_ur)
        self._measure()

    def _measure(self) -> None:
        """Add the seeded sensor noise to the true accelerations and deflections."""
        # drawn in blocks: the same numbers as one draw of 6 per step
        if self._noise_i >= len(self._noise):
            self._noise = self.rng.standard_normal((256, 6)).tolist()
            self._noise_i = 0
        e = self._noise[self._noise_i]
        self._noise_i += 1
        n = self.noise
        a, d = self.acc_true, self.deflection_true
        self.measured = (a[0] + n.acc_sprung * e[0], a[1] + n.acc_sprung * e[1],
                         a[2] + n.acc_unsprung * e[2], a[3] + n.acc_unsprung * e[3],
                         d[0] + n.deflection * e[4], d[1] + n.deflection * e[5])

    @property
    def x(self) -> np.ndarray:
        """The state [z, theta, z_uf, z_ur, z', theta', z_uf', z_ur'] (m, rad, m/s, rad/s)."""
        return self.x0 + self.dx

    @property
    def deflection_true(self) -> tuple[float, float]:
        """Suspension deflections (m) front and rear: body point (eq. 3) minus wheel."""
        df, dr = _deflections(self.params, self.dx)
        return self.defl0[0] + df, self.defl0[1] + dr

    @property
    def tire_deflection_true(self) -> tuple[float, float]:
        """Tyre deflections (m) front and rear: wheel minus the road under it, 0 at rest (actuator
        forces or not: they leave the wheels on the road); the dynamic tyre force is -k_t times it."""
        dx, du = self.dx.tolist(), self.du.tolist()
        return dx[2] - du[0], dx[3] - du[1]

    @property
    def tire_force(self) -> tuple[float, float]:
        """Total tyre forces (N, pushing the wheel up) front and rear: the static load at the
        present sprung mass plus k_t (q - z_u) about the equilibrium (where it is 0, actuator
        forces or not); negative when the linear tyre pulls."""
        p = self.params
        sf, sr = p.with_(m_s=self.m_s).static_tyre_loads()
        du, dx = self.du.tolist(), self.dx.tolist()
        return sf + p.k_tf * (du[0] - dx[2]), sr + p.k_tr * (du[1] - dx[3])

    @property
    def tire_contact(self) -> tuple[int, int]:
        """1 when a tyre is pressed on the road, 0 when the linear tyre pulls (a lifted wheel)."""
        f, r = self.tire_force
        return int(f > 0.0), int(r > 0.0)


def _deflections(p: HalfCarParams, q) -> tuple[float, float]:
    """Body point minus wheel (m), front and rear, of the displacements q[:4] (eq. 3)."""
    z, th, zf, zr = (float(v) for v in q[:4])
    return z + p.l_f * th - zf, z - p.l_r * th - zr


def discretise(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of x' = A x + B u: x[k+1] = Ad x[k] + Bd u[k], from
    expm([A B; 0 0] h) (plant/quarter_car.py's, for several inputs)."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = expm(M * h)
    return np.ascontiguousarray(E[:n, :n]), np.ascontiguousarray(E[:n, n:])

"""The variable contract of the FMUs: one table per FMU (docs/fmu-interface.md is generated
from it by ``python build.py --docs``).

Every FMU class registers exactly these variables, the model description gets its units and
descriptions from here, and the FMUs validate their parameters against ``allowed``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..plant import iso8608
from ..plant.half_car import DEFAULT_HALF_CAR, HALF_CAR_RANGES
from ..plant.iri import SEGMENT_RANGE
from ..plant.profile_band import CUTOFF_RANGE, PROFILE_CUTOFF
from ..plant.profile_formats import MAX_POINTS
from ..plant.quarter_car import NOISE_STD_RANGES, SensorNoise
from ..plant.sensors import CALIBRATION_ALLOWANCE, SENSOR_ERROR_RANGES, SensorErrors
from ..plant.suspension_forces import DEFAULT_AIR_SPRING, DEFAULT_BUMP_STOPS, DEFAULT_DAMPER, FORCE_RANGES
from ..plant.vehicle import DEFAULT_VEHICLE, VEHICLE_RANGES

# unit name -> SI base-unit exponents, for <UnitDefinitions>
UNITS: dict[str, dict[str, float]] = {
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "Pa": {"kg": 1, "m": -1, "s": -2},
    "m2": {"m": 2},
    "m3": {"m": 3},
    "1/m": {"m": -1},
    "s": {"s": 1},
    "1": {},
    "m/km": {"factor": 1e-3},  # IRI: a slope, 1 m/km = 0.001
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "kg.m2": {"kg": 1, "m": 2},
    "N2/s": {"kg": 2, "m": 2, "s": -5},
}


@dataclass(frozen=True)
class Var:
    """One variable of the contract.

    ``allowed`` is (low, high) for a closed range, (low, high, low_inclusive, high_inclusive), or
    a dict {value: meaning} for a mode selector. Outputs have no start.
    """

    name: str
    causality: str  # parameter | input | output
    type: str  # Real | Integer | Boolean | String
    unit: str | None
    start: object
    description: str
    allowed: object = None


def _real_param(name, unit, start, description, allowed):
    return Var(name, "parameter", "Real", unit, float(start), description, allowed)


NOISE = SensorNoise()
V = DEFAULT_VEHICLE
_STD = (0.0, 1e3)
_SEED = (0, 2 ** 31 - 1)
_CLASSES = {c: f"ISO 8608 class {iso8608.class_name(c)}" for c in range(1, 9)}
_SPEED = (0.0, 100.0)
_IRI_SEGMENT = Var("iri_segment", "parameter", "Real", "m", 100.0,
                   "length of the segments the IRI is reported for", SEGMENT_RANGE)


# The estimator codes: code -> (short name, meaning). estimators/interface.py maps each code to
# the class that implements it (a test checks that both list the same codes).
ROAD_ESTIMATORS: dict[int, tuple[str, str]] = {
    0: ("Kalman filter", "Kalman filter on the exact linear model (paper 000's baseline)"),
    1: ("MME&KF", "MME&KF: minimum model error + Kalman filter (paper 000)"),
    2: ("KF with suspension-force error state",
        "Kalman filter with a suspension-force error state, anchored below 1 Hz by the exact-model KF at the "
        "identified mass and damping (robust to the spring and damper; default)"),
    3: ("EKF on the nonlinear model",
        "extended Kalman filter on the nonlinear quarter car of spring_model, damper_model and their parameters "
        "(paper 003's baseline)"),
    4: ("VB-AKF",
        "variational-Bayes adaptive Kalman filter adapting the measurement noise online (paper 004), its nominal "
        "road intensity scheduled by the ISO class identified from the measured response"),
    5: ("UKF on the nonlinear model",
        "unscented Kalman filter (Merwe sigma points) on the nonlinear quarter car of spring_model, damper_model "
        "and their parameters"),
}
MASS_ESTIMATORS: dict[int, tuple[str, str]] = {
    0: ("off", "off: the mass stays m_s_nominal"),
    1: ("forgetting-factor RLS", "forgetting-factor RLS on the suspension force balance (paper 001)"),
    2: ("IMM", "interacting multiple model (paper 002, eqs. 18-32): imm_models Kalman filters at sprung masses "
               "spread over imm_mass_min..imm_mass_max, the mass from the model probabilities (mean over 0.25 s), the "
               "road from the mixed filter; needs road_estimator 0"),
    3: ("dual observer",
        "paper 003's dual observer: a Kalman filter on 1/sprung mass from the body acceleration, exchanging "
        "estimates every step with the state filter of road_estimator 3 (EKF) or 5 (UKF), which it needs"),
    4: ("moving-bank IMM", "IMM whose five sub-models follow the mass (between any grid points as on them), "
                           "starting at m_s_nominal; needs road_estimator 0"),
}


def _codes_text(codes: dict[int, tuple[str, str]]) -> str:
    return "; ".join(f"{k} = {meaning}" for k, (_, meaning) in codes.items())


def _iri_output(name: str, of: str) -> Var:
    return Var(name, "output", "Real", "m/km", None,
               "International Roughness Index (ASTM E1926: golden car at 80 km/h over the profile in distance, "
               f"whatever the speed) of {of} over the last completed segment of iri_segment m; 0 before the first")


def _vehicle_params(prefix: str) -> list[Var]:
    return [
        _real_param("m_u", "kg", V.m_u, f"unsprung mass {prefix}", VEHICLE_RANGES["m_u"]),
        _real_param("k_s", "N/m", V.k_s, f"suspension stiffness (linear spring) {prefix}", VEHICLE_RANGES["k_s"]),
        _real_param("k_t", "N/m", V.k_t, f"tyre stiffness {prefix}", VEHICLE_RANGES["k_t"]),
        _real_param("c_s", "N.s/m", V.c_s, f"suspension damping (linear damper) {prefix}", VEHICLE_RANGES["c_s"]),
    ]


def _sensor_params(plant: bool) -> list[Var]:
    """The sensor errors of plant/sensors.py: what the plant's sensors add (``plant``), or the
    calibration the estimator removes (the same names, so that equal values cancel)."""
    texts = {
        "deflection_offset": ("m", "zero error of the deflection sensor"),
        "acc_sprung_bias": ("m/s2", "bias (zero error) of the sprung-mass accelerometer"),
        "acc_unsprung_bias": ("m/s2", "bias (zero error) of the unsprung-mass accelerometer"),
        "acc_sprung_scale": ("1", "gain of the sprung-mass accelerometer (measured / true)"),
        "acc_unsprung_scale": ("1", "gain of the unsprung-mass accelerometer (measured / true)"),
        "acc_sprung_delay": ("s", "lag of the sprung-mass acceleration channel (logger skew)"),
        "acc_unsprung_delay": ("s", "lag of the unsprung-mass acceleration channel (logger skew)"),
        "deflection_delay": ("s", "lag of the deflection channel (logger skew)"),
    }
    if plant:
        tail = {"m": ", added to the measured deflection", "m/s2": ", added to the measurement",
                "1": "", "s": ": the channel reports the value this long ago (linear interpolation)"}
    else:
        tail = {"m": " the estimator removes (known calibration)", "m/s2": " the estimator removes (known calibration)",
                "1": " the estimator divides out (known calibration)",
                "s": " the estimator aligns (known): the other channels are delayed to match, and the estimates "
                     "refer to the largest lag ago"}
    default = SensorErrors()
    return [_real_param(name, unit, getattr(default, name), text + tail[unit], SENSOR_ERROR_RANGES[name])
            for name, (unit, text) in texts.items()]


def _assumed_noise(assumed_by: str, prefix: str = "") -> list[Var]:
    """The std of the white noise an estimator assumes on each of the three sensor kinds (it sets
    R), defaults the plants' noise; ``assumed_by`` ends each description ("the filters assume")."""
    texts = {"acc_sprung_noise_std": ("m/s2", NOISE.acc_sprung, "body (sprung-mass) accelerometer"),
             "acc_unsprung_noise_std": ("m/s2", NOISE.acc_unsprung, "wheel (unsprung-mass) accelerometer"),
             "defl_noise_std": ("m", NOISE.deflection, "deflection sensor")}
    return [_real_param(name, unit, start, f"{prefix}{text} noise {assumed_by} (sets R)", NOISE_STD_RANGES[name])
            for name, (unit, start, text) in texts.items()]


def _force_params() -> list[Var]:
    """The nonlinear plant's parameters (spring_model or damper_model = 1): defaults and ranges from
    plant/suspension_forces.py."""
    texts = {
        "air_area": ("m2", "air spring effective area A_e"),
        "air_volume": ("m3", "air spring gas volume V_0 at the static ride height"),
        "air_kappa": ("1", "polytropic exponent of the air (1 isothermal .. 1.4 adiabatic)"),
        "air_pressure_max": ("Pa", "highest absolute pressure the levelling valve supplies: the static pressure "
                                   "p_atm + sprung_mass*g/air_area must stay below it"),
        "damper_c_rebound": ("N.s/m", "damper slope in rebound (extension) below the knee"),
        "damper_c_compression": ("N.s/m", "damper slope in compression below the knee"),
        "damper_knee_rebound": ("m/s", "rebound velocity of the damper's knee"),
        "damper_knee_compression": ("m/s", "compression velocity of the damper's knee"),
        "damper_c_rebound_high": ("N.s/m", "damper slope in rebound beyond the knee"),
        "damper_c_compression_high": ("N.s/m", "damper slope in compression beyond the knee"),
        "bump_stop_gap": ("m", "compression from the static point where the bump stop starts (nonlinear plant)"),
        "rebound_stop_gap": ("m", "extension from the static point where the rebound stop starts (nonlinear plant)"),
        "bump_stop_stiffness": ("N/m", "stiffness of the bump and rebound stops, 0 = no stops (nonlinear plant)"),
    }
    defaults = {**vars(DEFAULT_AIR_SPRING), **vars(DEFAULT_DAMPER), **vars(DEFAULT_BUMP_STOPS)}
    return [_real_param(name, unit, defaults[name], text, FORCE_RANGES[name]) for name, (unit, text) in texts.items()]


ISO_ROAD: tuple[Var, ...] = (
    Var("road_class", "parameter", "Integer", None, 3,
        "ISO 8608 class 1..8 = A..H; sets Gd(n0) = 16e-6*4^(class-1) m3", _CLASSES),
    _real_param("psd_n0", "m3", 0.0, "if > 0, Gd(n0) used instead of the class value", (0.0, 1.0)),
    _real_param("waviness", "1", iso8608.WAVINESS, "PSD exponent w in Gd(n) = Gd(n0)*(n/n0)^-w, n0 = 0.1 cycle/m",
                (0.0, 5.0)),
    _real_param("n_min", "1/m", iso8608.N_MIN, "lowest spatial frequency of the generated profile", (1e-4, 10.0)),
    _real_param("n_max", "1/m", iso8608.N_MAX, "highest spatial frequency of the generated profile", (1e-4, 10.0)),
    Var("seed", "parameter", "Integer", None, 1, "random seed of the profile: same seed, same road, at any speed",
        _SEED),
    Var("profile_file", "parameter", "String", None, "",
        "optional measured profile that replaces the synthetic one: columns distance, elevation (CSV or whitespace), "
        "ProVAL ERD text, or ASAM OpenCRG .crg (binary or ASCII); absolute elevations of any magnitude; "
        f"at most {MAX_POINTS / 1e6:g} million points. An absolute path, or a path relative to the FMU's "
        "resources folder (a file shipped in the FMU); the working directory is not searched"),
    Var("profile_units", "parameter", "String", None, "",
        "units of profile_file: '' = from its header (else m), 'mm' = elevation unit, 'ft,in' = distance, "
        "elevation units; any of m, cm, mm, km, ft, in"),
    _real_param("profile_lateral_offset", "m", 0.0,
                "OpenCRG: lateral offset v of the driven line from the reference line (left > 0)", (-100.0, 100.0)),
    Var("profile_end", "parameter", "Integer", None, 0,
        "past the end of profile_file: 0 = stop (doStep discards with a message), 1 = hold the last elevation, "
        "2 = loop (the profile again, shifted by its end-to-start rise so that the road stays continuous)",
        {0: "stop", 1: "hold", 2: "loop"}),
    _IRI_SEGMENT,
    Var("vehicle_speed", "input", "Real", "m/s", 11.1111, "forward speed (held over the step)", _SPEED),
    Var("road_height", "output", "Real", "m", None, "elevation under the tyre at the travelled distance"),
    Var("road_velocity", "output", "Real", "m/s", None, "time derivative of road_height"),
    Var("distance", "output", "Real", "m", None, "distance travelled"),
    _iri_output("iri", "road_height"),
    # added for the half car; at the end, so that the value references above stay as they were
    _real_param("wheelbase", "m", 0.0,
                "distance from the front to the rear tyre for road_height_rear; 0 = one tyre (road_height_rear "
                "is road_height)", (0.0, 20.0)),
    Var("road_height_rear", "output", "Real", "m", None,
        "elevation under the rear tyre, at distance - wheelbase (HalfCar's road_height_rear). Behind the start "
        "of a measured profile: its first elevation, held; the synthetic road is a function of distance on "
        "the whole line (a sum of cosines), so there the rear tyre starts on the road under it"),
)

QUARTER_CAR: tuple[Var, ...] = (
    *_vehicle_params("of the plant"),
    Var("spring_model", "parameter", "Integer", None, 0,
        "0 = linear spring k_s; 1 = self-levelling polytropic air spring (air_* parameters; k_s unused)",
        {0: "linear", 1: "air spring"}),
    Var("damper_model", "parameter", "Integer", None, 0,
        "0 = linear damper c_s; 1 = asymmetric piecewise-linear damper (damper_* parameters; c_s unused)",
        {0: "linear", 1: "asymmetric piecewise-linear"}),
    *_force_params(),
    _real_param("acc_sprung_noise_std", "m/s2", NOISE.acc_sprung,
                "std of white noise on the measured sprung-mass acceleration", _STD),
    _real_param("acc_unsprung_noise_std", "m/s2", NOISE.acc_unsprung,
                "std of white noise on the measured unsprung-mass acceleration", _STD),
    _real_param("defl_noise_std", "m", NOISE.deflection, "std of white noise on the measured deflection", (0.0, 1.0)),
    Var("noise_seed", "parameter", "Integer", None, 1, "seed of the sensor noise", _SEED),
    Var("acc_sampling", "parameter", "Integer", None, 0,
        "0 = accelerations sampled at the end of the step; 1 = averaged over the step (anti-alias filtered sensor)",
        {0: "end of step", 1: "average over the step"}),
    Var("road_height", "input", "Real", "m", 0.0,
        "road elevation under the tyre (over the step: road_input); absolute levels are fine: the plant settles "
        "on the first value and works relative to it", (-1e4, 1e4)),
    Var("sprung_mass", "input", "Real", "kg", V.m_s, "sprung mass; may change during a run (payload)",
        VEHICLE_RANGES["m_s"]),
    Var("acc_sprung", "output", "Real", "m/s2", None, "measured sprung-mass acceleration (with noise)"),
    Var("acc_unsprung", "output", "Real", "m/s2", None, "measured unsprung-mass acceleration (with noise)"),
    Var("susp_deflection", "output", "Real", "m", None, "measured suspension deflection z_s - z_u (with noise)"),
    Var("acc_sprung_true", "output", "Real", "m/s2", None, "noise-free sprung-mass acceleration"),
    Var("acc_unsprung_true", "output", "Real", "m/s2", None, "noise-free unsprung-mass acceleration"),
    Var("z_s", "output", "Real", "m", None, "true sprung-mass displacement from static equilibrium"),
    Var("v_s", "output", "Real", "m/s", None, "true sprung-mass velocity"),
    Var("z_u", "output", "Real", "m", None, "true unsprung-mass displacement from static equilibrium"),
    Var("v_u", "output", "Real", "m/s", None, "true unsprung-mass velocity"),
    Var("tire_deflection", "output", "Real", "m", None, "z_u - road_height"),
    Var("tire_force", "output", "Real", "N", None,
        "dynamic tyre force k_t*(road_height - z_u); the nonlinear plant's tyre cannot pull, so it stays "
        ">= -(sprung_mass + m_u)*g"),
    Var("tire_contact", "output", "Integer", None, None,
        "1 = tyre on the road, 0 = it left the road during the step (the linear plant's tyre pulls instead: "
        "0 when it would)"),
    Var("bump_stop", "output", "Integer", None, None,
        "0 = stops free, 1 = bump (compression) stop, 2 = rebound stop touched during the step "
        "(nonlinear plant; the linear plant has none)"),
    # a real car's sensor errors (plant/sensors.py); at the end, so that the value references above stay
    *_sensor_params(plant=True),
    Var("road_input", "parameter", "Integer", None, 0,
        "0 = road_height held over the step; 1 = the road moves linearly over the step from the last value to "
        "this one: a road source stepped before the plant gives the road at the step's end, and a held road "
        "is a staircase whose steps the tyre reads as impulses (on a 3 % grade at 72 km/h and 1 ms, a wheel "
        "acceleration 1.4 m/s2 off)", {0: "held", 1: "linear"}),
)

# The suspension laws the nonlinear estimators (road_estimator 3, 5; mass_estimator 3) are told: the
# plant's own variables (names, units, defaults, ranges), without the bump stops they do not model.
_MODEL_PARAMS = tuple(v for v in QUARTER_CAR if v.name in ("spring_model", "damper_model")
                      or (v.name.startswith(("air_", "damper_")) and v.causality == "parameter"))

SUSPENSION_ESTIMATOR: tuple[Var, ...] = (
    _real_param("m_s_nominal", "kg", V.m_s, "sprung mass the model assumes at start", VEHICLE_RANGES["m_s"]),
    *_vehicle_params("the model assumes"),
    *_MODEL_PARAMS,
    Var("road_estimator", "parameter", "Integer", None, 2, _codes_text(ROAD_ESTIMATORS),
        {k: name for k, (name, _) in ROAD_ESTIMATORS.items()}),
    Var("mass_estimator", "parameter", "Integer", None, 1, _codes_text(MASS_ESTIMATORS),
        {k: name for k, (name, _) in MASS_ESTIMATORS.items()}),
    Var("mass_feedback", "parameter", "Boolean", None, True,
        "re-build the road estimator's model at the estimated sprung mass (joint road + mass estimation)"),
    _real_param("forgetting_factor", "1", 0.995, "RLS forgetting factor lambda, 0.9 < lambda <= 1",
                (0.9, 1.0, False, True)),
    _real_param("imm_mass_min", "kg", 250.0, "mass_estimator 2: sprung mass of the lightest sub-model of the bank",
                VEHICLE_RANGES["m_s"]),
    _real_param("imm_mass_max", "kg", 550.0, "mass_estimator 2: sprung mass of the heaviest sub-model of the bank "
                "(above imm_mass_min)", VEHICLE_RANGES["m_s"]),
    Var("imm_models", "parameter", "Integer", None, 7,
        "mass_estimator 2: number of sub-models, evenly spaced from imm_mass_min to imm_mass_max", (2, 25)),
    _real_param("imm_stay", "1", 0.999, "mass_estimator 2 and 4: probability of keeping the sub-model per step "
                "(Markov transition matrix: the rest shared equally among the others)", (0.0, 1.0, False, False)),
    Var("road_class", "parameter", "Integer", None, 0,
        "0 = identify the ISO class online and schedule Q/R from it; 1..8 = assume that class (A..H)",
        {0: "identify online", **_CLASSES}),
    *_assumed_noise("the filters assume"),
    Var("acc_sampling", "parameter", "Integer", None, 0,
        "0 = accelerations sampled at the end of the step; 1 = averaged over the step (anti-alias filtered "
        "sensor); must match the sensor. 1 assumes the road held over the step: on a real road's logs at "
        "100-500 Hz point samples (0) are better", {0: "end of step", 1: "average over the step"}),
    _IRI_SEGMENT,
    Var("vb_iterations", "parameter", "Integer", None, 6,
        "road_estimator 4: fixed-point iterations of the VB update per step (paper 004: 6)", (1, 50)),
    _real_param("vb_forgetting", "1", 1.0 - math.exp(-4.0),
                "road_estimator 4: forgetting factor rho of the measurement-noise posterior per step, memory "
                "1/(1 - rho) steps (paper 004: 1 - exp(-4))", (0.9, 1.0, False, True)),
    _real_param("vb_tau", "1", 0.0,
                "road_estimator 4: weight of the nominal prediction in the prior of the predicted covariance "
                "(paper 004: 0.8); 0 = the predicted covariance is not adapted, only the measurement noise "
                "(default: follows a sensor whose noise grows)", (0.0, 1e6)),
    Var("acc_sprung", "input", "Real", "m/s2", 0.0, "measured sprung-mass acceleration"),
    Var("acc_unsprung", "input", "Real", "m/s2", 0.0, "measured unsprung-mass acceleration"),
    Var("susp_deflection", "input", "Real", "m", 0.0, "measured suspension deflection z_s - z_u"),
    Var("vehicle_speed", "input", "Real", "m/s", 11.1111, "forward speed", _SPEED),
    Var("road_height_est", "output", "Real", "m", None,
        "estimated road profile as inertial profilers report it: the elevation under the tyre high-passed in "
        "distance at profile_cutoff (third-order Butterworth, from 0 at the start; harness.metrics."
        "reference_profile gives it from a true profile); it holds while the car stands (speed below 0.5 m/s). "
        "The start level, grades, vertical curves and the drift of constant accelerometer biases fall outside "
        "this band"),
    Var("road_velocity_est", "output", "Real", "m/s", None,
        "estimated time derivative of the road elevation (the filter's, relative to its long-wavelength reference)"),
    Var("road_height_std", "output", "Real", "m", None,
        "1-sigma uncertainty of road_height_est against reference_profile: the filter covariance scaled to its "
        "steady-state error in that band on a road of the online class, with the gain and delay errors of "
        "calibration_gain_std and calibration_delay_std (road_estimator 0 and 2); for the other estimators their "
        "raw road variance, an upper bound (docs/real-sensors.md)"),
    Var("z_s_est", "output", "Real", "m", None, "estimated sprung-mass displacement"),
    Var("v_s_est", "output", "Real", "m/s", None, "estimated sprung-mass velocity"),
    Var("z_u_est", "output", "Real", "m", None, "estimated unsprung-mass displacement"),
    Var("v_u_est", "output", "Real", "m/s", None, "estimated unsprung-mass velocity"),
    Var("susp_deflection_est", "output", "Real", "m", None, "estimated suspension deflection z_s - z_u"),
    Var("tire_deflection_est", "output", "Real", "m", None, "estimated tyre deflection z_u - z_r"),
    Var("sprung_mass_est", "output", "Real", "kg", None, "estimated sprung mass"),
    Var("mass_std", "output", "Real", "kg", None,
        "standard error of sprung_mass_est (forgetting-factor RLS): small where the road excites the body, large "
        "on a smooth road (2 mass_std above 1 % of the mass: the road does not excite it enough for +-1 %); "
        "m_s_nominal (the prior) in the first second, 0 when the RLS does not estimate the mass"),
    _iri_output("iri_est", "road_height_est"),
    Var("road_class_est", "output", "Integer", None, None,
        "ISO 8608 class identified online (1..8 = A..H), 0 until enough road has been seen"),
    Var("nis", "output", "Real", "1", None, "normalised innovation squared of the last update (filter health)"),
    Var("status", "output", "Integer", None, None,
        "0 = ok, 1 = last measurement rejected (non-finite or outlier), 2 = filter re-initialised, "
        "3 = the innovations show an error the filter cannot absorb (a sensor far outside its calibration "
        "allowance, a dead channel, or a suspension far from the model): road_height_std is then "
        "|road_height_est| plus the band rms of the roughest ISO class in sight, held for 3 profile_cutoff "
        "lengths after the innovations are back (road_estimator 0 and 2)"),
    # the known calibration of the sensors (plant/sensors.py); at the end, so that the value references stay
    *_sensor_params(plant=False),
    _real_param("profile_cutoff", "m", PROFILE_CUTOFF,
                "long-wavelength cut-off of road_height_est (default 300 ft, the usual cut-off of inertial "
                "profilers: every wavelength the IRI responds to passes)", CUTOFF_RANGE),
    _real_param("calibration_gain_std", "1", CALIBRATION_ALLOWANCE["calibration_gain_std"][0],
                "1-sigma gain error (measured / true - 1) of each accelerometer that road_height_std allows for; "
                "0 for accelerometers calibrated or told (acc_*_scale)", CALIBRATION_ALLOWANCE["calibration_gain_std"][1]),
    _real_param("calibration_delay_std", "s", CALIBRATION_ALLOWANCE["calibration_delay_std"][0],
                "1-sigma delay (logger skew) of each channel that road_height_std allows for; 0 for channels whose "
                "skew is told (*_delay) or known to be none", CALIBRATION_ALLOWANCE["calibration_delay_std"][1]),
)

# HalfCar: one side of a mid-size sedan (docs/half-car.md gives the reasoning behind every default)
HC = DEFAULT_HALF_CAR


def _half_car_param(name: str, unit: str, description: str) -> Var:
    return _real_param(name, unit, getattr(HC, name), description, HALF_CAR_RANGES[name])


def _half_car_outputs(kind: str, unit: str, text: str) -> list[Var]:
    """The measured (with noise) and true outputs of one sensor kind, front and rear."""
    out = []
    for end in ("front", "rear"):
        out.append(Var(f"{kind}_{end}", "output", "Real", unit, None, f"measured (with noise) {text.format(end=end)}"))
    for end in ("front", "rear"):
        out.append(Var(f"{kind}_{end}_true", "output", "Real", unit, None, f"noise-free {text.format(end=end)}"))
    return out


HALF_CAR: tuple[Var, ...] = (
    _half_car_param("pitch_inertia", "kg.m2",
                    "pitch moment of inertia of the sprung mass about its centre of gravity (one side of the car; "
                    "default: the default sprung_mass 672 kg times (1.2 m radius of gyration)^2)"),
    _half_car_param("l_f", "m", "distance from the centre of gravity back to the front axle (default 1.1 m: 59 % "
                                "of the sprung weight on the front axle of a 2.7 m wheelbase)"),
    _half_car_param("l_r", "m", "distance from the centre of gravity forward to the rear axle; l_f + l_r > 0 "
                                "is the wheelbase"),
    _half_car_param("m_uf", "kg", "front unsprung mass (one wheel; default QuarterCar's m_u)"),
    _half_car_param("m_ur", "kg", "rear unsprung mass (one wheel; default QuarterCar's m_u)"),
    _half_car_param("k_f", "N/m", "front suspension spring (default QuarterCar's k_s: 1.13 Hz on the front "
                                  "corner's 398 kg)"),
    _half_car_param("k_r", "N/m", "rear suspension spring (default 1.25 Hz on the rear corner's 274 kg: the "
                                  "rear about 10 % above the front, Olley's flat ride)"),
    _half_car_param("c_f", "N.s/m", "front passive damper, 0 = none (paper 002's car: actuators only); default "
                                    "QuarterCar's c_s, damping ratio 0.35"),
    _half_car_param("c_r", "N.s/m", "rear passive damper, 0 = none; default damping ratio 0.35 on the rear corner"),
    _half_car_param("k_tf", "N/m", "front tyre stiffness (default QuarterCar's k_t)"),
    _half_car_param("k_tr", "N/m", "rear tyre stiffness (default QuarterCar's k_t)"),
    _real_param("acc_sprung_noise_std", "m/s2", NOISE.acc_sprung,
                "std of white noise on each measured body acceleration (front and rear, independent)", _STD),
    _real_param("acc_unsprung_noise_std", "m/s2", NOISE.acc_unsprung,
                "std of white noise on each measured wheel acceleration (front and rear, independent)", _STD),
    _real_param("defl_noise_std", "m", NOISE.deflection,
                "std of white noise on each measured suspension deflection (front and rear, independent)", (0.0, 1.0)),
    Var("noise_seed", "parameter", "Integer", None, 1, "seed of the sensor noise", _SEED),
    Var("road_height_front", "input", "Real", "m", 0.0,
        "road elevation under the front tyre (held over the step); absolute levels are fine: the plant settles "
        "on the first values and works relative to them", (-1e4, 1e4)),
    Var("road_height_rear", "input", "Real", "m", 0.0,
        "road elevation under the rear tyre (held over the step; ISORoad's road_height_rear)", (-1e4, 1e4)),
    Var("sprung_mass", "input", "Real", "kg", HC.m_s,
        "sprung mass of the side (default: a 1500 kg car less four 39 kg wheels, halved); may change during a "
        "run, the suspension then levelled, the centre of gravity and pitch_inertia kept", VEHICLE_RANGES["m_s"]),
    Var("force_front", "input", "Real", "N", 0.0,
        "front actuator force, positive pushing body and wheel apart (held over the step)", (-1e6, 1e6)),
    Var("force_rear", "input", "Real", "N", 0.0,
        "rear actuator force, positive pushing body and wheel apart (held over the step)", (-1e6, 1e6)),
    *_half_car_outputs("acc_body", "m/s2", "vertical acceleration of the body above the {end} axle"),
    *_half_car_outputs("acc_unsprung", "m/s2", "vertical acceleration of the {end} wheel"),
    *_half_car_outputs("susp_deflection", "m",
                       "{end} suspension deflection: body point above the axle minus wheel, 0 at rest (unless an "
                       "actuator pushes at the start)"),
    Var("heave", "output", "Real", "m", None, "true body displacement at the centre of gravity, upwards"),
    Var("heave_velocity", "output", "Real", "m/s", None, "true body velocity at the centre of gravity"),
    Var("pitch", "output", "Real", "rad", None, "true body pitch angle, nose up positive (small angles)"),
    Var("pitch_rate", "output", "Real", "rad/s", None, "true body pitch rate, nose up positive"),
    Var("z_u_front", "output", "Real", "m", None, "true front wheel displacement, upwards"),
    Var("v_u_front", "output", "Real", "m/s", None, "true front wheel velocity"),
    Var("z_u_rear", "output", "Real", "m", None, "true rear wheel displacement, upwards"),
    Var("v_u_rear", "output", "Real", "m/s", None, "true rear wheel velocity"),
    Var("tire_force_front", "output", "Real", "N", None,
        "total front tyre force (static load + k_tf (road_height_front - z_u_front) about the equilibrium); the "
        "linear tyre pulls when the wheel would lift: then it is negative and tire_contact_front 0"),
    Var("tire_force_rear", "output", "Real", "N", None, "total rear tyre force (as tire_force_front)"),
    Var("tire_contact_front", "output", "Integer", None, None,
        "1 = front tyre pressed on the road, 0 = the linear tyre pulls (the wheel would have lifted)"),
    Var("tire_contact_rear", "output", "Integer", None, None,
        "1 = rear tyre pressed on the road, 0 = the linear tyre pulls (the wheel would have lifted)"),
    # added for SuspensionController; at the end, so that the value references above stay as they were
    Var("tire_deflection_front_true", "output", "Real", "m", None,
        "noise-free front tyre deflection: wheel minus the road under it, 0 at rest (the dynamic tyre force is "
        "-k_tf times it)"),
    Var("tire_deflection_rear_true", "output", "Real", "m", None,
        "noise-free rear tyre deflection: wheel minus the road under it, 0 at rest"),
)

# HalfCarEstimator: paper 002's observers on the half car (estimators/half_car_imm.py; its
# ObserverSettings holds the same defaults, tests/test_half_car_estimator.py checks both agree)
HALF_CAR_ESTIMATORS: dict[int, tuple[str, str]] = {
    0: ("KF", "KF: one Kalman filter at m_s_nominal on a road of class road_class (the paper's KF)"),
    1: ("AKF", "AKF: the KF with its road noise switched to the ISO class identified online"),
    2: ("IMMKF", "IMMKF: interacting multiple model of imm_models Kalman filters at sprung masses evenly spread "
                 "over imm_mass_min..imm_mass_max, on a road of class road_class"),
    3: ("IMMAKF3", "IMMAKF3: one IMM of 3 mass sub-models (imm_mass_min, the middle, imm_mass_max) per road grade, "
                   "the grade identified online in use"),
    4: ("IMMAKF5", "IMMAKF5: as IMMAKF3 with 5 mass sub-models per grade (the paper's best; default)"),
}
HALF_CAR_SENSORS: dict[int, str] = {
    0: "a real car: acc_body_front, acc_body_rear, acc_unsprung_front, acc_unsprung_rear, susp_deflection_front, "
       "susp_deflection_rear (HalfCar's measured outputs)",
    1: "the paper's: heave_velocity, pitch_rate, v_u_front, v_u_rear (absolute velocities, eq. 41)",
}
_VELOCITY_STD = (1e-6, 1e3)


def _estimate_outputs(name: str, unit: str, text: str) -> list[Var]:
    return [Var(f"{name}_est", "output", "Real", unit, None, f"estimated {text}"),
            Var(f"{name}_std", "output", "Real", unit, None, f"1-sigma uncertainty of {name}_est (filter covariance)")]


HALF_CAR_ESTIMATOR: tuple[Var, ...] = (
    Var("estimator", "parameter", "Integer", None, 4, _codes_text(HALF_CAR_ESTIMATORS),
        {k: name for k, (name, _) in HALF_CAR_ESTIMATORS.items()}),
    Var("sensors", "parameter", "Integer", None, 0,
        "the measurements the observer reads: " + "; ".join(f"{k} = {v}" for k, v in HALF_CAR_SENSORS.items()),
        {k: v.split(":")[0] for k, v in HALF_CAR_SENSORS.items()}),
    _real_param("m_s_nominal", "kg", HC.m_s, "sprung mass of the side the KF and AKF assume", VEHICLE_RANGES["m_s"]),
    _real_param("imm_mass_min", "kg", HC.m_s - 200.0,
                "estimator 2-4: sprung mass of the lightest sub-model (default: a side's payload -200 kg)",
                VEHICLE_RANGES["m_s"]),
    _real_param("imm_mass_max", "kg", HC.m_s + 200.0,
                "estimator 2-4: sprung mass of the heaviest sub-model (above imm_mass_min)", VEHICLE_RANGES["m_s"]),
    Var("imm_models", "parameter", "Integer", None, 5, "estimator 2: number of mass sub-models (the paper's IMMKF: 5)",
        (2, 25)),
    _real_param("imm_stay", "1", 0.999, "estimator 2-4: probability of keeping the sub-model per step (Markov "
                "transition matrix: the rest shared equally among the others)", (0.0, 1.0, False, False)),
    Var("road_class", "parameter", "Integer", None, 3,
        "ISO class the KF and IMMKF assume, and the AKF and IMMAKF start from until a class is identified", _CLASSES),
    Var("road_noise", "parameter", "Integer", None, 0,
        "process noise of the road model: 0 = the ISO intensity of the class at the speed (eq. 5, exact at any step); "
        "1 = the paper's eqs. 38-40 (eq. 40's road velocity per sample, fitted at 20 m/s)",
        {0: "ISO intensity (eq. 5)", 1: "paper eqs. 38-40"}),
    *(_half_car_param(v.name, v.unit, v.description) for v in HALF_CAR if v.name in HALF_CAR_RANGES),
    *_assumed_noise("the observer assumes", "sensors 0: "),
    _real_param("velocity_noise_std", "m/s", 0.01, "sensors 1: noise of each velocity the observer assumes, the pitch "
                "rate's in rad/s (sets R; the paper's R = 0.01^2)", _VELOCITY_STD),
    _real_param("force_error_q", "N2/s", 100.0,
                "sensors 0: intensity of the random walk of each axle's force error, a state that takes up what the model's "
                "spring and damper forces get wrong; 0 = the paper's model (an LQR on its estimates diverges in "
                "pitch with springs 15 % softer than told)", (0.0, 1e8)),
    *(Var(v.name, "input", "Real", v.unit, 0.0, v.description.replace("measured (with noise)", "sensors 0: measured"))
      for v in HALF_CAR if v.name in ("acc_body_front", "acc_body_rear", "acc_unsprung_front", "acc_unsprung_rear",
                                      "susp_deflection_front", "susp_deflection_rear")),
    Var("heave_velocity", "input", "Real", "m/s", 0.0, "sensors 1: measured body velocity at the centre of gravity"),
    Var("pitch_rate", "input", "Real", "rad/s", 0.0, "sensors 1: measured body pitch rate, nose up positive"),
    Var("v_u_front", "input", "Real", "m/s", 0.0, "sensors 1: measured front wheel velocity"),
    Var("v_u_rear", "input", "Real", "m/s", 0.0, "sensors 1: measured rear wheel velocity"),
    Var("force_front", "input", "Real", "N", 0.0,
        "front actuator force held over the step the measurements end (HalfCar's force_front), positive pushing body "
        "and wheel apart", (-1e6, 1e6)),
    Var("force_rear", "input", "Real", "N", 0.0, "rear actuator force held over the step (HalfCar's force_rear)",
        (-1e6, 1e6)),
    Var("vehicle_speed", "input", "Real", "m/s", 11.1111, "forward speed (sets the road noise)", _SPEED),
    *_estimate_outputs("heave_velocity", "m/s", "body velocity at the centre of gravity"),
    *_estimate_outputs("pitch_rate", "rad/s", "body pitch rate, nose up positive"),
    *_estimate_outputs("v_u_front", "m/s", "front wheel velocity"),
    *_estimate_outputs("v_u_rear", "m/s", "rear wheel velocity"),
    *_estimate_outputs("susp_deflection_front", "m", "front suspension deflection: body point above the axle minus "
                                                     "wheel, 0 at rest without actuator force"),
    *_estimate_outputs("susp_deflection_rear", "m", "rear suspension deflection (as susp_deflection_front_est)"),
    *_estimate_outputs("tire_deflection_front", "m", "front tyre deflection: wheel minus road, 0 at rest"),
    *_estimate_outputs("tire_deflection_rear", "m", "rear tyre deflection: wheel minus road, 0 at rest"),
    Var("road_height_front_est", "output", "Real", "m", None,
        "estimated road under the front tyre relative to a level the filter lets go at eq. 5's 0.01 Hz pole (no "
        "sensor sees the absolute level): from 0 at the start, good above about 1 Hz"),
    Var("road_height_rear_est", "output", "Real", "m", None, "estimated road under the rear tyre (as the front's)"),
    Var("sprung_mass_est", "output", "Real", "kg", None,
        "estimated sprung mass of the side: the probability-weighted mass of the sub-models (estimator 2-4), "
        "m_s_nominal for estimator 0 and 1"),
    Var("sprung_mass_std", "output", "Real", "kg", None,
        "spread of the sub-models' masses under their probabilities (0 for estimator 0 and 1)"),
    Var("road_class_est", "output", "Integer", None, None,
        "ISO 8608 class (1..8 = A..H) identified from the estimated front road over the last 102.4 m (road_class "
        "until the first window is full); estimator 1, 3 and 4 switch the road noise with it"),
    Var("mass_model", "output", "Integer", None, None,
        "the most probable mass sub-model, 1 = the lightest (0 for estimator 0 and 1)"),
    Var("mass_model_probability", "output", "Real", "1", None, "its probability (1 for estimator 0 and 1)"),
    Var("innovation_ratio", "output", "Real", "1", None,
        "average over 1 s of the normalised innovation squared per measurement: about 1 when the car and the "
        "sensors are the model's; the *_std outputs are the filter's times its square root when above 1"),
    Var("status", "output", "Integer", None, None,
        "0 = updated, 1 = a measurement of the sensor set was not finite: the step predicted only, 3 = "
        "innovation_ratio above 2.5: the car or a sensor is not what the model assumes (the *_std are widened)"),
)

# SuspensionController: the half car's active suspension (controllers/; docs/controller.md). The
# mode codes are controllers/controller.py's MODES (a test checks that both list the same codes).
CONTROLLER_MODES: dict[int, tuple[str, str]] = {
    0: ("passive", "passive: no actuator force (the car's dampers c_f, c_r alone)"),
    1: ("skyhook", "skyhook: f = -c_sky times the velocity of the body above each axle"),
    2: ("LQR, weights scheduled",
        "LQR of paper 002 (eqs. 10-14) designed at sprung_mass, its weights scheduled over vehicle_speed, road_class "
        "and sprung_mass from the NSGA-II of eq. 17 on HalfCar's default car (default)"),
    3: ("LQR, fixed weights", "the LQR designed at sprung_mass with the weights q1, q2, q3"),
}
_STATE = (-1e6, 1e6)  # any finite value
# the car the controller designs for: HalfCar's parameters, its defaults
_DESIGN_CAR = tuple(_half_car_param(v.name, v.unit, "the controller's model of the car: " + v.description)
                    for v in HALF_CAR if v.name in HALF_CAR_RANGES)

SUSPENSION_CONTROLLER: tuple[Var, ...] = (
    Var("mode", "parameter", "Integer", None, 2, _codes_text(CONTROLLER_MODES),
        {k: name for k, (name, _) in CONTROLLER_MODES.items()}),
    _real_param("force_limit", "N", 3000.0,
                "actuator force limit: each force is saturated at +-force_limit (default: 3 sigma of the scheduled "
                "LQR's force on ISO D at 30 m/s is 2.8 kN)", (0.0, 1e6, False, True)),
    _real_param("c_sky", "N.s/m", 3000.0,
                "mode 1: skyhook damping at each axle (default: damping ratio 0.53 on the front corner, 398 kg on "
                "20 kN/m)", (0.0, 1e6)),
    _real_param("q1", "1", 2e7, "mode 3: LQR weight of each suspension deflection squared (m2), paper 002's q1 = q4 "
                "(eq. 11); only the ratios of q1, q2, q3 matter", (0.0, 1e9)),
    _real_param("q2", "1", 1000.0, "mode 3: LQR weight of each body acceleration squared above the axles ((m/s2)2), "
                "q2 = q5; R^-1 needs q2 > 0", (0.0, 2000.0, False, True)),
    _real_param("q3", "1", 1e-4, "mode 3: LQR weight of each tyre deflection squared (m2), q3 = q6 (the paper's "
                "1e-4)", (0.0, 1e9)),
    *_DESIGN_CAR,
    Var("heave_velocity", "input", "Real", "m/s", 0.0,
        "body velocity at the centre of gravity (HalfCar's heave_velocity, or an estimator's)", _STATE),
    Var("pitch_rate", "input", "Real", "rad/s", 0.0, "body pitch rate, nose up positive", _STATE),
    Var("v_u_front", "input", "Real", "m/s", 0.0, "front wheel velocity", _STATE),
    Var("v_u_rear", "input", "Real", "m/s", 0.0, "rear wheel velocity", _STATE),
    Var("susp_deflection_front", "input", "Real", "m", 0.0,
        "front suspension deflection: body point above the axle minus wheel (HalfCar's susp_deflection_front_true)",
        _STATE),
    Var("susp_deflection_rear", "input", "Real", "m", 0.0, "rear suspension deflection (as the front's)", _STATE),
    Var("tire_deflection_front", "input", "Real", "m", 0.0,
        "front tyre deflection: wheel minus road (HalfCar's tire_deflection_front_true); never an absolute height",
        _STATE),
    Var("tire_deflection_rear", "input", "Real", "m", 0.0, "rear tyre deflection: wheel minus road", _STATE),
    Var("vehicle_speed", "input", "Real", "m/s", 20.0, "forward speed: schedules the weights (mode 2)", _SPEED),
    Var("road_class", "input", "Integer", None, 3,
        "ISO 8608 class of the road, 1..8 = A..H (an estimator's road_class_est), 0 = not identified yet (taken as "
        "C): schedules the weights (mode 2; E-H take D's)", {0: "not identified (C)", **_CLASSES}),
    Var("sprung_mass", "input", "Real", "kg", HC.m_s,
        "sprung mass of the side (an estimator's sprung_mass_est, or the truth): the LQR is designed for it "
        "(modes 2, 3) and it schedules the weights (mode 2)", VEHICLE_RANGES["m_s"]),
    Var("force_front", "output", "Real", "N", None,
        "front actuator force after the limit, positive pushing body and wheel apart: HalfCar's force_front"),
    Var("force_rear", "output", "Real", "N", None, "rear actuator force after the limit: HalfCar's force_rear"),
    Var("force_front_demand", "output", "Real", "N", None, "front force the control law asks before the limit"),
    Var("force_rear_demand", "output", "Real", "N", None, "rear force the control law asks before the limit"),
    Var("saturated", "output", "Integer", None, None, "1 = the limit cut a demand at this step, 0 = it did not"),
    Var("q1_used", "output", "Real", "1", None, "LQR weight q1 in use (0 in modes 0 and 1)"),
    Var("q2_used", "output", "Real", "1", None, "LQR weight q2 in use (0 in modes 0 and 1)"),
    Var("q3_used", "output", "Real", "1", None, "LQR weight q3 in use (0 in modes 0 and 1)"),
)

CONTRACTS: dict[str, tuple[Var, ...]] = {
    "ISORoad": ISO_ROAD,
    "QuarterCar": QUARTER_CAR,
    "SuspensionEstimator": SUSPENSION_ESTIMATOR,
    "HalfCar": HALF_CAR,
    "HalfCarEstimator": HALF_CAR_ESTIMATOR,
    "SuspensionController": SUSPENSION_CONTROLLER,
}

# The longest communication step (s) each FMU takes; a longer one is refused (fmi2Discard)
# before anything moves. The estimator's ISO class from the response band-passes up to 32 Hz,
# which a step must resolve (32 Hz < 1 / (2 h)): 100 Hz logging is the coarsest the design aims
# at; HalfCarEstimator identifies its class from the road up to 2 cycles/m (40 Hz at 20 m/s) and
# takes the same limit. The road integrates the IRI over every 250 mm it passes: 1 s at 100 m/s is 400 of them.
# The plants are exact for any step; the controller is a static gain (docs/controller.md: the
# sampled loop with the scheduled LQR stays stable to 0.1 s).
MAX_STEP: dict[str, float] = {"ISORoad": 1.0, "QuarterCar": math.inf, "SuspensionEstimator": 0.015,
                              "HalfCar": math.inf, "HalfCarEstimator": 0.015,
                              "SuspensionController": math.inf}


def allowed_text(var: Var) -> str:
    a = var.allowed
    if isinstance(a, dict):
        return "{" + ", ".join(f"{k} = {v}" for k, v in a.items()) + "}"
    low, high, *incl = a
    lo_in, hi_in = (incl + [True, True])[:2]
    return f"{'[' if lo_in else '('}{_number(low)}, {_number(high)}{']' if hi_in else ')'}"


def _number(x: float) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


def problem(var: Var, value: object) -> str | None:
    """A message naming the variable and its allowed range if ``value`` is not allowed."""
    a = var.allowed
    if a is None:
        return None
    if isinstance(a, dict):
        ok = value in a
    else:
        low, high, *incl = a
        lo_in, hi_in = (incl + [True, True])[:2]
        try:
            v = float(value)
        except (TypeError, ValueError):
            v = float("nan")
        ok = v == v and (v >= low if lo_in else v > low) and (v <= high if hi_in else v < high)
    if ok:
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return f"{var.name} = {value!r} is not a finite number (allowed range {allowed_text(var)})"
    return f"{var.name} = {value!r} is outside the allowed range {allowed_text(var)}"


# Inputs each output depends on at a communication point (FMI 2.0 ModelStructure/Outputs
# ``dependencies``; an output not listed depends on none). Every output is computed by doStep
# from the inputs held over the step, so an input set at a communication point reaches no output
# before the next doStep: no FMU has direct feedthrough, and a master can close a loop through
# them without an algebraic loop. tests/test_model_structure.py checks this through the built FMUs.
DEPENDENCIES: dict[str, dict[str, tuple[str, ...]]] = {
    "ISORoad": {},
    "QuarterCar": {},
    "SuspensionEstimator": {},
    "HalfCar": {},
    "HalfCarEstimator": {},
    "SuspensionController": {},
}

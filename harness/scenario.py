"""Scenarios: TOML data files that say what to co-simulate (road, speed, payload, noise, duration).

A scenario is looked up by name in ``harness/scenarios/`` (``default`` -> ``default.toml``) or
given as a path. Keys (units in brackets; everything but ``duration`` and ``step`` optional):

    description = "..."
    duration = 20.0            # [s], or "profile": drive the whole [road] profile_file at the
                               # [speed] (the last whole step before its end)
    step = 0.001               # [s] communication step
    estimator_step = 0.01      # [s] the estimator's step, a whole number of steps (default: step):
                               # it runs on the plant's outputs at its own steps, as a data logger
                               # sampling at 1 / estimator_step gives them, and the record holds
                               # those rows (with [plant] road_input = 1 the road is not a staircase)
    system = "auto"            # "auto" (with the estimator when its FMU exists), "road_plant",
                               # "road_plant_estimator"

    [road]                     # ISORoad parameters by name
    road_class = "C"           # "A".."H" or 1..8
    seed = 1                   # also psd_n0 [m3], waviness [1], n_min, n_max [1/m],
    profile_file = ""          # a path relative to the scenario file; also profile_units,
                               # profile_lateral_offset, profile_end (see the ISORoad contract)

    [speed]                    # vehicle_speed [m/s]: value = 11.1111, or breakpoints
    time = [0.0, 10.0]         # [s], increasing
    value = [11.1111, 22.2222] # [m/s]
    interpolation = "linear"   # "linear" or "step" (hold the value from each breakpoint)

    [sprung_mass]              # QuarterCar sprung_mass input [kg], same form as [speed];
                               # the default interpolation is "step" (a payload change)

    [noise]                    # sensor noise of the plant, also what the estimator assumes
    seed = 1
    acc_sprung_std = 0.02      # [m/s2]
    acc_unsprung_std = 0.2     # [m/s2]
    defl_std = 0.0001          # [m]

    [plant]                    # QuarterCar parameters by name (override [noise] for the plant
                               # only); its m_u, k_s, k_t, c_s and acc_sampling are also
                               # what the estimator assumes
    [estimator]                # SuspensionEstimator parameters by name (override both)

    [output]
    record = ["QuarterCar.v_s"]  # extra variables to record, "instance.variable"
    plots = true

Structural errors raise ``ScenarioError`` with a one-line message naming the key. Physical
ranges (a negative speed, a zero mass) are the FMUs' to refuse, at initialization or at the step.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

SCENARIOS = Path(__file__).resolve().parent / "scenarios"

_TOP = {"description", "duration", "step", "estimator_step", "system", "road", "speed", "sprung_mass", "noise", "plant",
        "estimator", "output"}
_SYSTEMS = ("auto", "road_plant", "road_plant_estimator")
_PROFILE = {"value", "time", "interpolation"}
_NOISE = {"seed": "noise_seed", "acc_sprung_std": "acc_sprung_noise_std",
          "acc_unsprung_std": "acc_unsprung_noise_std", "defl_std": "defl_noise_std"}
_OUTPUT = {"record", "plots"}
_CLASSES = "ABCDEFGH"
_VEHICLE = ("m_u", "k_s", "k_t", "c_s", "acc_sampling")  # also told to the estimator


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message is one line naming the file and key."""


@dataclass
class Profile:
    """A signal over time: breakpoints ``time`` [s] and ``value``, interpolated linearly or held
    (``step``); constant before the first and after the last breakpoint."""

    time: np.ndarray
    value: np.ndarray
    interpolation: str = "linear"

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        if self.interpolation == "step":
            i = np.searchsorted(self.time, t, side="right") - 1
            return self.value[np.clip(i, 0, len(self.value) - 1)]
        return np.interp(t, self.time, self.value)

    @property
    def is_constant(self) -> bool:
        return bool(np.all(self.value == self.value[0]))


@dataclass
class Scenario:
    """A validated scenario. Parameters are ``{"instance.variable": value}`` for the harness."""

    name: str
    path: Path
    description: str
    duration: float
    step: float
    system: str
    speed: Profile
    sprung_mass: Profile
    road: dict = field(default_factory=dict)
    plant: dict = field(default_factory=dict)
    estimator: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)
    record: list[str] = field(default_factory=list)
    plots: bool = True
    estimator_every: int = 1  # steps per estimator step (``estimator_step``)

    def parameters(self, with_estimator: bool) -> dict[str, object]:
        """Parameters of every instance by ``"instance.variable"``."""
        out = {f"ISORoad.{k}": v for k, v in self.road.items()}
        noise = {_NOISE[k]: v for k, v in self.noise.items()}
        out.update({f"QuarterCar.{k}": v for k, v in {**noise, **self.plant}.items()})
        if with_estimator:
            assumed = {k: v for k, v in noise.items() if k != "noise_seed"}
            assumed.update({k: v for k, v in self.plant.items() if k in _VEHICLE})
            out.update({f"SuspensionEstimator.{k}": v for k, v in {**assumed, **self.estimator}.items()})
        return out

    @property
    def profile_cutoff(self) -> float:
        """m, the estimator's profile_cutoff (the band road_height_est and its truth are in)."""
        from ..plant.profile_band import PROFILE_CUTOFF

        return float(self.estimator.get("profile_cutoff", PROFILE_CUTOFF))


def _err(where: str, msg: str) -> ScenarioError:
    return ScenarioError(f"{where}: {msg}")


def _number(where: str, key: str, value, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _err(where, f"'{key}' must be a finite number, got {value!r}")
    if positive and not value > 0:
        raise _err(where, f"'{key}' must be > 0, got {value!r}")
    return float(value)


def _table(where: str, data: dict, key: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise _err(where, f"'{key}' must be a table ([{key}])")
    return value


def _profile(where: str, key: str, data, default: float, default_interp: str) -> Profile:
    if data is None:
        return Profile(np.array([0.0]), np.array([default]), default_interp)
    if isinstance(data, (int, float)) and not isinstance(data, bool):
        return Profile(np.array([0.0]), np.array([_number(where, key, data)]), default_interp)
    if not isinstance(data, dict):
        raise _err(where, f"'{key}' must be a number or a table with 'value' (and 'time')")
    if unknown := set(data) - _PROFILE:
        raise _err(where, f"unknown key '{key}.{sorted(unknown)[0]}' (allowed: {', '.join(sorted(_PROFILE))})")
    if "value" not in data:
        raise _err(where, f"'{key}.value' is missing")
    interp = data.get("interpolation", default_interp)
    if interp not in ("linear", "step"):
        raise _err(where, f"'{key}.interpolation' must be \"linear\" or \"step\", got {interp!r}")
    value = data["value"]
    if "time" not in data:
        if isinstance(value, list):
            raise _err(where, f"'{key}.value' is a list, so '{key}.time' is needed")
        return Profile(np.array([0.0]), np.array([_number(where, f"{key}.value", value)]), interp)
    times, values = data["time"], value
    if not isinstance(times, list) or not isinstance(values, list) or not times:
        raise _err(where, f"'{key}.time' and '{key}.value' must be non-empty lists")
    if len(times) != len(values):
        raise _err(where, f"'{key}.time' has {len(times)} entries, '{key}.value' {len(values)}")
    t = np.array([_number(where, f"{key}.time", x) for x in times])
    v = np.array([_number(where, f"{key}.value", x) for x in values])
    if np.any(np.diff(t) <= 0):
        raise _err(where, f"'{key}.time' must be strictly increasing")
    return Profile(t, v, interp)


def _params(where: str, key: str, data: dict) -> dict:
    for k, v in data.items():
        if isinstance(v, (dict, list)):
            raise _err(where, f"'{key}.{k}' must be a single value")
    return dict(data)


def _whole_profile_duration(where: str, road: dict, speed: Profile, step: float) -> float:
    """The duration (s, whole steps) that drives the road's profile_file to its end: the road
    advances by speed(t_k) * step in step k, and the last step must not pass the end."""
    from suspension_estimation.plant.profile_formats import ProfileError, read_profile

    if not road.get("profile_file"):
        raise _err(where, "'duration' = \"profile\" needs 'road.profile_file'")
    try:
        dist, _ = read_profile(road["profile_file"], road.get("profile_units", ""),
                               road.get("profile_lateral_offset", 0.0))
    except ProfileError as e:
        raise _err(where, str(e)) from None
    length = float(dist[-1] - dist[0])
    travelled, n, chunk = 0.0, 0, 4096
    while True:
        v = np.abs(np.broadcast_to(speed(step * np.arange(n, n + chunk)), (chunk,)))
        d = travelled + step * np.cumsum(v)
        over = np.flatnonzero(d > length * (1 + 1e-12))
        if len(over):
            n += int(over[0])
            break
        travelled, n = float(d[-1]), n + chunk
        if n * step > 1e7:
            raise _err(where, f"the speed never covers the {length:g} m of the profile")
    if n == 0:
        raise _err(where, f"the profile ({length:g} m) is shorter than one step at the start speed")
    return n * step


def find_scenario(name_or_path: str | Path) -> Path:
    """The scenario file for a name in ``harness/scenarios/`` or a path."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.parent != Path("."):
        if not p.is_file():
            raise ScenarioError(f"scenario file {p} does not exist")
        return p
    q = SCENARIOS / f"{p.name}.toml"
    if q.is_file():
        return q
    if p.is_file():
        return p
    known = ", ".join(sorted(f.stem for f in SCENARIOS.glob("*.toml")))
    raise ScenarioError(f"unknown scenario {str(name_or_path)!r} (known: {known})")


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Read and validate a scenario (by name or path)."""
    path = find_scenario(name_or_path)
    where = f"scenario {path.name}"
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise _err(where, f"not valid TOML: {e}") from None
    if unknown := set(data) - _TOP:
        raise _err(where, f"unknown key '{sorted(unknown)[0]}' (allowed: {', '.join(sorted(_TOP))})")
    for key in ("duration", "step"):
        if key not in data:
            raise _err(where, f"'{key}' is missing")
    step = _number(where, "step", data["step"], positive=True)
    speed = _profile(where, "speed", data.get("speed"), 11.1111, "linear")
    road = _params(where, "road", _table(where, data, "road"))
    if road.get("profile_file"):
        pf = Path(road["profile_file"])
        road["profile_file"] = str(pf if pf.is_absolute() else (path.parent / pf).resolve())
    if data["duration"] == "profile":
        duration = _whole_profile_duration(where, road, speed, step)
    else:
        duration = _number(where, "duration", data["duration"], positive=True)
    est_step = _number(where, "estimator_step", data.get("estimator_step", step), positive=True)
    every = round(est_step / step)
    if every < 1 or abs(every * step - est_step) > 1e-9 * est_step:
        raise _err(where, f"'estimator_step' = {est_step} s is not a whole number of 'step' = {step} s")
    if data["duration"] == "profile":  # the last whole estimator step before the profile's end
        duration = math.floor(duration / est_step + 1e-9) * est_step
    if est_step > duration:
        raise _err(where, f"'estimator_step' = {est_step} s is longer than 'duration' = {duration} s")
    n = round(duration / est_step)
    if abs(n * est_step - duration) > 1e-9 * duration:
        name = "'estimator_step'" if "estimator_step" in data else "'step'"
        raise _err(where, f"'duration' = {duration} s is not a whole number of {name} = {est_step} s")
    system = data.get("system", "auto")
    if system not in _SYSTEMS:
        raise _err(where, f"'system' must be one of {', '.join(_SYSTEMS)}, got {system!r}")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise _err(where, "'description' must be a string")

    if "road_class" in road:
        c = road["road_class"]
        if isinstance(c, str):
            if len(c) != 1 or c.upper() not in _CLASSES:
                raise _err(where, f"'road.road_class' must be \"A\"..\"H\" or 1..8, got {c!r}")
            road["road_class"] = _CLASSES.index(c.upper()) + 1

    noise = _table(where, data, "noise")
    if unknown := set(noise) - set(_NOISE):
        raise _err(where, f"unknown key 'noise.{sorted(unknown)[0]}' (allowed: {', '.join(_NOISE)})")
    for k, v in noise.items():
        if k == "seed":
            if isinstance(v, bool) or not isinstance(v, int):
                raise _err(where, f"'noise.seed' must be an integer, got {v!r}")
        else:
            _number(where, f"noise.{k}", v)

    output = _table(where, data, "output")
    if unknown := set(output) - _OUTPUT:
        raise _err(where, f"unknown key 'output.{sorted(unknown)[0]}' (allowed: {', '.join(sorted(_OUTPUT))})")
    record = output.get("record", [])
    if not isinstance(record, list) or not all(isinstance(r, str) and "." in r for r in record):
        raise _err(where, "'output.record' must be a list of \"instance.variable\" names")
    plots = output.get("plots", True)
    if not isinstance(plots, bool):
        raise _err(where, "'output.plots' must be true or false")

    return Scenario(
        name=path.stem, path=path, description=description, duration=duration, step=step, system=system,
        estimator_every=every,
        speed=speed,
        sprung_mass=_profile(where, "sprung_mass", data.get("sprung_mass"), 410.0, "step"),
        road=road, plant=_params(where, "plant", _table(where, data, "plant")),
        estimator=_params(where, "estimator", _table(where, data, "estimator")),
        noise=dict(noise), record=list(record), plots=plots)

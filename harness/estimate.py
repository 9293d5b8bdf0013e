"""``python -m suspension_estimation.harness estimate LOG --out DIR``: the estimator FMU over a
user's own log.

The log is a CSV file or an ASAM MDF file (``.mf4``, ``.mdf``; read with asammdf) holding a time
(s) and the channels ``acc_sprung`` (m/s2), ``acc_unsprung`` (m/s2), ``susp_deflection`` (m) and
``vehicle_speed`` (m/s). Other names: ``--map acc_sprung=COLUMN``. Other units: in a CSV header as
``name [unit]`` (e.g. ``defl [mm]``), an MDF channel's own unit, or ``--unit
susp_deflection=mm`` (which wins); the units read are in ``UNITS``. An MDF file's channels are
put on the time base of its fastest one by linear interpolation.

The time base must increase. Steps that vary by more than ``JITTER`` of their median are
resampled onto the median step by linear interpolation (with a warning); the estimator takes
steps of at most 15 ms (``MAX_STEP``), so a log slower than about 67 Hz is refused. Row k of
the log feeds the step that ends at its time, the speed the step that starts there (as the
harness wires the plant and the road to the estimator). A CSV log is read within the limits of
measured profiles (plant/profile_formats.py: MAX_LINE, MAX_POINTS, MAX_OTHER_LINES).

Written to DIR, all at the end (a failure leaves DIR as it was): ``estimates.csv``, ``iri.csv``
(the IRI of the estimated profile per segment of distance, plant/iri.py) and ``report.png``.
Every problem with the inputs raises ``LogError`` with a one-line message.
"""
from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import sys
import textwrap
import tomllib
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..plant.iri import DX, SEGMENT_RANGE, segment_iri
from ..plant.profile_formats import MAX_OTHER_LINES, MAX_POINTS, text_lines
from ..suspension_fmi.contract import MAX_STEP
from .cosim import CoSimulation, SimulationError, System, model_variables, write_csv
from .runner import DIST

MEASURED = ("acc_sprung", "acc_unsprung", "susp_deflection")
CHANNELS = (*MEASURED, "vehicle_speed")
_ACC = {"m/s2": 1.0, "g": 9.80665}
# unit (lower case, spaces and '^' dropped, '²' as 2) -> factor to SI, per channel
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6},
    "acc_sprung": _ACC,
    "acc_unsprung": _ACC,
    "susp_deflection": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6},
    "vehicle_speed": {"m/s": 1.0, "km/h": 1 / 3.6, "kph": 1 / 3.6, "mph": 0.44704},
}
JITTER = 0.01  # steps within this fraction of their median count as constant
LONG_LOG = 10.0  # s of data above which a progress bar is shown
ESTIMATOR = "SuspensionEstimator"
OUTPUTS = ("road_height_est", "road_height_std", "sprung_mass_est", "mass_std",
           "road_class_est", "status")


class LogError(ValueError):
    """A log, a vehicle file or an option that cannot be used (one-line message)."""


@dataclass
class Log:
    """A log on a constant time base: ``time`` (s), ``step`` (s), ``channels`` in SI units
    (m/s2, m, m/s), ``notes``: warnings about what was done to it (resampling)."""

    path: Path
    time: np.ndarray
    step: float
    channels: dict[str, np.ndarray]
    notes: list[str] = field(default_factory=list)


def parse_pairs(pairs: list[str] | None, option: str, keys: tuple[str, ...]) -> dict[str, str]:
    """The values of a repeated ``--map`` or ``--unit`` (``"acc_sprung=a_body"``, or several pairs
    separated by commas: ``"acc_sprung=a_body,vehicle_speed=v"``) as a dict; a key not in ``keys``
    or a pair without '=' is refused."""
    out = {}
    # a comma separates pairs only before another CHANNEL=: a column name may hold commas
    next_key = re.compile(r",\s*(?=(?:" + "|".join(map(re.escape, keys)) + r")\s*=)")
    for pair in (p for value in pairs or () for p in next_key.split(value)):
        key, eq, value = pair.partition("=")
        if not eq or not key.strip() or not value.strip():
            raise LogError(f"{option} {pair!r}: expected CHANNEL=VALUE")
        if key.strip() not in keys:
            raise LogError(f"{option} {pair!r}: {key.strip()!r} is not one of {', '.join(keys)}")
        out[key.strip()] = value.strip()
    return out


def unit_factor(channel: str, unit: str, where: str) -> float:
    """Factor from ``unit`` to the SI unit of ``channel`` ('' = SI); ``where`` says whence the unit came."""
    key = unit.strip().lower().replace(" ", "").replace("^", "").replace("²", "2")
    if not key:
        return 1.0
    if key not in UNITS[channel]:
        raise LogError(f"{channel}: unit {unit!r} ({where}) is not one of {', '.join(UNITS[channel])}")
    return UNITS[channel][key]


def _one_line(e: Exception) -> str:
    return " ".join(str(e).split())[:300]


def _columns_text(names: list[str], limit: int = 30) -> str:
    more = f" ... ({len(names) - limit} more)" if len(names) > limit else ""
    return ", ".join(repr(n) for n in names[:limit]) + more


def _header(text: str) -> tuple[str, str]:
    """(name, unit) of a header cell ``name [unit]``; unit '' without brackets."""
    text = text.strip().strip('"').strip()
    m = re.fullmatch(r"(.*?)\s*\[([^\]]*)\]", text)
    return (m.group(1), m.group(2)) if m else (text, "")


def read_csv_log(path: Path, names: dict[str, str], units: dict[str, str]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(time s, {channel: values in SI}) of a CSV log: '#' comments and blank lines skipped, one
    header line of names (``name [unit]``), then rows separated by ',', ';' or tabs (as the
    header). An empty or 'nan' measurement is kept as NaN (the estimator leaves it out);
    every other cell of the columns used must be a finite number."""
    wanted = {"time": names.get("time", "time"), **{c: names.get(c, c) for c in CHANNELS}}
    cols: dict[str, int] = {}
    factors: dict[str, float] = {}
    data = {k: array("d") for k in wanted}
    sep = b","
    width = other = 0
    previous = (-math.inf, 0)
    with open(path, "rb") as f:
        for lineno, line in text_lines(path, f, error=LogError, label=""):
            if not line.strip() or line.lstrip().startswith(b"#"):
                other += 1
                if other > MAX_OTHER_LINES:
                    raise LogError(f"{path}: more than {MAX_OTHER_LINES} comment or blank lines")
                continue
            if not cols:  # the header
                text = line.decode("utf-8-sig", errors="replace")
                sep = next((s for s in (",", ";", "\t") if s in text), ",")
                cells = text.split(sep)
                heads = [_header(c) for c in cells]
                found = [c.strip().strip('"') for c in cells]
                for key, want in wanted.items():
                    j = next((j for j, (n, _) in enumerate(heads) if n == want), None)
                    if j is None:
                        j = next((j for j, c in enumerate(found) if c == want), None)
                    if j is None:
                        how = f"another: --map {key}=COLUMN" if key not in names else f"--map {key}={want}"
                        raise LogError(f"{path}: no column {want!r} for {key} ({how}); columns found: "
                                       f"{_columns_text(found)}")
                    cols[key] = j
                    unit, where = (units[key], "--unit") if key in units else (heads[j][1], f"column {found[j]!r}")
                    factors[key] = unit_factor(key, unit, where)
                width, sep = len(cells), sep.encode()
                continue
            if len(data["time"]) == MAX_POINTS:
                raise LogError(f"{path} line {lineno}: more than {MAX_POINTS} rows (MAX_POINTS of "
                               "plant/profile_formats.py): cut the log into parts")
            cells = line.split(sep)
            if len(cells) != width:
                raise LogError(f"{path} line {lineno}: {len(cells)} fields, the header has {width}")
            for key, j in cols.items():
                cell = cells[j].strip().strip(b'"')
                try:
                    value = float(cell) if cell or key not in MEASURED else math.nan
                except ValueError:
                    value = None
                if value is None or not (math.isfinite(value) or key in MEASURED and math.isnan(value)):
                    raise LogError(f"{path} line {lineno}: {cell.decode(errors='replace')[:30]!r} in column "
                                   f"{wanted[key]!r} is not {'a number' if key in MEASURED else 'a finite number'}")
                data[key].append(value)
            t = data["time"][-1]
            if t <= previous[0]:
                raise LogError(f"{path} line {lineno}: time {t:.9g} does not increase (line {previous[1]}: "
                               f"{previous[0]:.9g})")
            previous = (t, lineno)
    if not cols:
        raise LogError(f"{path} holds no header line (names of the columns)")
    out = {k: factors[k] * np.frombuffer(v) for k, v in data.items()}
    return out.pop("time"), out


def read_mdf_log(path: Path, names: dict[str, str], units: dict[str, str]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(time s, {channel: values in SI}) of an ASAM MDF file: each channel by name (the first
    occurrence), with its own unit unless ``units`` names one, all put on the time stamps of the
    fastest channel (linear interpolation) over the span they share."""
    if "time" in names or "time" in units:
        raise LogError("--map time and --unit time do not apply to an MDF file: its channels carry their "
                       "own time stamps (s)")
    try:
        from asammdf import MDF
    except ImportError:
        raise LogError("reading an MDF file needs the package asammdf (pip install asammdf)") from None
    try:
        mdf = MDF(path)
    except Exception as e:  # noqa: BLE001 - whatever a damaged file makes asammdf raise
        raise LogError(f"{path}: not a readable MDF file ({type(e).__name__}: {_one_line(e)})") from None
    signals = {}
    try:
        for key in CHANNELS:
            want = names.get(key, key)
            where = mdf.whereis(want)
            if not where:
                how = f"another: --map {key}=CHANNEL" if key not in names else f"--map {key}={want}"
                found = [n for n in mdf.channels_db if n not in ("time", "t")]
                raise LogError(f"{path}: no channel {want!r} for {key} ({how}); channels found: {_columns_text(found)}")
            group, index = where[0]
            if mdf.groups[group].channel_group.cycles_nr > MAX_POINTS:
                raise LogError(f"{path}: channel {want!r} holds more than {MAX_POINTS} samples (MAX_POINTS of "
                               "plant/profile_formats.py): cut the log into parts")
            sig = mdf.get(want, group, index)
            unit, whence = (units[key], "--unit") if key in units else (sig.unit or "", f"channel {want!r}")
            t, x = np.asarray(sig.timestamps, float), np.asarray(sig.samples, float)
            if len(t) < 2:
                raise LogError(f"{path}: channel {want!r} holds {len(t)} samples; at least 2 are needed")
            if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
                i = int(np.flatnonzero(~np.isfinite(t[1:]) | (np.diff(t) <= 0))[0]) + 1
                raise LogError(f"{path}: channel {want!r}: time stamp {i} ({t[i]:.9g} s) does not increase "
                               f"(previous {t[i - 1]:.9g} s)")
            signals[key] = (t, x * unit_factor(key, unit, whence))
    except LogError:
        raise
    except Exception as e:  # noqa: BLE001
        raise LogError(f"{path}: cannot read the channels ({type(e).__name__}: {_one_line(e)})") from None
    finally:
        mdf.close()
    start, end = max(t[0] for t, _ in signals.values()), min(t[-1] for t, _ in signals.values())
    base = min(signals.values(), key=lambda s: np.median(np.diff(s[0])))[0]
    base = base[(base >= start) & (base <= end)]
    if len(base) < 2:
        raise LogError(f"{path}: the channels share no stretch of time (each covers its own)")
    return base, {k: np.interp(base, t, x) for k, (t, x) in signals.items()}


def on_constant_step(path: Path, t: np.ndarray, channels: dict[str, np.ndarray]) -> Log:
    """The log on a constant step: as it is if its steps are within ``JITTER`` of their median,
    else resampled onto the median step by linear interpolation (noted). Refused if that step is
    longer than the estimator takes."""
    if len(t) < 2:
        raise LogError(f"{path} holds {len(t)} samples; at least 2 are needed")
    steps = np.diff(t)
    h = float(np.median(steps))
    longest = MAX_STEP[ESTIMATOR]
    if h > longest * (1 + 1e-9):
        raise LogError(f"{path} is sampled every {1e3 * h:.4g} ms ({1 / h:.4g} Hz): the estimator takes steps of "
                       f"at most {1e3 * longest:g} ms, a log of at least {1 / longest:.1f} Hz")
    if np.max(np.abs(steps - h)) <= JITTER * h:
        n = len(t)
        h = float(t[-1] - t[0]) / (n - 1)
        return Log(path, t[0] + h * np.arange(n), h, channels)
    n = int((t[-1] - t[0]) / h * (1 + 1e-12)) + 1
    if n > MAX_POINTS:
        raise LogError(f"{path}: resampled onto its median step of {h:.4g} s it would hold {n} samples, more "
                       f"than {MAX_POINTS}")
    grid = t[0] + h * np.arange(n)
    note = (f"{path}: the time steps vary from {1e3 * steps.min():.4g} to {1e3 * steps.max():.4g} ms: resampled "
            f"onto their median step of {1e3 * h:.4g} ms by linear interpolation")
    return Log(path, grid, h, {k: np.interp(grid, t, x) for k, x in channels.items()}, [note])


def read_log(path: str | Path, names: dict[str, str] | None = None, units: dict[str, str] | None = None) -> Log:
    """A CSV or MDF log (see the module doc) on a constant step, its channels in SI units."""
    path = Path(path)
    names, units = names or {}, units or {}
    if not path.is_file():
        raise LogError(f"{path} does not exist" if not path.exists() else f"{path} is not a file")
    with open(path, "rb") as f:
        first = f.read(4096)
    if first.startswith((b"MDF", b"UnFinMF")) or path.suffix.lower() in (".mf4", ".mdf"):
        t, channels = read_mdf_log(path, names, units)
    elif b"\0" in first:
        raise LogError(f"{path} holds NUL bytes in its first {len(first)} bytes: binary (or UTF-16) data, not a "
                       "CSV log")
    else:
        t, channels = read_csv_log(path, names, units)
    return on_constant_step(path, t, channels)


def read_vehicle(path: str | Path, dist: Path) -> dict[str, object]:
    """The estimator's parameters from a TOML file of ``name = value`` (the parameters of
    SuspensionEstimator.fmu in ``dist``): an unknown name or a value of the wrong type is refused;
    the FMU itself refuses values out of range when it initializes."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            given = tomllib.load(f)
    except FileNotFoundError:
        raise LogError(f"vehicle file {path} does not exist") from None
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise LogError(f"vehicle file {path}: {e}") from None
    fmu = Path(dist) / f"{ESTIMATOR}.fmu"
    variables = model_variables(System(components={ESTIMATOR: fmu}))[ESTIMATOR]
    params = {n: v for n, v in variables.items() if v.causality == "parameter"}
    for key, value in given.items():
        var = params.get(key)
        if var is None:
            raise LogError(f"vehicle file {path}: {key!r} is not a parameter of {ESTIMATOR} "
                           f"(parameters: {', '.join(params)})")
        ok = {"Real": isinstance(value, (int, float)) and not isinstance(value, bool),
              "Integer": isinstance(value, int) and not isinstance(value, bool),
              "Boolean": isinstance(value, bool), "String": isinstance(value, str)}.get(var.type, False)
        if not ok:
            raise LogError(f"vehicle file {path}: {key} must be a {var.type}"
                           + (f" in {var.unit}" if var.unit else "") + f", got {value!r}")
    return given


def run_estimator(log: Log, parameters: dict[str, object], dist: Path,
                  progress: Callable[[int], None] | None = None) -> np.ndarray:
    """Run SuspensionEstimator.fmu in ``dist`` over the log with ``parameters``; the record of
    ``OUTPUTS`` (structured array, ``time`` first, one row per sample of the log).
    ``SimulationError`` if the FMU refuses (its parameters at initialization, or a step)."""
    system = System(components={ESTIMATOR: Path(dist) / f"{ESTIMATOR}.fmu"})
    ch = log.channels
    # step k, from time k to k + 1: the measurements at its end, the speed at its start
    inputs = {f"{ESTIMATOR}.{c}": ch[c][1:] for c in MEASURED}
    inputs[f"{ESTIMATOR}.vehicle_speed"] = ch["vehicle_speed"][:-1]
    t0, n = float(log.time[0]), len(log.time) - 1
    with CoSimulation(system, parameters={f"{ESTIMATOR}.{k}": v for k, v in parameters.items()},
                      inputs=inputs, record=[f"{ESTIMATOR}.{v}" for v in OUTPUTS], start_time=t0) as sim:
        result = sim.run(t0 + n * log.step, log.step, progress=progress)
    result.dtype.names = ["time", *OUTPUTS]
    result["time"] = log.time
    return result


def distance(log: Log) -> np.ndarray:
    """Distance travelled (m) at each sample: the speed held over each step, as the FMUs count it."""
    return np.concatenate(([0.0], np.cumsum(log.channels["vehicle_speed"][:-1] * log.step)))


def iri_table(dist: np.ndarray, height: np.ndarray, segment: float = 100.0) -> np.ndarray:
    """Rows (start m, end m, IRI m/km) of every complete segment of ``segment`` m of the profile
    ``height`` (m) against ``dist`` (m, non-decreasing; where it stands still the first sample
    counts, as plant/iri.py's IRIMeter takes it), resampled linearly every DX m."""
    keep = np.concatenate(([True], np.diff(dist) > 0))
    d, z = dist[keep] - dist[0], height[keep]
    grid = np.arange(int(d[-1] / DX + 1e-9) + 1) * DX
    try:
        iri = segment_iri(np.interp(grid, d, z), DX, segment)
    except ValueError:  # less road than the IRI's start needs
        iri = np.empty(0)
    start = segment * np.arange(len(iri))
    return np.column_stack([start, start + segment, iri])


def plot_report(path: Path, est: np.ndarray, dist: np.ndarray, iri: np.ndarray, title: str) -> Path:
    """``path`` (PNG): against distance, the road estimate with its ±2σ band, the IRI per segment,
    the sprung mass with its ±2σ band and the status."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(11, 10), sharex=True, gridspec_kw={"height_ratios": [3, 2, 2, 1]})
    fig.suptitle(title)
    road = "road_height_smooth" if "road_height_smooth" in est.dtype.names else "road_height_est"
    z, s = 1e3 * est[road], 1e3 * est[road.replace("_est", "") + "_std"]
    ax[0].fill_between(dist, z - 2 * s, z + 2 * s, color="C0", alpha=0.25, lw=0, label="±2σ")
    ax[0].plot(dist, z, "C0", lw=0.8, label=road)
    ax[0].set_ylabel("road height (mm)")
    ax[0].legend(loc="upper right")
    if len(iri):
        bars = ax[1].bar(iri[:, 0], iri[:, 2], width=iri[:, 1] - iri[:, 0], align="edge", color="C1",
                         edgecolor="white")
        ax[1].bar_label(bars, fmt="%.2f", label_type="center")
    else:
        ax[1].text(0.5, 0.5, "no complete segment", transform=ax[1].transAxes, ha="center")
    ax[1].set_ylabel("IRI (m/km)")
    m, ms = est["sprung_mass_est"], est["mass_std"]
    late = est["time"] >= est["time"][0] + 1.0  # the first second's std is the prior (m_s_nominal)
    ax[2].fill_between(dist, m - 2 * ms, m + 2 * ms, where=late, color="C2", alpha=0.25, lw=0, label="±2σ")
    ax[2].plot(dist, m, "C2", lw=0.8, label="sprung_mass_est")
    ref = m[late] if late.any() else m
    pad = max(0.02 * float(np.median(ref)), 2 * float(np.median(ms[late])) if late.any() else 0.0)
    ax[2].set_ylim(float(ref.min()) - pad, float(ref.max()) + pad)
    ax[2].set_ylabel("sprung mass (kg)")
    ax[2].legend(loc="upper right")
    ax[3].plot(dist, est["status"], "C3", drawstyle="steps-post", lw=0.8)
    ax[3].set_yticks([0, 1, 2])
    ax[3].set_ylabel("status")
    ax[3].set_xlabel("distance (m)")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _replace_into(tmp: Path, out: Path) -> None:
    """Move what ``tmp`` holds to ``out``: a rename if ``out`` does not exist, else file by file."""
    if not out.exists():
        os.rename(tmp, out)
        return
    for f in tmp.iterdir():
        os.replace(f, out / f.name)
    tmp.rmdir()


def estimate(log_path: str | Path, out: str | Path, names: dict[str, str] | None = None,
             units: dict[str, str] | None = None, vehicle: str | Path | None = None, segment: float = 100.0,
             dist: str | Path = DIST, quiet: bool = False, smooth: bool = False) -> list[str]:
    """Run the estimator over a log and write ``out``/estimates.csv, iri.csv, report.png. With
    ``smooth``, estimates.csv also holds the offline RTS smoother's road and its std
    (``road_height_smooth``, ``road_height_smooth_std``: harness.smoothing.smooth_default), and the
    IRI and the report are of the smoothed profile.

    Prints warnings (resampling) to stderr; returns the summary paragraph's lines. ``LogError``
    for every problem with the inputs, before anything is written.
    """
    from tqdm import tqdm

    out, dist = Path(out), Path(dist)
    if out.exists() and not out.is_dir():
        raise LogError(f"--out {out} is a file, not a folder")
    if not (math.isfinite(segment) and SEGMENT_RANGE[0] <= segment <= SEGMENT_RANGE[1]):
        raise LogError(f"--segment {segment:g} m is outside [{SEGMENT_RANGE[0]:g}, {SEGMENT_RANGE[1]:g}] m")
    parameters = read_vehicle(vehicle, dist) if vehicle is not None else {}
    if smooth and int(parameters.get("road_estimator", 2)) != 2:
        raise LogError("--smooth smooths the default road estimator (road_estimator 2) only, not "
                       f"road_estimator {parameters['road_estimator']}")
    log = read_log(log_path, names, units)
    for note in log.notes:
        print(f"warning: {note}", file=sys.stderr)
    duration = float(log.time[-1] - log.time[0])
    n = len(log.time) - 1
    hide = quiet or duration <= LONG_LOG or None  # None: shown on a terminal only
    try:
        with tqdm(total=n, unit="step", desc="estimate", disable=hide, leave=False) as bar:
            est = run_estimator(log, parameters, dist, progress=bar.update)
    except SimulationError as e:  # the FMU's logged reason, as one line
        errors = [m for status, m in e.messages if status in ("error", "fatal", "discard")]
        reason = " ".join((errors[-1] if errors else str(e)).split())
        if e.result is None or len(e.result) == 0:  # refused at initialization: its parameters
            reason = reason.removeprefix(f"{ESTIMATOR} refuses its parameters: ")
            raise LogError(f"{ESTIMATOR}.fmu refuses the vehicle" + (f" of {vehicle}" if vehicle else "")
                           + f": {reason}") from None
        raise LogError(f"{log.path}: {ESTIMATOR}.fmu refused the step at t = {e.time:.6g} s: {reason}") from None
    d = distance(log)
    extra = ("road_height_smooth", "road_height_smooth_std") if smooth else ()
    table = np.empty(len(est), dtype=[("time", float), ("distance", float)]
                     + [(k, est.dtype[k]) for k in OUTPUTS] + [(k, float) for k in extra])
    table["distance"] = d
    for k in ("time", *OUTPUTS):
        table[k] = est[k]
    if smooth:
        from .smoothing import smooth_default

        ch = log.channels  # as the FMU took them: step k's measurements at its end, its speed at its start
        sm = smooth_default(*(ch[c][1:] for c in MEASURED), ch["vehicle_speed"][:-1], parameters, log.step)
        table["road_height_smooth"] = np.r_[est["road_height_est"][0], sm["road_height_est"]]
        table["road_height_smooth_std"] = np.r_[est["road_height_std"][0], sm["road_height_std"]]
    # the IRI of the profile as a profiler reports it (docs/real-sensors.md), or of the smoothed one
    iri = iri_table(d, table["road_height_smooth" if smooth else "road_height_est"], segment)
    rows = np.empty(len(iri), dtype=[("start_m", float), ("end_m", float), ("iri_m_per_km", float)])
    for j, k in enumerate(rows.dtype.names):
        rows[k] = iri[:, j]
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"  # beside DIR: the rename stays on its file system
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        write_csv(tmp / "estimates.csv", table)
        write_csv(tmp / "iri.csv", rows)
        plot_report(tmp / "report.png", table, d, iri, f"{log.path.name}: {ESTIMATOR}.fmu")
        _replace_into(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    bad = int(np.count_nonzero(est["status"]))
    mean_iri = (f"mean IRI {iri[:, 2].mean():.2f} m/km over {len(iri)} segment{'s' * (len(iri) != 1)} of "
                f"{segment:g} m" if len(iri) else f"no complete IRI segment of {segment:g} m")
    text = (f"{log.path.name}: {duration:.6g} s and {d[-1]:.1f} m of log at {1 / log.step:.6g} Hz "
            f"({1e3 * log.step:.4g} ms steps, {len(log.time)} samples); {mean_iri}; sprung mass "
            f"{est['sprung_mass_est'][-1]:.1f} kg ± {est['mass_std'][-1]:.1f} kg (1σ) at the end"
            + ("" if parameters else " (the FMU's default vehicle: no --vehicle)")
            + f"; {bad} of {len(est)} samples had status != 0. Wrote estimates.csv, iri.csv and report.png "
            f"to {out}.")
    return textwrap.wrap(text, 100)


def add_parser(sub: argparse._SubParsersAction, dist: Path = DIST) -> None:
    """The ``estimate`` subcommand of harness/cli.py."""
    p = sub.add_parser("estimate", formatter_class=argparse.RawDescriptionHelpFormatter,
                       help="run the estimator FMU over a log of your own (CSV or MDF4)",
                       description="Run SuspensionEstimator.fmu over a log (CSV or ASAM MDF4) of time (s), "
                                   "acc_sprung,\nacc_unsprung (m/s2), susp_deflection (m) and vehicle_speed (m/s); "
                                   "write DIR/estimates.csv,\nDIR/iri.csv and DIR/report.png; print a summary.",
                       epilog="units: in a CSV header as 'name [unit]' (e.g. 'defl [mm]'), an MDF channel's own, "
                              "or --unit; known:\n" + "\n".join(f"  {c}: {', '.join(u)}" for c, u in UNITS.items()))
    p.add_argument("log", help="the log: a CSV file (one header line) or an MDF file (.mf4)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (written at the end, all at once)")
    p.add_argument("--map", action="append", metavar="CHANNEL=COLUMN",
                   help="the column (or MDF channel) of a channel, e.g. acc_sprung=a_body (repeatable, or "
                        "pairs separated by commas)")
    p.add_argument("--unit", action="append", metavar="CHANNEL=UNIT",
                   help="the unit of a channel, e.g. susp_deflection=mm, vehicle_speed=km/h, acc_sprung=g "
                        "(repeatable, or pairs separated by commas)")
    p.add_argument("--vehicle", metavar="FILE", help="TOML file of the estimator's parameters (m_s_nominal, m_u, "
                                                     "k_s, k_t, c_s, ...; docs/fmu-interface.md)")
    p.add_argument("--segment", type=float, default=100.0, help="length of the IRI segments in m (default 100)")
    p.add_argument("--dist", default=str(dist), help="folder with the FMUs (default dist/)")
    p.add_argument("--smooth", action="store_true",
                   help="also the offline RTS smoother's road and its std (the default estimator only); "
                        "the IRI and the report of the smoothed profile")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run ``estimate`` with parsed arguments; print the summary."""
    keys = ("time", *CHANNELS)
    lines = estimate(args.log, args.out, parse_pairs(args.map, "--map", keys), parse_pairs(args.unit, "--unit", keys),
                     args.vehicle, args.segment, args.dist, args.quiet, args.smooth)
    print("\n".join(lines))
    return 0

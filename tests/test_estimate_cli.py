"""``python -m suspension_estimation.harness estimate LOG --out DIR`` (harness/estimate.py): a log of a
quarter car on an ISO class C road, with a stop, through the built estimator FMU; CSV and MDF4,
mapped names and units; every refusal one line, exit 1, DIR untouched."""
from __future__ import annotations

import gc
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from suspension_estimation.harness import metrics
from suspension_estimation.harness.cli import main
from suspension_estimation.harness.cosim import read_csv
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.iri import DX, segment_iri
from suspension_estimation.plant.quarter_car import QuarterCar
from suspension_estimation.plant.road import SyntheticRoad
from suspension_estimation.plant.vehicle import DEFAULT_VEHICLE

ROOT = Path(__file__).resolve().parents[1]
SPEED = 50 / 3.6  # m/s
STOP = (8.0, 11.0)  # s: standing still in between (1 s to brake before, 1 s to pull away after)
SEGMENT = 50.0  # m


def drive(h: float, duration: float = 20.0, seed: int = 5) -> dict[str, np.ndarray]:
    """The log of a quarter car (the contract's vehicle, 410 kg, its sensor noise) on an ISO C road:
    the speed at each row held over the step from it, the road at a row's distance under the
    wheel over the step that ends there (as the harness wires ISORoad to QuarterCar). Also the true
    road at each row (``road``) and the distance (``distance``)."""
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=seed)
    n = int(round(duration / h)) + 1
    t = h * np.arange(n)
    speed = SPEED * np.interp(t, [0, STOP[0] - 1, STOP[0], STOP[1], STOP[1] + 1, duration], [1, 1, 0, 0, 1, 1])
    dist = np.concatenate(([0.0], np.cumsum(speed[:-1] * h)))
    z = np.array([road.height(s) for s in dist])
    car = QuarterCar(DEFAULT_VEHICLE, noise_seed=seed)
    car.settle(z[0])
    meas = np.zeros((n, 3))
    for k in range(1, n):
        car.step(z[k], h)
        meas[k] = car.measured
    return {"time": t, "acc_sprung": meas[:, 0], "acc_unsprung": meas[:, 1], "susp_deflection": meas[:, 2],
            "vehicle_speed": speed, "road": z, "distance": dist}


def write_log(path: Path, log: dict[str, np.ndarray], names: dict[str, str] | None = None,
              scale: dict[str, float] | None = None) -> Path:
    """The log as CSV, columns renamed by ``names`` and divided by ``scale``."""
    names, scale = names or {}, scale or {}
    keys = ("time", "acc_sprung", "acc_unsprung", "susp_deflection", "vehicle_speed")
    cols = np.column_stack([log[k] / scale.get(k, 1.0) for k in keys])
    header = ",".join(names.get(k, k) for k in keys)
    np.savetxt(path, cols, delimiter=",", header=header, comments="", fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> dict[float, dict[str, np.ndarray]]:
    return {h: drive(h) for h in (0.001, 0.005)}


def estimate(capsys, dist: Path, log: Path, out: Path, *args: str) -> tuple[int, str, str]:
    """``main(["estimate", ...])`` in this process: (exit status, stdout, stderr)."""
    code = main(["estimate", str(log), "--out", str(out), "--dist", str(dist), "--segment", str(SEGMENT), *args])
    captured = capsys.readouterr()
    return code, " ".join(captured.out.split()), captured.err


@pytest.fixture(scope="module")
def runs(dist, logs, tmp_path_factory) -> dict[float, tuple[Path, str]]:
    """Each log through the CLI as CSV with the default names and units: {step: (DIR, stdout)}."""
    out = {}
    for h, log in logs.items():
        folder = tmp_path_factory.mktemp(f"run{h}")
        with pytest.MonkeyPatch.context() as mp:
            lines = []
            mp.setattr("builtins.print", lambda *a, **k: lines.append(" ".join(map(str, a))))
            code = main(["estimate", str(write_log(folder / "log.csv", log)), "--out", str(folder / "out"),
                         "--dist", str(dist), "--segment", str(SEGMENT)])
        assert code == 0, lines
        out[h] = (folder / "out", " ".join(" ".join(lines).split()))  # the paragraph unwrapped
    return out


def true_iri(seed: int, length: float) -> np.ndarray:
    road = SyntheticRoad(iso8608.class_psd_n0(3), seed=seed)
    grid = DX * np.arange(int(length / DX) + 1)
    return segment_iri(np.array([road.height(s) for s in grid]), DX, SEGMENT)


@pytest.mark.parametrize("h", [0.001, 0.005])
def test_estimates_road_and_iri_by_distance(runs, logs, h):
    out, text = runs[h]
    log = logs[h]
    assert sorted(p.name for p in out.iterdir()) == ["estimates.csv", "iri.csv", "report.png"]
    est, iri = read_csv(out / "estimates.csv"), read_csv(out / "iri.csv")
    assert est.dtype.names == ("time", "distance", "road_height_est", "road_height_std", "sprung_mass_est",
                               "mass_std", "road_class_est", "status")
    assert iri.dtype.names == ("start_m", "end_m", "iri_m_per_km")
    assert np.allclose(est["time"], log["time"], atol=1e-9) and np.allclose(est["distance"], log["distance"])
    assert (out / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    # the road, scored as the project scores it: against what road_height_est estimates, the
    # profile of the true road at the distance travelled (metrics.reference_profile). Seeds 1, 2,
    # 3, 5 at 1 and 5 ms: HP error 1.40-1.86 %, raw 1.08-3.92 %, 2-sigma coverage 0.955-1.000
    t = est["time"]
    s = metrics.road_scores(t, est["road_height_est"], log["road"], est["road_height_std"],
                            warmup=metrics.warmup_for(t), distance=log["distance"])
    assert s["err_std_hp_pct"] < 4 and s["err_std_raw_pct"] < 8 and s["coverage_2sigma"] > 0.9, s
    assert np.all(est["status"] == 0)
    assert abs(est["sprung_mass_est"][-1] - 410) < 0.05 * 410

    # IRI by distance: the stop (distance still) adds no segment
    stopped = (t > STOP[0] + 1e-9) & (t < STOP[1] - 1e-9)
    assert np.ptp(est["distance"][stopped]) == 0
    n = int(log["distance"][-1] // SEGMENT)
    assert len(iri) == n == 4
    assert np.allclose(iri["start_m"], SEGMENT * np.arange(n)) and np.allclose(iri["end_m"] - iri["start_m"], SEGMENT)
    truth = true_iri(5, log["distance"][-1])
    assert np.all(np.abs(iri["iri_m_per_km"] / truth - 1) < 0.15), (iri["iri_m_per_km"], truth)

    # the summary: duration, distance, rate, mean IRI, final mass and its std, status count
    assert "20 s and 222.2 m of log" in text and f"{1 / h:g} Hz" in text
    assert f"mean IRI {iri['iri_m_per_km'].mean():.2f} m/km over 4 segments of 50 m" in text
    assert f"{est['sprung_mass_est'][-1]:.1f} kg ± {est['mass_std'][-1]:.1f} kg" in text
    assert f"0 of {len(est)} samples had status != 0" in text


def same_estimates(a: Path, b: Path) -> None:
    x, y = read_csv(a / "estimates.csv"), read_csv(b / "estimates.csv")
    assert x.dtype.names == y.dtype.names and len(x) == len(y)
    for k, tol in (("time", 1e-9), ("distance", 1e-6), ("road_height_est", 1e-7), ("road_height_std", 1e-7),
                   ("sprung_mass_est", 1e-3), ("mass_std", 1e-3), ("road_class_est", 0), ("status", 0)):
        assert np.max(np.abs(x[k] - y[k])) <= tol, k
    assert np.allclose(read_csv(a / "iri.csv").tolist(), read_csv(b / "iri.csv").tolist(), rtol=1e-6)


def test_mdf4_log_gives_the_same_estimates(capsys, dist, runs, logs, tmp_path):
    from asammdf import MDF, Signal

    log = logs[0.005]
    t = log["time"]
    mdf = MDF(version="4.10")
    mdf.append([Signal(log["acc_sprung"], t, name="acc_sprung", unit="m/s^2"),
                Signal(log["acc_unsprung"], t, name="acc_unsprung", unit="m/s²"),
                Signal(1e3 * log["susp_deflection"], t, name="susp_deflection", unit="mm")], common_timebase=True)
    # the speed from another bus, at a quarter of the rate (its corners fall on its samples)
    mdf.append([Signal(3.6 * log["vehicle_speed"][::4], t[::4], name="vehicle_speed", unit="km/h")])
    mdf.save(tmp_path / "log.mf4")
    mdf.close()
    code, text, err = estimate(capsys, dist, tmp_path / "log.mf4", tmp_path / "out")
    assert code == 0 and err == "", err
    assert "log.mf4: 20 s and 222.2 m of log at 200 Hz" in text
    same_estimates(runs[0.005][0], tmp_path / "out")


def test_names_and_units_mapped_give_the_same_estimates(capsys, dist, runs, logs, tmp_path):
    names = {"time": "t [ms]", "acc_sprung": "a_body [g]", "acc_unsprung": "a_wheel", "susp_deflection": "defl [mm]",
             "vehicle_speed": "v"}
    scale = {"time": 1e-3, "acc_sprung": 9.80665, "susp_deflection": 1e-3, "vehicle_speed": 1 / 3.6}
    path = write_log(tmp_path / "log.csv", logs[0.005], names, scale)
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    (out / "estimates.csv").write_text("old")
    code, text, err = estimate(capsys, dist, path, out, "--map", "time=t,acc_sprung=a_body, susp_deflection=defl",
                               "--map", "acc_unsprung=a_wheel", "--map", "vehicle_speed=v",
                               "--unit", "vehicle_speed=km/h")
    assert code == 0 and err == "", err
    same_estimates(runs[0.005][0], out)
    assert (out / "keep.txt").read_text() == "mine"  # written into an existing DIR: the rest stays
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv", "out"]  # no temporary folder left


def test_uneven_time_steps_are_resampled_with_a_warning(capsys, dist, logs, tmp_path):
    log = {k: v[:2001] for k, v in logs[0.001].items()}
    log["time"] = log["time"] + np.r_[0, np.random.default_rng(1).uniform(-2e-4, 2e-4, 2000)]
    code, text, err = estimate(capsys, dist, write_log(tmp_path / "log.csv", log), tmp_path / "out")
    assert code == 0
    assert err.startswith("warning: ") and "linear interpolation" in err and err.count("\n") == 1, err
    t = read_csv(tmp_path / "out" / "estimates.csv")["time"]
    assert np.ptp(np.diff(t)) < 1e-12 and abs(np.median(np.diff(log["time"])) - (t[1] - t[0])) < 1e-12


def test_entry_point_in_a_process_of_its_own(dist, logs, tmp_path):
    path = write_log(tmp_path / "log.csv", logs[0.005])

    def harness(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "suspension_estimation.harness", "estimate", str(path),
                               "--dist", str(dist), *args], capture_output=True, text=True, cwd=ROOT, timeout=120)

    ok = harness("--out", str(tmp_path / "out"))
    assert ok.returncode == 0, ok.stderr
    assert "log.csv: 20 s and 222.2 m of log at 200 Hz" in ok.stdout and "samples had status != 0" in ok.stdout
    assert (tmp_path / "out" / "estimates.csv").is_file()
    bad = harness("--out", str(tmp_path / "bad"), "--map", "vehicle_speed=speed")
    assert bad.returncode == 1 and bad.stdout == ""
    assert bad.stderr.count("\n") == 1 and "no column 'speed' for vehicle_speed" in bad.stderr, bad.stderr
    assert not (tmp_path / "bad").exists()


HEADER = "time,acc_sprung,acc_unsprung,susp_deflection,vehicle_speed\n"


def _rows(logs, n: int = 400, step: int = 1) -> list[str]:
    log = logs[0.001]
    keys = ("time", "acc_sprung", "acc_unsprung", "susp_deflection", "vehicle_speed")
    return [",".join(f"{log[k][i]:.17g}" for k in keys) + "\n" for i in range(0, n, step)]


def _swap_times(rows: list[str], i: int, j: int) -> list[str]:
    a, b = rows[i].split(",", 1), rows[j].split(",", 1)
    rows[i], rows[j] = f"{b[0]},{a[1]}", f"{a[0]},{b[1]}"
    return rows


# name -> (what to write as the log, extra arguments, what the error line must say)
ERRORS = {
    "missing file": (None, [], "log.csv does not exist"),
    "binary": (lambda logs: b"\x00\x01garbage" * 100, [], "holds NUL bytes"),
    "not a number": (lambda logs: [HEADER, *_rows(logs, 3), "0.003,abc,0,0,13\n"], [],
                     "line 5: 'abc' in column 'acc_sprung' is not a number"),
    "line too long": (lambda logs: [HEADER, "1" * 70_000 + "\n"], [], "line 2 is longer than 65536 characters"),
    "missing column": (lambda logs: [HEADER.replace(",vehicle_speed", ",speed"), *_rows(logs)], [],
                       "no column 'vehicle_speed' for vehicle_speed (another: --map vehicle_speed=COLUMN); columns found: "
                       "'time', 'acc_sprung', 'acc_unsprung', 'susp_deflection', 'speed'"),
    "time goes back": (lambda logs: [HEADER, *_swap_times(_rows(logs), 100, 101)], [],
                       "line 103: time 0.1 does not increase (line 102: 0.101)"),
    "time repeated": (lambda logs: [HEADER, *_rows(logs)[:50], *_rows(logs)[49:]], [],
                      "line 52: time 0.049 does not increase (line 51: 0.049)"),
    "unit in header": (lambda logs: [HEADER.replace("susp_deflection", "susp_deflection [furlong]"), *_rows(logs)], [],
                       "susp_deflection: unit 'furlong' (column 'susp_deflection [furlong]') is not one of m, cm, mm"),
    "unit option": (lambda logs: [HEADER, *_rows(logs)], ["--unit", "vehicle_speed=knots"],
                    "vehicle_speed: unit 'knots' (--unit) is not one of m/s, km/h"),
    "too slow": (lambda logs: [HEADER, *_rows(logs, 1000, 20)], [],
                 "sampled every 20 ms (50 Hz): the estimator takes steps of at most 15 ms"),
    "unknown vehicle key": (lambda logs: [HEADER, *_rows(logs)], ["--vehicle", "m_s = 410.0\n"],
                            "vehicle.toml: 'm_s' is not a parameter of SuspensionEstimator (parameters: m_s_nominal"),
    "vehicle refused": (lambda logs: [HEADER, *_rows(logs)], ["--vehicle", "m_s_nominal = 400.0\nm_u = 0.5\n"],
                        "SuspensionEstimator.fmu refuses the vehicle of "),
    "too many rows": (lambda logs: [HEADER, *_rows(logs, 200)], ["MAX_POINTS=100"], "more than 100 rows"),
}


@pytest.mark.parametrize("case", ERRORS)
def test_each_refusal_is_one_line_exit_1_and_leaves_dir_as_it_was(capsys, dist, logs, tmp_path, monkeypatch, case):
    make, args, says = ERRORS[case]
    log = tmp_path / "in" / "log.csv"
    log.parent.mkdir()
    if make is not None:
        content = make(logs)
        log.write_bytes(content if isinstance(content, bytes) else "".join(content).encode())
    if args and args[0] == "--vehicle":
        (tmp_path / "in" / "vehicle.toml").write_text(args[1])
        args = ["--vehicle", str(tmp_path / "in" / "vehicle.toml")]
    if args and args[0].startswith("MAX_POINTS="):
        monkeypatch.setattr("suspension_estimation.harness.estimate.MAX_POINTS", int(args[0].split("=")[1]))
        args = []
    out = tmp_path / "out" / "DIR"
    out.mkdir(parents=True)
    (out / "estimates.csv").write_text("an earlier run's")
    code, text, err = estimate(capsys, dist, log, out, *args)
    assert code == 1 and text == ""
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert says in err, err
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["DIR"]
    assert [p.name for p in out.iterdir()] == ["estimates.csv"] and (out / "estimates.csv").read_text() == "an earlier run's"


# asammdf 8.8's MDF4.__del__ fails on an object whose constructor failed (no _file): collected here
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_refused_mdf_files(capsys, dist, logs, tmp_path):
    from asammdf import MDF, Signal

    t = logs[0.005]["time"]
    mdf = MDF(version="4.10")
    mdf.append([Signal(logs[0.005][k], t, name=k) for k in ("acc_sprung", "acc_unsprung", "susp_deflection")],
               common_timebase=True)
    mdf.save(tmp_path / "log.mf4")
    mdf.close()
    code, _, err = estimate(capsys, dist, tmp_path / "log.mf4", tmp_path / "out")
    assert code == 1 and "no channel 'vehicle_speed' for vehicle_speed" in err and err.count("\n") == 1, err
    (tmp_path / "cut.mf4").write_bytes((tmp_path / "log.mf4").read_bytes()[:2000])
    code, _, err = estimate(capsys, dist, tmp_path / "cut.mf4", tmp_path / "out")
    assert code == 1 and "not a readable MDF file" in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()
    gc.collect()


def test_smooth_adds_the_smoothed_road_with_an_honest_std(capsys, dist, runs, logs, tmp_path):
    """--smooth on the 1 ms log (with its stop): the causal columns unchanged, the smoothed
    profile's HP error well below the causal one's (seeds 1, 2, 3, 5: 0.29-0.35 of it), its ±2σ
    (the smoothed road's std before the profile's high-pass, an upper bound) covering the error it
    has against what it estimates (1.000), and the IRI of the smoothed profile."""
    log = logs[0.001]
    code, text, err = estimate(capsys, dist, write_log(tmp_path / "log.csv", log), tmp_path / "out", "--smooth")
    assert code == 0, err
    est = read_csv(tmp_path / "out" / "estimates.csv")
    assert est.dtype.names[-2:] == ("road_height_smooth", "road_height_smooth_std")
    plain = read_csv(runs[0.001][0] / "estimates.csv")
    for k in plain.dtype.names:
        assert np.array_equal(est[k], plain[k]), k
    t = est["time"]
    causal = metrics.road_scores(t, est["road_height_est"], log["road"], est["road_height_std"],
                                 warmup=metrics.warmup_for(t), distance=log["distance"])
    smooth = metrics.road_scores(t, est["road_height_smooth"], log["road"], est["road_height_smooth_std"],
                                 warmup=metrics.warmup_for(t), distance=log["distance"])
    assert smooth["err_std_hp_pct"] < 0.6 * causal["err_std_hp_pct"], (smooth, causal)
    assert smooth["coverage_2sigma"] >= 0.95, smooth
    truth = true_iri(5, log["distance"][-1])
    iri = read_csv(tmp_path / "out" / "iri.csv")["iri_m_per_km"]
    assert np.all(np.abs(iri / truth - 1) < 0.15), (iri, truth)

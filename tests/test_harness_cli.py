"""Scenarios (harness/scenario.py) and ``python -m suspension_estimation.harness run``: outputs, exit codes, one-line errors."""
from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from suspension_estimation.harness.cli import main
from suspension_estimation.harness.cosim import read_csv
from suspension_estimation.harness.runner import run_scenario
from suspension_estimation.harness.scenario import SCENARIOS, ScenarioError, load_scenario
from suspension_estimation.harness.studies import STUDIES
from suspension_estimation.harness.sweep import SWEEPS
from suspension_estimation.suspension_fmi.contract import ROAD_ESTIMATORS, SUSPENSION_ESTIMATOR

ROOT = Path(__file__).resolve().parents[1]

SHORT = """\
duration = 0.3
step = 0.001
[road]
road_class = "D"
seed = 7
[speed]
time = [0.0, 0.1]
value = [10.0, 20.0]
[sprung_mass]
time = [0.0, 0.15]
value = [410.0, 300.0]
[noise]
acc_unsprung_std = 0.3
[plant]
acc_sprung_noise_std = 0.0
"""

# Refusal tests run road -> plant only: a process that ran QuarterCar and SuspensionEstimator for
# a few steps sometimes aborts at exit ("corrupted double-linked list", in library finalizers),
# also with tests/fmu_driver.py alone (PythonFMU issue 229, docs/native-hosts.md).
ROAD_PLANT = 'system = "road_plant"\n'


def harness(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "suspension_estimation.harness", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=120)


def scenario_file(tmp_path: Path, text: str, name: str = "s") -> Path:
    p = tmp_path / f"{name}.toml"
    p.write_text(text)
    return p


def test_default_scenario_is_iso_c_40_kmh_410_kg_20_s_1_ms():
    s = load_scenario("default")
    assert s.path == SCENARIOS / "default.toml"
    assert (s.road["road_class"], s.duration, s.step, s.system) == (3, 20.0, 0.001, "auto")
    assert s.speed.is_constant and s.speed(0.0) == pytest.approx(40 / 3.6, rel=1e-5)
    assert s.sprung_mass.is_constant and s.sprung_mass(0.0) == 410.0


def test_every_shipped_scenario_loads():
    for f in SCENARIOS.glob("*.toml"):
        load_scenario(f)


def test_profiles_interpolate_or_hold(tmp_path):
    s = load_scenario(scenario_file(tmp_path, SHORT))
    assert s.speed(np.array([0.0, 0.05, 0.1, 1.0])).tolist() == [10.0, 15.0, 20.0, 20.0]
    assert s.sprung_mass(np.array([0.0, 0.149, 0.15, 9.0])).tolist() == [410.0, 410.0, 300.0, 300.0]
    p = s.parameters(with_estimator=True)
    assert p["ISORoad.road_class"] == 4 and p["QuarterCar.acc_unsprung_noise_std"] == 0.3
    assert p["SuspensionEstimator.acc_unsprung_noise_std"] == 0.3  # the estimator assumes the sensor's noise
    assert p["QuarterCar.acc_sprung_noise_std"] == 0.0  # [plant] overrides the plant only
    assert "SuspensionEstimator.acc_sprung_noise_std" not in p and "SuspensionEstimator.noise_seed" not in p


@pytest.mark.parametrize("text, key", [
    ("duration = 1.0\n", "'step' is missing"),
    ("duration = 1.0\nstep = 0.001\nspeeed = 3\n", "unknown key 'speeed'"),
    ("duration = 1.0\nstep = -0.001\n", "'step' must be > 0"),
    ("duration = 1.0\nstep = 0.3\n", "not a whole number"),
    ('duration = "long"\nstep = 0.001\n', "'duration' must be a finite number"),
    ("duration = 1.0\nstep = 0.001\n[speed]\ntime = [0, 1]\nvalue = [1]\n", "'speed.time' has 2 entries"),
    ("duration = 1.0\nstep = 0.001\n[speed]\ntime = [1, 0]\nvalue = [1, 2]\n", "'speed.time' must be strictly"),
    ("duration = 1.0\nstep = 0.001\n[sprung_mass]\nvalue = 400\nshape = 1\n", "unknown key 'sprung_mass.shape'"),
    ('duration = 1.0\nstep = 0.001\n[road]\nroad_class = "Z"\n', "'road.road_class'"),
    ("duration = 1.0\nstep = 0.001\n[noise]\nacc_std = 1\n", "unknown key 'noise.acc_std'"),
    ('duration = 1.0\nstep = 0.001\nsystem = "car"\n', "'system' must be one of"),
    ("duration = 1.0\nstep = 0.001\n[output]\nrecord = ['z_s']\n", "'output.record'"),
    ("duration = 1.0\nstep = [0.001\n", "not valid TOML"),
    ("duration = 1.0\nstep = 0.001\nestimator_step = 0.0015\n", "'estimator_step' = 0.0015 s is not a whole number"),
    ("duration = 1.005\nstep = 0.001\nestimator_step = 0.01\n", "not a whole number of 'estimator_step'"),
])
def test_bad_scenarios_are_refused_naming_the_key(tmp_path, text, key):
    with pytest.raises(ScenarioError, match=None) as info:
        load_scenario(scenario_file(tmp_path, text))
    msg = str(info.value)
    assert key in msg and msg.startswith("scenario s.toml: ") and "\n" not in msg


def test_unknown_scenario_names_the_known_ones():
    with pytest.raises(ScenarioError, match="unknown scenario 'nope' .*default"):
        load_scenario("nope")


def test_parameters_that_the_fmus_do_not_have_are_refused(dist, tmp_path):
    s = load_scenario(scenario_file(tmp_path, SHORT + "k_x = 1.0\n"))
    with pytest.raises(ScenarioError, match="'plant.k_x' is not a parameter of QuarterCar"):
        run_scenario(s, dist=dist)
    s = load_scenario(scenario_file(tmp_path, SHORT + "noise_seed = 1.5\n"))
    with pytest.raises(ScenarioError, match="'plant.noise_seed' must be a Integer"):
        run_scenario(s, dist=dist)


def test_run_scenario_applies_the_scenario(dist, tmp_path):
    s = load_scenario(scenario_file(tmp_path, SHORT + '[output]\nrecord = ["QuarterCar.v_s"]\n'))
    run = run_scenario(s, dist=dist, out=tmp_path / "out")
    r = run.result
    t = r["time"]
    assert len(r) == 301 and run.csv == tmp_path / "out" / "s.csv"
    assert np.array_equal(r["QuarterCar.sprung_mass"][1:], s.sprung_mass(t[:-1]))
    assert np.allclose(r["ISORoad.vehicle_speed"][1:], s.speed(t[:-1]), rtol=0, atol=1e-12)
    assert np.array_equal(r["QuarterCar.acc_sprung"], r["QuarterCar.acc_sprung_true"])  # noise std 0
    assert "QuarterCar.v_s" in r.dtype.names
    assert np.array_equal(read_csv(run.csv)["QuarterCar.z_s"], r["QuarterCar.z_s"])


def test_an_estimator_step_runs_the_estimator_at_its_loggers_rate(dist, tmp_path):
    """``estimator_step`` = 10 ms over a 1 ms plant whose road moves linearly over the step: the
    record holds the estimator's steps, and each estimate follows from the plant's outputs there
    (the core fed the recorded samples at 10 ms gives the same)."""
    from suspension_estimation.estimators import SuspensionEstimator

    text = "duration = 1.0\nstep = 0.001\nestimator_step = 0.01\n[speed]\nvalue = 15.0\n[plant]\nroad_input = 1\n"
    s = load_scenario(scenario_file(tmp_path, text))
    assert s.estimator_every == 10
    r = run_scenario(s, dist=dist).result
    assert len(r) == 101 and np.allclose(np.diff(r["time"]), 0.01)
    core = SuspensionEstimator()
    est = [core.step(a, b, c, 15.0, 0.01)["road_height_est"]
           for a, b, c in zip(r["QuarterCar.acc_sprung"][1:], r["QuarterCar.acc_unsprung"][1:],
                              r["QuarterCar.susp_deflection"][1:])]
    assert np.allclose(r["SuspensionEstimator.road_height_est"][1:], est, rtol=1e-12, atol=1e-15)


def test_cli_run_writes_csv_plots_and_a_summary(dist, tmp_path):
    out = tmp_path / "out"
    p = harness("run", str(scenario_file(tmp_path, SHORT)), "--out", str(out), "--dist", str(dist))
    assert p.returncode == 0, p.stderr
    assert "s: ISORoad -> QuarterCar" in p.stdout and "wrote" in p.stdout
    assert (out / "s.csv").is_file()
    pngs = {f.name for f in out.glob("*.png")}
    assert {"s_road.png", "s_accelerations.png", "s_deflection.png"} <= pngs
    if (dist / "SuspensionEstimator.fmu").is_file():
        assert {"s_road_estimate.png", "s_sprung_mass.png"} <= pngs
        assert "sprung mass" in p.stdout and "no score" not in p.stdout
        assert "road profile (high-passed at 91.44 m of travel" in p.stdout and "within 2 sigma" in p.stdout


def test_cli_run_prints_the_parameters_it_uses(dist, tmp_path):
    """Before the summary: the plant's vehicle and the estimator's parameters with units, the
    scenario's values where it sets them ([plant] k_s is also what the estimator assumes) and the
    FMU's defaults elsewhere (m_s_nominal)."""
    text = SHORT + "k_s = 25000.0\n[estimator]\nroad_estimator = 0\n"
    p = harness("run", str(scenario_file(tmp_path, text)), "--out", str(tmp_path / "out"), "--dist", str(dist),
                "--no-plots")
    assert p.returncode == 0, p.stderr
    before, summary = p.stdout.split("s: ISORoad -> QuarterCar", 1)
    vehicle, estimator = " ".join(before.split()).split("estimator (SuspensionEstimator):")
    assert "vehicle (QuarterCar):" in vehicle and "road profile (high-passed at" in summary
    for item in ("sprung_mass 410 -> 300 kg (step at 0, 0.15 s)", "k_s 25000 N/m,", "m_u 39 kg,",
                 "acc_sprung_noise_std 0 m/s2,", "acc_unsprung_noise_std 0.3 m/s2,", "spring_model 0 (linear)"):
        assert item in vehicle, (item, vehicle)
    default = {v.name: v for v in SUSPENSION_ESTIMATOR}
    m_s = default["m_s_nominal"]
    for item in (f"m_s_nominal {m_s.start:g} {m_s.unit},", "k_s 25000 N/m,", "acc_unsprung_noise_std 0.3 m/s2,",
                 f"acc_sprung_noise_std {default['acc_sprung_noise_std'].start:g} m/s2,",
                 f"road_estimator 0 ({ROAD_ESTIMATORS[0][0]}),", "mass_feedback true,"):
        assert item in estimator, (item, estimator)


def test_help_lists_every_scenario_study_and_sweep(capsys):
    """``--help`` of each command: run lists the shipped scenarios and paper the registered studies,
    each with its description; sweep the shipped sweeps."""
    def help_text(*args: str) -> str:
        with pytest.raises(SystemExit) as e:
            main([*args, "--help"])
        assert e.value.code == 0
        return capsys.readouterr().out

    def described(folder: Path) -> dict[str, str]:
        return {f.stem: tomllib.loads(f.read_text())["description"] for f in folder.glob("*.toml")}

    top = " ".join(help_text().split())
    assert all(c in top for c in ("run", "paper", "sweep")) and f"({len(STUDIES)} studies" in top
    listed = {"run": described(SCENARIOS), "paper": {n: text for n, (_, text) in STUDIES.items()},
              "sweep": described(SWEEPS)}
    assert len(listed["run"]) >= 4 and len(listed["paper"]) >= 8
    for command, rows in listed.items():
        lines = help_text(command).splitlines()
        for name, description in rows.items():
            assert any(line.split() == [name, *description.split()] for line in lines), (command, name)


def test_cli_no_plots(dist, tmp_path):
    out = tmp_path / "out"
    p = harness("run", str(scenario_file(tmp_path, SHORT)), "--out", str(out), "--dist", str(dist), "--no-plots")
    assert p.returncode == 0, p.stderr
    assert [f.name for f in out.iterdir()] == ["s.csv"]


@pytest.mark.parametrize("args, words", [
    (["run", "no_such_scenario"], ["unknown scenario 'no_such_scenario'"]),
    (["run", "missing.toml"], ["missing.toml does not exist"]),
])
def test_cli_user_errors_are_one_line(args, words, dist):
    p = harness(*args, "--dist", str(dist))
    assert p.returncode == 1
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, p.stderr
    assert all(w in p.stderr for w in words), p.stderr


def test_cli_bad_key_is_one_line(dist, tmp_path):
    p = harness("run", str(scenario_file(tmp_path, "colour = 1\n" + SHORT)), "--dist", str(dist))
    assert p.returncode == 1 and p.stderr.count("\n") == 1
    assert p.stderr.startswith("error: scenario s.toml: unknown key 'colour' (allowed: description, duration, ")


def test_cli_fmu_refusal_is_one_line_and_keeps_the_partial_csv(dist, tmp_path):
    text = ROAD_PLANT + SHORT.replace("value = [10.0, 20.0]", "value = [10.0, -5.0]\ninterpolation = \"step\"")
    out = tmp_path / "out"
    p = harness("run", str(scenario_file(tmp_path, text)), "--out", str(out), "--dist", str(dist))
    assert p.returncode == 1
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, p.stderr
    assert p.stderr.startswith("error: ISORoad refused the step (discard) at t = 0.1 s: ")
    assert "vehicle_speed" in p.stderr and "partial results up to t = 0.1 s" in p.stderr
    r = read_csv(out / "s.csv")
    assert r["time"][-1] == pytest.approx(0.1) and len(r) == 101


def test_cli_refusal_at_initialization_writes_no_result(dist, tmp_path):
    out = tmp_path / "out"
    good = scenario_file(tmp_path, ROAD_PLANT + SHORT)
    assert harness("run", str(good), "--dist", str(dist), "--out", str(out), "--no-plots").returncode == 0
    assert (out / "s.csv").is_file()
    # the same scenario refused: the earlier run's file must not pass for this one's
    p = harness("run", str(scenario_file(tmp_path, ROAD_PLANT + SHORT + "k_t = 0.0\n")), "--dist", str(dist),
                "--out", str(out))
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stderr
    assert p.stderr.startswith("error: QuarterCar refused to initialize at t = 0 s: ") and "k_t" in p.stderr
    assert "no result file written" in p.stderr
    assert list(out.iterdir()) == []


def test_read_csv_names_a_result_without_rows(tmp_path):
    f = tmp_path / "refused.csv"
    f.write_text('"time","QuarterCar.z_s"\n')
    with pytest.raises(ValueError, match="holds no result rows .* refused to initialize"):
        read_csv(f)

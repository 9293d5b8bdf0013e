"""ISORoad.fmu through FMPy: ISO 8608 spectrum, distance-based profile, derivative, profile files."""
from __future__ import annotations

import numpy as np
import pytest

from fmpy.fmi1 import FMICallException
from suspension_estimation.plant import iso8608
from suspension_estimation.plant.road import SyntheticRoad


@pytest.fixture
def road(driven):
    return lambda **params: driven("ISORoad", **params)


@pytest.mark.parametrize("road_class", range(1, 9))
def test_psd_matches_iso8608_in_every_octave_band(road, road_class):
    # 20 km at 0.2 m spacing. 2 km holds only ~40 wavelengths of the lowest octave, whose
    # power then scatters by about +-16 % (1 sigma) for any Gaussian road, so 20 km is used.
    r = road(road_class=road_class, seed=road_class)
    out = r.run(0.01, 100_000, ["road_height", "distance"], vehicle_speed=20.0)
    assert np.allclose(np.diff(out[:, 1]), 0.2)
    errors = iso8608.band_psd_errors(out[:, 0], 0.2, iso8608.class_psd_n0(road_class), segment=1000.0)
    assert len(errors) == 7
    for lo, hi, err in errors:
        assert abs(err) < 0.15, f"class {iso8608.class_name(road_class)} band {lo:.2f}-{hi:.2f}: {err:+.1%}"


def test_psd_n0_and_waviness_override_the_class(road):
    r = road(road_class=8, psd_n0=64e-6, waviness=2.5, seed=3)
    out = r.run(0.01, 100_000, ["road_height"], vehicle_speed=20.0)
    for lo, hi, err in iso8608.band_psd_errors(out[:, 0], 0.2, 64e-6, 2.5, segment=1000.0):
        assert abs(err) < 0.15, (lo, err)


def test_same_seed_same_road_at_any_speed(road):
    slow = road(seed=7).run(0.01, 2000, ["road_height", "distance"], vehicle_speed=10.0)  # 0.1 m/step
    fast = road(seed=7).run(0.005, 2000, ["road_height", "distance"], vehicle_speed=20.0)  # 0.1 m/step
    assert np.allclose(slow[:, 1], fast[:, 1], rtol=0, atol=1e-9)
    assert np.allclose(slow[:, 0], fast[:, 0], rtol=0, atol=1e-9)
    other = road(seed=8).run(0.01, 2000, ["road_height"], vehicle_speed=10.0)
    assert np.std(other[:, 0] - slow[:, 0]) > 0.5 * np.std(slow[:, 0])


def test_speed_changing_during_a_run_traverses_the_same_road(road):
    r = road(seed=5)
    rows = []
    for k in range(3000):
        r.step(0.002, vehicle_speed=5.0 + 25.0 * abs(np.sin(k / 300)))
        rows.append((r.get("distance"), r.get("road_height")))
    rows = np.array(rows)
    core = SyntheticRoad(iso8608.class_psd_n0(3), seed=5)
    expected = np.array([core.height(s) for s in rows[:, 0]])
    assert np.max(np.abs(rows[:, 1] - expected)) < 1e-12
    # and against a constant-speed run of the same FMU, interpolated at the same distances
    ref = road(seed=5).run(0.001, int(rows[-1, 0] / 0.01) + 2, ["road_height", "distance"], vehicle_speed=10.0)
    interp = np.interp(rows[:, 0], ref[:, 1], ref[:, 0])
    assert np.max(np.abs(rows[:, 1] - interp)) < 2e-3 * np.ptp(ref[:, 0])


def test_road_velocity_is_the_time_derivative_of_road_height(road):
    # central differences are O((omega h)^2) off; at 0.1 ms that is < 0.2 % at 2.83 cycle/m and 25 m/s
    h = 1e-4
    out = road(road_class=4).run(h, 20_000, ["road_height", "road_velocity"], vehicle_speed=25.0)
    fd = (out[2:, 0] - out[:-2, 0]) / (2 * h)
    err = fd - out[1:-1, 1]
    assert np.sqrt(np.mean(err ** 2)) < 1e-3 * np.std(out[:, 1])


def _write(path, text):
    path.write_text(text)
    return str(path)


def test_profile_file_is_followed(road, tmp_path):
    s = np.linspace(0.0, 50.0, 501)
    z = 0.01 * np.sin(2 * np.pi * s / 7.0)
    f = _write(tmp_path / "p.csv", "distance_m,elevation_m\n" + "".join(f"{a},{b}\n" for a, b in zip(s, z)))
    out = road(profile_file=f).run(0.01, 400, ["road_height", "distance"], vehicle_speed=10.0)
    assert np.max(np.abs(out[:, 0] - 0.01 * np.sin(2 * np.pi * out[:, 1] / 7.0))) < 1e-5
    g = _write(tmp_path / "p.txt", "# whitespace columns\n" + "".join(f"{a}  {b}\n" for a, b in zip(s + 100, z)))
    out2 = road(profile_file=g).run(0.01, 400, ["road_height"], vehicle_speed=10.0)
    assert np.allclose(out2[:, 0], out[:, 0], atol=1e-12)


def test_road_height_rear_is_road_height_without_a_wheelbase(road):
    out = road(road_class=4).run(0.001, 500, ["road_height", "road_height_rear"], vehicle_speed=20.0)
    assert np.array_equal(out[:, 0], out[:, 1])


def test_road_height_rear_is_the_same_synthetic_road_a_wheelbase_behind(road):
    """The rear tyre reads the road at distance - wheelbase, also behind the start: the synthetic
    road is a sum of cosines, defined for negative distances as for positive ones."""
    r = road(road_class=4, seed=2, wheelbase=2.7)
    first = [r.get("road_height"), r.get("road_height_rear"), r.get("distance")]
    out = np.vstack([first, r.run(0.001, 500, ["road_height", "road_height_rear", "distance"], vehicle_speed=27.0)])
    core = SyntheticRoad(iso8608.class_psd_n0(4), seed=2)
    assert np.max(np.abs(out[:, 1] - [core.height(s - 2.7) for s in out[:, 2]])) < 1e-12
    assert out[0, 1] != out[0, 0]  # at rest the rear tyre stands on the road under it, not on the front's height
    # 27 mm a step: the rear reads what the front read 100 steps before
    assert np.max(np.abs(out[100:, 1] - out[:-100, 0])) < 1e-9 * np.ptp(out[:, 0])


def test_road_height_rear_holds_a_measured_profiles_first_elevation_behind_its_start(road, tmp_path):
    s = np.linspace(0.0, 50.0, 501)
    z = 0.05 + 0.01 * np.sin(2 * np.pi * s / 7.0)
    f = _write(tmp_path / "p.csv", "".join(f"{a},{b}\n" for a, b in zip(s, z)))
    out = road(profile_file=f, wheelbase=2.5).run(0.01, 400, ["road_height", "road_height_rear", "distance"],
                                                  vehicle_speed=10.0)
    behind = out[:, 2] < 2.5
    assert np.all(out[behind, 1] == 0.05)
    assert np.max(np.abs(out[~behind, 1] - (0.05 + 0.01 * np.sin(2 * np.pi * (out[~behind, 2] - 2.5) / 7.0)))) < 1e-5


@pytest.mark.parametrize("wheelbase", [-0.1, 25.0, float("nan")])
def test_bad_wheelbase_is_refused_naming_it(road, wheelbase):
    r = road(wheelbase=wheelbase)
    assert any(status == 3 and "wheelbase" in m and "[0, 20]" in m for status, m in r.messages), r.messages
    with pytest.raises(FMICallException, match="discard"):
        r.step(0.001)


@pytest.mark.parametrize("text, words", [
    (None, ["does not exist"]),
    ("0 0\n1 0.1\nabc 3\n", ["line 3", "two numbers"]),
    ("0 0\n1 0.1\n1 0.2\n", ["line 3", "does not increase"]),
    ("0 0\n1 nan\n", ["line 2", "non-finite"]),
])
def test_bad_profile_file_is_refused_with_its_reason(road, tmp_path, text, words):
    path = tmp_path / "missing.csv" if text is None else tmp_path / "bad.csv"
    if text is not None:
        path.write_text(text)
    r = road(profile_file=str(path))
    assert any("profile_file" in m and all(w in m for w in words) for _, m in r.messages), r.messages
    with pytest.raises(FMICallException, match="discard"):
        r.step(0.01)


def test_driving_past_the_end_of_a_profile_is_an_error(road, tmp_path):
    f = _write(tmp_path / "short.csv", "0 0\n10 0.01\n20 0\n")
    r = road(profile_file=f)
    r.run(0.1, 20, ["road_height"], vehicle_speed=10.0)  # to the last sample at 20 m
    with pytest.raises(FMICallException, match="discard"):
        r.step(0.1)
    assert any("past the end" in m for _, m in r.messages)


@pytest.mark.parametrize("params, name", [
    ({"road_class": 9}, "road_class"), ({"road_class": 0}, "road_class"), ({"waviness": -1.0}, "waviness"),
    ({"psd_n0": -1e-6}, "psd_n0"), ({"n_min": 3.0}, "n_min"), ({"seed": -1}, "seed"),
])
def test_bad_parameter_is_refused_naming_it_and_its_range(road, params, name):
    r = road(**params)
    assert any(status == 3 and name in m and ("range" in m or "below" in m) for status, m in r.messages), r.messages
    with pytest.raises(FMICallException, match="discard"):
        r.step(0.001)


@pytest.mark.parametrize("speed", [-1.0, float("nan"), float("inf")])
def test_bad_speed_is_refused_at_the_step(road, speed):
    r = road()
    r.step(0.001, vehicle_speed=10.0)
    with pytest.raises(FMICallException, match="discard"):
        r.step(0.001, vehicle_speed=speed)
    assert any("vehicle_speed" in m and "[0, 100]" in m for _, m in r.messages), r.messages


def test_a_percent_sign_in_a_message_reaches_the_log_verbatim(road, tmp_path):
    # FMI loggers format the message printf-style: the FMU must escape a literal %
    r = road(profile_file=str(tmp_path / "no%sfile%d.csv"))
    assert any("no%sfile%d.csv" in m and "does not exist" in m for _, m in r.messages), r.messages

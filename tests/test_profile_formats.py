"""Measured profiles as users have them (plant/profile_formats.py): units, ERD, OpenCRG binary and
ASCII, absolute elevations through the plant, profile_end and a scenario that drives the whole
profile. Every file here is written by the test; the OpenCRG sample of ../shared is only read."""
from __future__ import annotations

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from conftest import SHARED
from plant.profile_formats import ProfileError, read_profile

S = np.arange(0.0, 40.01, 0.25)
Z = 0.01 * np.sin(2 * np.pi * S / 7.0) + 0.002 * S  # m: a wave on a 0.2 % grade


def _csv(path, header, dist, elev):
    path.write_text(header + "".join(f"{a:.6f},{b:.9f}\n" for a, b in zip(dist, elev)))
    return path


@pytest.mark.parametrize("header, d_unit, e_unit, units", [
    ("distance (ft), elevation (in)\n", 0.3048, 0.0254, ""),
    ("dist_m,elev_mm\n", 1.0, 1e-3, ""),
    ("distance elevation\n", 1.0, 1e-3, "mm"),
    ("# no header\n", 0.3048, 0.0254, "ft,in"),
])
def test_units_from_the_header_or_the_parameter(tmp_path, header, d_unit, e_unit, units):
    f = _csv(tmp_path / "p.csv", header, S / d_unit, Z / e_unit)
    d, z = read_profile(f, units)
    assert np.allclose(d, S, atol=1e-5) and np.allclose(z, Z, atol=1e-8)


def test_an_unknown_unit_is_refused(tmp_path):
    f = _csv(tmp_path / "p.csv", "distance [m], elevation [furlong]\n", S, Z)
    with pytest.raises(ProfileError, match="furlong"):
        read_profile(f)
    with pytest.raises(ProfileError, match="profile_units"):
        read_profile(_csv(tmp_path / "q.csv", "", S, Z), "yd")


def test_erd_text_file(tmp_path):
    # two channels (left, right elevation) in inches every 0.25 ft from 10 ft
    dx_ft, n = 0.25, len(S)
    left, right = Z / 0.0254, -Z / 0.0254
    rows = "".join(f"{a:.6f}, {b:.6f}\n" for a, b in zip(left, right))
    f = tmp_path / "p.erd"
    f.write_text(f"ERDFILEV2.00\n2, {n}, 1, -1, {dx_ft}, 10.0, 0\nTITLE test road\nSHORTNAMES Left, Right\n"
                 f"UNITSNAMES in, in\nXUNITS ft\nSCALEFACTORS 1, 1\nEND\n" + rows)
    d, z = read_profile(f)
    assert np.allclose(d, (10.0 + dx_ft * np.arange(n)) * 0.3048)
    assert np.allclose(z, Z, atol=1e-7)
    f.write_text(f"ERDFILEV2.00\n2, {n}, 1, 4, {dx_ft}, 10.0, 0\nEND\n")
    with pytest.raises(ProfileError, match="binary ERD"):
        read_profile(f)


def _crg_header(fmt: str, channels: list[str], du: float, n: int, extra: str = "") -> str:
    return ("$CT\ntest road written by the test suite\n$\n$ROAD_CRG\n"
            f"reference_line_start_u = 100.0\nreference_line_end_u = {100.0 + du * (n - 1)}\n"
            f"reference_line_increment = {du}\n{extra}$\n$KD_DEFINITION\n#:{fmt}\n"
            + "".join(f"D:{c}\n" for c in channels) + "$\n" + "$" * 72 + "\n")


def _crg_grid():
    """Three long sections at v = -1, 0, 1.5 m and a reference-line slope channel."""
    v = np.array([-1.0, 0.0, 1.5])
    grid = Z[:, None] + 0.004 * v[None, :]  # a 0.4 % cross slope
    slope = np.full(len(Z), 0.001)
    return v, grid, slope


@pytest.mark.parametrize("offset", [0.0, 0.75, -1.0])
def test_opencrg_ascii_layout(tmp_path, offset):
    v, grid, slope = _crg_grid()
    chans = ["reference line slope,m/m"] + [f"long section at v = {x:.3f},m" for x in v]
    lines = []
    for s, row in zip(slope, grid):
        # fixed 10-character fields with no separator: a minus sign joins two numbers
        lines.append("".join(f"{x:10.6f}" for x in (s, *row)))
    lines[3] = lines[3][:10] + "*missing*".ljust(10) + lines[3][20:]  # missing at v = -1 only
    f = tmp_path / "road.crg"
    f.write_text(_crg_header("LRFI", chans, 0.25, len(S), "reference_line_start_z = 583.0\n") + "\n".join(lines) + "\n")
    if offset == -1.0:
        with pytest.raises(ProfileError, match="missing"):
            read_profile(f, lateral_offset=offset)
        return
    d, z = read_profile(f, lateral_offset=offset)
    ref = 583.0 + 0.001 * (d - d[0])  # start z plus the integrated slope
    assert np.allclose(d, 100.0 + S)
    assert np.allclose(z, ref + Z + 0.004 * offset, atol=2e-6)  # 6 decimals in the file


def test_opencrg_binary_layout_and_a_damaged_file(tmp_path):
    v, grid, _ = _crg_grid()
    chans = ["reference line phi,rad"] + [f"long section {i + 1},m" for i in range(len(v))]
    # numbered sections from v_right every v_increment: -1, 0, 1 (not the 1.5 of the grid)
    data = np.column_stack([np.zeros(len(S)), grid[:, 0], grid[:, 1], Z + 0.004])
    body = data.astype(">f4").tobytes()
    body += np.full((-len(body)) % 80 // 4, np.nan, ">f4").tobytes()  # NaN padding to a whole record
    head = _crg_header("KRBI", chans, 0.25, len(S), "long_section_v_right = -1.0\nlong_section_v_increment = 1.0\n")
    f = tmp_path / "road.crg"
    f.write_bytes(head.encode("latin-1") + body)
    d, z = read_profile(f, lateral_offset=0.5)
    assert np.allclose(z, Z + 0.002, atol=1e-6)  # float32, halfway between v = 0 and v = 1
    with pytest.raises(ProfileError, match="profile_lateral_offset"):
        read_profile(f, lateral_offset=3.0)
    f.write_bytes(head.encode("latin-1") + body[:1000] + body[1001:])  # one byte lost
    with pytest.raises(ProfileError, match="damaged"):
        read_profile(f)


def test_opencrg_sample_is_read_or_refused_never_garbage():
    """The measured Belgian-block sample (binary, 10 m at 1 cm, elevations about 2.1 m): either a
    clean profile or a clear refusal. (The copy in OpenCRG's crg-bin folder is 5 bytes short of
    its header's 1001 rows: a line-ending conversion dropped bytes, and the reader says so.)"""
    path = SHARED / "data" / "opencrg" / "belgian_block.crg"
    if not path.is_file():
        pytest.skip("../shared is absent")
    try:
        d, z = read_profile(path)
    except ProfileError as e:
        assert "damaged" in str(e) and "1001 rows" in str(e)
        return
    assert len(d) == 1001 and np.allclose(np.diff(d), 0.01)
    assert np.all((z > 1.9) & (z < 2.4))


def test_absolute_elevation_through_road_and_plant(driven, tmp_path):
    """A road at 1583 m drives the plant exactly as the same road at 0 m: the plant settles on the
    first elevation."""
    results = []
    for level in (0.0, 1583.1):
        f = _csv(tmp_path / f"p{level:g}.csv", "distance_m,elevation_m\n", S, Z + level)
        road = driven("ISORoad", profile_file=str(f))
        car = driven("QuarterCar", road_height=float(Z[0] + level))
        acc = []
        for _ in range(300):
            road.step(0.01, vehicle_speed=10.0)
            car.step(0.01, road_height=road.get("road_height"))
            acc.append((car.get("acc_sprung_true"), car.get("acc_unsprung_true"), car.get("tire_deflection")))
        assert not any(status >= 3 for status, _ in car.messages), car.messages
        results.append(np.array(acc))
    assert np.allclose(results[0], results[1], atol=1e-7)
    assert np.abs(results[0][:, 0]).max() > 0.1  # the road did shake the car


@pytest.mark.parametrize("mode", [0, 1, 2])
def test_profile_end_stop_hold_loop(driven, tmp_path, mode):
    f = _csv(tmp_path / "p.csv", "distance_m,elevation_m\n", S, Z)
    road = driven("ISORoad", profile_file=str(f), profile_end=mode)
    out = road.run(0.01, 400, ["road_height", "distance"], vehicle_speed=10.0)  # to 40 m, the end
    if mode == 0:
        with pytest.raises(FMICallException, match="discard"):
            road.step(0.01)
        assert any("end of the profile" in m and "profile_end" in m for _, m in road.messages)
        return
    more = road.run(0.01, 300, ["road_height", "distance"])
    if mode == 1:
        assert np.allclose(more[:, 0], Z[-1])
    else:  # the profile again, raised by its end-to-start rise: continuous at the seam
        lap = more[:, 1] > 40.0
        expected = np.interp(more[lap, 1] - 40.0, S, Z) + (Z[-1] - Z[0])
        assert np.allclose(more[lap, 0], expected, atol=2e-4)
        assert abs(more[0, 0] - out[-1, 0]) < 0.01


def test_scenario_drives_the_whole_profile(dist, tmp_path):
    from harness.runner import run_scenario
    from harness.scenario import ScenarioError, load_scenario

    _csv(tmp_path / "p.csv", "distance (m), elevation (mm)\n", S, 1e3 * (Z + 1583.1))
    sc = tmp_path / "whole.toml"
    sc.write_text('duration = "profile"\nstep = 0.01\nsystem = "road_plant"\n[road]\nprofile_file = "p.csv"\n'
                  "[speed]\ntime = [0.0, 2.0]\nvalue = [5.0, 15.0]\n")
    scenario = load_scenario(sc)
    run = run_scenario(scenario, dist=dist)
    travelled = run.result["ISORoad.distance"][-1]
    assert 40.0 - 0.15 < travelled <= 40.0  # the last whole step before the end (15 m/s * 10 ms)
    assert abs(run.result["ISORoad.road_height"][-1] - (Z[-1] + 1583.1)) < 1e-3
    sc.write_text('duration = "profile"\nstep = 0.01\n')
    with pytest.raises(ScenarioError, match="profile_file"):
        load_scenario(sc)

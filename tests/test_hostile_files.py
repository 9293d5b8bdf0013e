"""Profile files from outside (plant/profile_formats.py): a huge file, an endless line, binary
garbage, a header claiming sizes its data does not have or absurd sizes and increments, a header
that never ends. Each is refused with its reason, or read within a bound, and never hangs; the
limits are monkeypatched small so that every file here is written in milliseconds
(benchmarks/hostile_profiles.py measures the real sizes). Through ISORoad.fmu: the refusal is
logged naming profile_file and every doStep is discarded; a relative profile_file names a file
shipped in the FMU's resources folder, nothing else."""
from __future__ import annotations

import shutil
import tracemalloc
import zipfile

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

import suspension_estimation.plant.profile_formats as pf
from suspension_estimation.plant.profile_formats import ProfileError, read_profile


def _csv(path, rows: int, start: float = 0.0):
    s = start + 0.01 * np.arange(rows)
    path.write_text("distance_m,elevation_m\n" + "".join(f"{a:.2f},{0.01 * np.sin(a):.6f}\n" for a in s))
    return path


def _peak(read, *args, **kwargs) -> tuple[object, float]:
    """(what read returned or the ProfileError it raised, peak traced memory in MB)."""
    tracemalloc.start()
    try:
        out = read(*args, **kwargs)
    except ProfileError as e:
        out = e
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return out, peak


def _crg(path, fmt: str, channels: list[str], rows: int, data: bytes, keys: str = "", header_rows: int | None = None):
    """An OpenCRG file of ``rows`` rows every 1 cm from u = 0 (the header claims ``header_rows``;
    None: no reference_line_end_u)."""
    end = "" if header_rows is None else f"reference_line_end_u = {0.01 * (header_rows - 1)!r}\n"
    head = (f"$CT\nwritten by the test\n$ROAD_CRG\nreference_line_start_u = 0.0\n{end}"
            f"reference_line_increment = 0.01\n{keys}$KD_DEFINITION\n#:{fmt}\n"
            + "".join(f"D:{c}\n" for c in channels) + "$\n" + "$" * 72 + "\n")
    path.write_bytes(head.encode() + data)
    return path


def _ascii_rows(values: np.ndarray) -> bytes:
    """LRFI records: 8 fields of 10 characters a line, a row on as many lines as it needs."""
    lines = []
    for row in np.atleast_2d(values):
        fields = [f"{x:10.5f}" for x in row]
        lines += ["".join(fields[i:i + 8]) for i in range(0, len(fields), 8)]
    return ("\n".join(lines) + "\n").encode()


# -- a huge file --------------------------------------------------------------------------------

def test_more_rows_than_the_limit_are_refused_at_the_limit(tmp_path, monkeypatch):
    """A file past MAX_POINTS is refused when its row MAX_POINTS + 1 is met: the rest (here 100
    times the limit) is never read, and what was read is held in arrays of 8 bytes a number."""
    monkeypatch.setattr(pf, "MAX_POINTS", 1000)
    d, _ = read_profile(_csv(tmp_path / "at.csv", 1000))
    assert len(d) == 1000
    big = _csv(tmp_path / "big.csv", 100_000)
    err, peak = _peak(read_profile, big)
    assert isinstance(err, ProfileError)
    assert "line 1002 is data row 1001" in str(err) and "at most 1000 points" in str(err)
    assert peak < 1.0, f"{peak:.2f} MB traced for 1000 rows read"


def test_sizes_announced_beyond_the_limit_are_refused_before_reading(tmp_path, monkeypatch):
    monkeypatch.setattr(pf, "MAX_POINTS", 1000)
    erd = tmp_path / "p.erd"
    erd.write_text("ERDFILEV2.00\n1, 1001, 1, -1, 0.01, 0.0, 0\nEND\n0.0\n0.1\n")
    with pytest.raises(ProfileError, match="NSAMP = 1001 points; at most 1000"):
        read_profile(erd)
    claims = _crg(tmp_path / "claims.crg", "KRBI", ["long section at v = 0,m"], 2, np.zeros(2, ">f4").tobytes(),
                  header_rows=10**9)
    with pytest.raises(ProfileError, match="announces 1000000000 rows"):
        read_profile(claims)
    # no reference_line_end_u: as many rows as the data holds, up to the limit
    binary = _crg(tmp_path / "bin.crg", "KRBI", ["long section at v = 0,m"], 1001,
                  np.arange(1001, dtype=">f4").tobytes())
    with pytest.raises(ProfileError, match="holds 1001 rows; at most 1000"):
        read_profile(binary)
    text = _crg(tmp_path / "text.crg", "LRFI", ["long section at v = 0,m"], 1001, _ascii_rows(np.zeros((1001, 1))))
    with pytest.raises(ProfileError, match="road data row 1001; at most 1000"):
        read_profile(text)


# -- absurd lines and binary garbage ------------------------------------------------------------

@pytest.mark.parametrize("name, head", [
    ("p.csv", b""),                          # a file without line ends
    ("p.csv", b"distance_m,elevation_m\n"),  # ... after its header
    ("p.erd", b"ERDFILEV2.00\n"),            # ERD's second line
    ("p.crg", b"$CT\n"),                     # inside an OpenCRG header
])
def test_a_long_line_is_refused_without_being_read_whole(tmp_path, name, head):
    path = tmp_path / name
    path.write_bytes(head + b"1" * 5_000_000)  # one line of 5 MB
    err, peak = _peak(read_profile, path)
    lineno = head.count(b"\n") + 1
    assert isinstance(err, ProfileError), err
    assert f"line {lineno} is longer than {pf.MAX_LINE} characters" in str(err)
    assert peak < 1.0, f"{peak:.2f} MB traced"


def test_a_line_of_exactly_the_limit_is_read(tmp_path, monkeypatch):
    monkeypatch.setattr(pf, "MAX_LINE", 40)
    path = tmp_path / "p.csv"
    path.write_text("0,0\n" + "1,0.001".ljust(40) + "\r\n")
    assert len(read_profile(path)[0]) == 2
    path.write_text("0,0\n" + "1,0.001".ljust(41) + "\n")
    with pytest.raises(ProfileError, match="line 2 is longer than 40 characters"):
        read_profile(path)


@pytest.mark.parametrize("name", ["p.csv", "p.txt", "p.crg"])
def test_binary_garbage_is_refused(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(np.random.default_rng(1).bytes(2_000_000))
    with pytest.raises(ProfileError, match="profile_file"):
        read_profile(path)


def test_utf16_text_is_refused_as_binary(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("distance_m,elevation_m\n0,0\n1,0.1\n", encoding="utf-16")
    with pytest.raises(ProfileError, match="NUL bytes"):
        read_profile(path)


# -- headers that never end ---------------------------------------------------------------------

@pytest.mark.parametrize("name, text, words", [
    ("p.crg", "$CT\n" + "* a comment\n" * 2000, "OpenCRG header does not end"),
    ("p.erd", "ERDFILEV2.00\n1, 10, 1, -1, 0.01, 0.0, 0\n" + "TITLE a road\n" * 2000, "no END line within"),
    ("p.csv", "# a comment\n" * 2000 + "0,0\n1,0.1\n", "more than 1000 lines that are not data"),
    ("p.csv", "0,0\n" + "\n" * 2000 + "1,0.1\n", "more than 1000 lines that are not data"),
])
def test_a_header_that_never_ends_is_refused(tmp_path, monkeypatch, name, text, words):
    monkeypatch.setattr(pf, "MAX_OTHER_LINES", 1000)
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ProfileError, match=words):
        read_profile(path)


# -- headers that claim what their data does not hold -------------------------------------------

CH = ["reference line slope,m/m", "long section at v = -1,m", "long section at v = 1,m"]


@pytest.mark.parametrize("claimed, words", [(101, "holds 1200 bytes, 1212 expected"),
                                            (90, "holds 1200 bytes, 1080 expected")])
def test_opencrg_binary_claiming_other_rows_is_refused(tmp_path, claimed, words):
    data = np.zeros((100, 3), ">f4").tobytes()  # 1200 bytes: 15 whole 80-byte records
    with pytest.raises(ProfileError, match=words):
        read_profile(_crg(tmp_path / "p.crg", "KRBI", CH, 100, data, header_rows=claimed))


@pytest.mark.parametrize("claimed, words", [(101, "holds 100 rows, its header announces 101"),
                                            (99, "line 113: more road data rows than the 99")])
def test_opencrg_ascii_claiming_other_rows_is_refused(tmp_path, claimed, words):
    data = _ascii_rows(np.zeros((100, 3)))
    with pytest.raises(ProfileError, match=words):
        read_profile(_crg(tmp_path / "p.crg", "LRFI", CH, 100, data, header_rows=claimed))


def test_opencrg_ascii_ending_inside_a_row_is_refused(tmp_path):
    chans = [f"long section at v = {v},m" for v in range(-5, 6)]  # 11 channels: two lines a row
    data = _ascii_rows(np.zeros((10, 11)))
    data = data[:data.rindex(b"\n", 0, len(data) - 1) + 1]  # the last row's second line lost
    with pytest.raises(ProfileError, match=r"ends inside row 10 \(1 of its 2 lines\)"):
        read_profile(_crg(tmp_path / "p.crg", "LRFI", chans, 10, data))


@pytest.mark.parametrize("announced, words", [
    (11, "20 numbers after END, 2 x 11 announced"),
    (9, "line 13: more numbers after END than the 2 x 9 announced"),
])
def test_erd_claiming_other_sizes_is_refused(tmp_path, announced, words):
    path = tmp_path / "p.erd"
    path.write_text(f"ERDFILEV2.00\n2, {announced}, 1, -1, 0.25, 0.0, 0\nEND\n"
                    + "".join(f"{0.001 * k}, {-0.001 * k}\n" for k in range(10)))
    with pytest.raises(ProfileError, match=words):
        read_profile(path)


# -- absurd sizes and increments ----------------------------------------------------------------

@pytest.mark.parametrize("keys, words", [
    ("reference_line_increment = 0\n", "reference_line_increment = 0 must be > 0"),
    ("reference_line_increment = -0.01\n", "must be > 0"),
    ("reference_line_increment = nan\n", "'nan' is not a finite number"),
    ("reference_line_increment = 1e400\n", "'1e400' is not a finite number"),
    ("reference_line_increment = 1e-300\nreference_line_end_u = 1.0\n", r"announces 1e\+300 rows"),
    ("reference_line_increment = 0.01\nreference_line_end_u = -5\n", "give -499 rows; at least 2"),
    ("reference_line_increment = 1e-300\nreference_line_end_u = 1e300\n", "announces inf rows"),
    ("reference_line_increment = 1e308\n", "the distance of row 20 is inf m"),
    ("reference_line_increment = 0.01\nreference_line_start_z = inf\n", "'inf' is not a finite number"),
    ("reference_line_increment = 0.01\nlong_section_v_increment = nan\n", "long_section_v_increment"),
    ("reference_line_increment = 0.01\nlong_section_v_increment = 0\n", "two long sections at v = 0 m"),
])
def test_absurd_opencrg_header_values_are_refused(tmp_path, keys, words):
    head = (f"$ROAD_CRG\nreference_line_start_u = 0\nlong_section_v_increment = 1\n{keys}$KD_DEFINITION\n"
            "#:KRBI\nD:long section 1,m\nD:long section 2,m\n$\n" + "$" * 72 + "\n")
    path = tmp_path / "p.crg"
    path.write_bytes(head.encode() + np.zeros((20, 2), ">f4").tobytes())
    with pytest.raises(ProfileError, match=words):
        read_profile(path)


@pytest.mark.parametrize("channel, words", [
    ("long section at v = 1e999", "has no finite v"),
    ("long section at v = 1.2.3", "has no finite v"),
])
def test_absurd_opencrg_channels_are_refused(tmp_path, channel, words):
    with pytest.raises(ProfileError, match=words):
        read_profile(_crg(tmp_path / "p.crg", "KRBI", [channel], 20, np.zeros(20, ">f4").tobytes()))


@pytest.mark.parametrize("line2, words", [
    ("1, nan, 1, -1, 0.01, 0", "NSAMP = nan"),
    ("1, -5, 1, -1, 0.01, 0", "NSAMP = -5"),
    ("inf, 10, 1, -1, 0.01, 0", "NCHAN = inf"),
    ("1, 10, 1, -1, 0, 0", "DX = 0"),
    ("1, 10, 1, -1, nan, 0", "DX = nan"),
    ("1, 10, 1, -1, 0.01, inf", "X0 = inf"),
    ("1, 1e12, 1, -1, 0.01, 0", "NSAMP = 1e\\+12 points; at most"),
    ("1, 10, 1, -1, 1e308, 0", "the distance of row 10 is inf m"),
    ("1, 10", "expected 'NCHAN, NSAMP"),
])
def test_absurd_erd_header_values_are_refused(tmp_path, line2, words):
    path = tmp_path / "p.erd"
    path.write_text(f"ERDFILEV2.00\n{line2}\nEND\n" + "0.001\n" * 10)
    with pytest.raises(ProfileError, match=words):
        read_profile(path)


# -- read within a bound ------------------------------------------------------------------------

def test_a_wide_opencrg_file_keeps_only_the_driven_channels(tmp_path):
    """20 000 rows of 101 long sections (8 MB of float32): read in 1 MB chunks, only the two
    sections around the driven line kept."""
    rows, v = 20_000, np.linspace(-1.0, 1.0, 101)
    s = 0.01 * np.arange(rows)
    grid = (0.01 * np.sin(s)[:, None] + 0.002 * v[None, :]).astype(">f4")
    keys = "long_section_v_right = -1.0\nlong_section_v_increment = 0.02\n"
    path = _crg(tmp_path / "wide.crg", "KRBI", [f"long section {i + 1},m" for i in range(101)], rows,
                grid.tobytes(), keys, header_rows=rows)
    (d, z), peak = _peak(read_profile, path, lateral_offset=0.31)
    assert np.allclose(d, s) and np.allclose(z, 0.01 * np.sin(s) + 0.002 * 0.31, atol=1e-6)
    assert peak < 2.5, f"{peak:.2f} MB traced for {grid.nbytes / 1e6:.0f} MB of data"


# -- through ISORoad.fmu ------------------------------------------------------------------------

def _long_line(path):
    path.write_bytes(b"0," + b"1" * 1_000_000)


def _garbage(path):
    path.write_bytes(np.random.default_rng(2).bytes(1_000_000))


def _claims(path):
    _crg(path, "KRBI", ["long section at v = 0,m"], 2, np.zeros(2, ">f4").tobytes(), header_rows=10**9)


@pytest.mark.parametrize("name, write, words", [
    ("long.csv", _long_line, "line 1 is longer than"),
    ("garbage.csv", _garbage, "NUL bytes"),
    ("claims.crg", _claims, "announces 1000000000 rows"),
])
def test_a_hostile_profile_file_is_refused_by_the_fmu(driven, tmp_path, name, write, words):
    write(tmp_path / name)
    road = driven("ISORoad", profile_file=str(tmp_path / name))
    assert any(status == 3 and "profile_file" in m and words in m for status, m in road.messages), road.messages
    for _ in range(2):
        with pytest.raises(FMICallException, match="discard"):
            road.step(0.01, vehicle_speed=10.0)
    # the host goes on: another instance of the same FMU runs
    good = driven("ISORoad", profile_file=str(_csv(tmp_path / "good.csv", 200)))
    out = good.run(0.01, 10, ["road_height", "distance"], vehicle_speed=10.0)
    assert np.allclose(out[:, 1], 0.1 * np.arange(1, 11))


def test_a_relative_profile_file_names_a_file_in_the_fmu_resources(dist, driven, tmp_path, monkeypatch):
    # in the working directory only: refused, naming the path tried and what to do
    monkeypatch.chdir(tmp_path)
    _csv(tmp_path / "road.csv", 300)
    road = driven("ISORoad", profile_file="road.csv")
    refusal = [m for status, m in road.messages if status == 3]
    assert refusal and "profile_file = 'road.csv' is a relative path" in refusal[0], road.messages
    assert "resources" in refusal[0] and "road.csv' does not exist" in refusal[0]
    assert "give an absolute path" in refusal[0]
    with pytest.raises(FMICallException, match="discard"):
        road.step(0.01)
    # shipped in the FMU's resources folder: read from there
    fmu = tmp_path / "ISORoad.fmu"
    shutil.copy(dist / "ISORoad.fmu", fmu)
    with zipfile.ZipFile(fmu, "a") as z:
        z.write(_csv(tmp_path / "shipped.csv", 300, start=100.0), "resources/roads/shipped.csv")
    from fmu_driver import Driven

    shipped = Driven(fmu, {"profile_file": "roads/shipped.csv"})
    try:
        out = shipped.run(0.01, 100, ["road_height", "distance"], vehicle_speed=2.0)
        assert not any(status >= 3 for status, _ in shipped.messages), shipped.messages
        assert np.allclose(out[:, 0], np.interp(100.0 + out[:, 1], 100.0 + 0.01 * np.arange(300),
                                                0.01 * np.sin(100.0 + 0.01 * np.arange(300))), atol=1e-5)
    finally:
        shipped.close()

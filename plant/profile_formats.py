"""Measured longitudinal profiles as users have them: columns (CSV / whitespace), ProVAL's ERD
text files and ASAM OpenCRG (.crg, binary and ASCII layouts).

``read_profile(path, units, lateral_offset)`` returns (distance m, elevation m) with distance
strictly increasing; the elevations are kept as they are (absolute levels of any magnitude: the
plant settles on the first value). Every problem raises ``ProfileError`` naming the file (and
the line or key).

Units (m, cm, mm, km, ft, in) come from the ``units`` argument when given ("mm" for the elevation,
or "ft,in" for distance, elevation), else from the file: a column header such as
``distance (ft), elevation [mm]`` or ``dist_m, elev_mm``, ERD's XUNITS / UNITSNAMES, or the
OpenCRG channel unit; else metres.

OpenCRG (ASAM OpenCRG 1.2 specification, "Data file structure" and "Road data"): header sections
``$ROAD_CRG`` (reference_line_start_u / _increment, long_section_v_right / _left / _increment,
reference_line_start_z) and ``$KD_DEFINITION`` (``#:KRBI`` / ``#:KDBI`` big-endian float32 / 64
filling 80-byte records, ``#:LRFI`` / ``#:LDFI`` text in fixed 10 / 20 character fields, a
field starting with '*' is missing; one ``D:`` line per column: ``reference line slope``,
``reference line banking``, ``long section N`` or ``long section at v = X``). The profile is
the elevation along the reference line (distance u) at the lateral offset v, linear between the
two nearest long sections, plus the reference line's own height (start z and the integrated
slope channel) and banking * v. Modifiers ($ROAD_CRG_MODS) are not applied; file references
($ROAD_CRG_FILE) are refused. Missing values inside the profile are refused.

ERD (UMTRI's ERD file, as ProVAL exports it): a first line starting ``ERDFILE``, a second line
``NCHAN, NSAMP, ..., format, DX, X0`` (format < 0: text data in this file; the binary layout
keeps its data in a .bin companion and is refused), keyword lines (XUNITS, UNITSNAMES,
SCALEFACTORS, ...) and ``END``, then NSAMP rows of NCHAN numbers; the first channel is used.

Files come from outside, so they are read within fixed bounds (the constants below): a text line
is read at most MAX_LINE characters at a time (a longer one is refused without being read
whole), at most MAX_POINTS points are kept and MAX_OTHER_LINES lines that are not data (headers,
comments, blank lines) read, the sizes a header claims (ERD's NSAMP, OpenCRG's rows from the
reference line's start, end and increment) are checked against these limits before anything of
their size is allocated and then against the data, and of an OpenCRG file only the channels of
the driven line are kept. Reading stops at the first limit crossed; docs/real-roads.md gives the
time and memory measured.
"""
from __future__ import annotations

import itertools
import math
import os
import re
from array import array
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np

LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3, "ft": 0.3048, "in": 0.0254}

# Most points of a profile: 125 km at a profiler's 25 mm, 50 km at 1 cm. The road keeps 24 bytes
# a point (distance, elevation, slope): 120 MB at the limit.
MAX_POINTS = 5_000_000
# Longest text line (characters): a data row is a few numbers, an OpenCRG ASCII record 80
# characters, a header line a keyword and its values. Binary data or a file without line ends is
# refused after this much of its first line.
MAX_LINE = 65_536
# Most lines that are not data (headers, comments, blank lines): a header that never ends.
MAX_OTHER_LINES = 100_000
# OpenCRG binary data is read this many bytes at a time (only the driven channels are kept)
_CHUNK = 1 << 20


class ProfileError(ValueError):
    """A measured profile file that cannot be used."""


def parse_units(units: str, where: str = "profile_units") -> tuple[float | None, float | None]:
    """(distance factor, elevation factor) to metres from "", "mm" (elevation) or "ft,in"."""
    text = (units or "").strip().lower()
    if not text:
        return None, None
    parts = [p.strip() for p in text.split(",")]
    bad = [p for p in parts if p not in LENGTH_UNITS]
    if bad or len(parts) > 2:
        raise ProfileError(f"{where} = {units!r}: expected a unit of {', '.join(LENGTH_UNITS)} "
                           "(elevation) or two separated by a comma (distance, elevation)")
    if len(parts) == 1:
        return None, LENGTH_UNITS[parts[0]]
    return LENGTH_UNITS[parts[0]], LENGTH_UNITS[parts[1]]


def _unit_in(path: Path, name: str) -> float | None:
    """The length unit a column name carries: 'elevation (mm)', 'x [ft]' (refused if unknown),
    'elev_mm' (only a known unit counts: 'road_profile' has none)."""
    text = name.strip().lower()
    if m := re.search(r"[\(\[]\s*([a-z]+)\s*[\)\]]", text):
        if m.group(1) not in LENGTH_UNITS:
            raise ProfileError(f"profile_file '{path}': column '{name.strip()}' has the unit {m.group(1)!r}, "
                               f"not one of {', '.join(LENGTH_UNITS)}")
        return LENGTH_UNITS[m.group(1)]
    m = re.search(r"_([a-z]+)$", text)
    return LENGTH_UNITS.get(m.group(1)) if m else None


def _finish(path: Path, dist: np.ndarray, elev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if len(dist) < 2:
        raise ProfileError(f"profile_file '{path}' holds {len(dist)} data rows; at least 2 are needed")
    if not np.all(np.isfinite(dist)):  # a column's number times its unit
        row = int(np.flatnonzero(~np.isfinite(dist))[0]) + 1
        raise ProfileError(f"profile_file '{path}': non-finite distance at row {row}")
    bad = np.flatnonzero(~np.isfinite(elev))
    if len(bad):
        raise ProfileError(f"profile_file '{path}': {len(bad)} missing or non-finite elevations "
                           f"(first at {dist[bad[0]]:g} m)")
    step = np.diff(dist)
    if np.any(step <= 0):
        i = int(np.flatnonzero(step <= 0)[0])
        raise ProfileError(f"profile_file '{path}': distance {dist[i + 1]:g} m does not increase "
                           f"(previous {dist[i]:g} m)")
    return dist, elev


def text_lines(path: Path, f: BinaryIO, first: int = 1, error: type[Exception] = ProfileError,
               label: str = "profile_file ") -> Iterator[tuple[int, bytes]]:
    """(line number, line without its end) of a file opened in binary mode from its position on;
    a line longer than MAX_LINE characters is refused (``error``) having read MAX_LINE + 2 of them."""
    for lineno in itertools.count(first):
        line = f.readline(MAX_LINE + 2)  # and its end, \r\n
        if not line:
            return
        text = line.rstrip(b"\r\n")
        if len(text) > MAX_LINE:
            raise error(f"{label}'{path}' line {lineno} is longer than {MAX_LINE} characters, "
                        "the limit of a text line: binary data, or a file without line ends?")
        yield lineno, text


def _grid(path: Path, start: float, step: float, n: int, factor: float) -> np.ndarray:
    """Distances (start + step k) factor, k = 0 .. n - 1, in m; refused unless all are finite."""
    last = (start + step * (n - 1)) * factor
    if not math.isfinite(last):
        raise ProfileError(f"profile_file '{path}': the distance of row {n} is {last} m (a start or an "
                           "increment too large)")
    return (start + step * np.arange(n)) * factor


def _too_many_points(path: Path, what: str) -> ProfileError:
    return ProfileError(f"profile_file '{path}': {what}; at most {MAX_POINTS} points are read "
                        "(MAX_POINTS of plant/profile_formats.py): cut the profile into parts")


def _count_other(path: Path, lineno: int, other: int) -> int:
    """``other`` + 1, the lines that are not data so far; refused past MAX_OTHER_LINES."""
    if other >= MAX_OTHER_LINES:
        raise ProfileError(f"profile_file '{path}' line {lineno}: more than {MAX_OTHER_LINES} lines that "
                           "are not data (headers, comments, blank lines)")
    return other + 1


def read_columns(path: Path, units: str = "") -> tuple[np.ndarray, np.ndarray]:
    """Distance and elevation columns, CSV / ';' / whitespace separated; '#' comments; one header
    line before the data may name the units."""
    d_unit, e_unit = parse_units(units)
    dist, elev = array("d"), array("d")
    header_units = (None, None)
    other = 0
    with open(path, "rb") as f:
        for lineno, line in text_lines(path, f):
            parts = line.replace(b",", b" ").replace(b";", b" ").split()
            if not parts or parts[0].startswith(b"#"):
                other = _count_other(path, lineno, other)
                continue
            try:
                a, b = float(parts[0]), float(parts[1])
            except (ValueError, IndexError):
                text = line.decode("utf-8", errors="replace").strip()
                if not dist and not text[:1].isdigit():
                    other = _count_other(path, lineno, other)
                    names = re.split(r"[,;\t]|\s{2,}", text) if re.search(r"[,;\t]", text) else text.split()
                    if len(names) >= 2:
                        header_units = (_unit_in(path, names[0]), _unit_in(path, names[1]))
                    continue  # a header line before the data
                raise ProfileError(f"profile_file '{path}' line {lineno}: expected two numbers "
                                   f"(distance, elevation), got {text[:60]!r}") from None
            if not (math.isfinite(a) and math.isfinite(b)):
                raise ProfileError(f"profile_file '{path}' line {lineno}: non-finite value "
                                   f"{line.decode('utf-8', errors='replace').strip()[:60]!r}")
            if dist and a <= dist[-1]:
                raise ProfileError(f"profile_file '{path}' line {lineno}: distance {a:g} does not "
                                   f"increase (previous {dist[-1]:g})")
            if len(dist) == MAX_POINTS:
                raise _too_many_points(path, f"line {lineno} is data row {MAX_POINTS + 1}")
            dist.append(a)
            elev.append(b)
    fd = d_unit or header_units[0] or 1.0
    fe = e_unit or header_units[1] or 1.0
    return _finish(path, fd * np.frombuffer(dist), fe * np.frombuffer(elev))


def read_erd(path: Path, units: str = "") -> tuple[np.ndarray, np.ndarray]:
    """The first channel of an ERD text file (see the module doc)."""
    d_unit, e_unit = parse_units(units)
    with open(path, "rb") as f:
        lines = text_lines(path, f)
        next(lines, None)  # ERDFILE...
        second = next(lines, (2, b""))[1]
        try:
            head = [float(x) for x in second.replace(b",", b" ").split()[:6]]
            nchan, nsamp, form, dx, x0 = head[0], head[1], head[3], head[4], head[5]
        except (IndexError, ValueError):
            raise ProfileError(f"profile_file '{path}' line 2: expected 'NCHAN, NSAMP, NPASS, FORMAT, DX, X0'") \
                from None
        if form >= 0:
            raise ProfileError(f"profile_file '{path}': binary ERD data (format {form:g}, a .bin companion) "
                               "is not read; export the text layout")
        if not (1 <= nchan < math.inf and 2 <= nsamp < math.inf and 0 < dx < math.inf and math.isfinite(x0)):
            raise ProfileError(f"profile_file '{path}' line 2: NCHAN = {nchan:g}, NSAMP = {nsamp:g}, DX = {dx:g}, "
                               f"X0 = {x0:g} must be >= 1, >= 2, > 0 and finite")
        if nsamp > MAX_POINTS:
            raise _too_many_points(path, f"line 2 announces NSAMP = {nsamp:g} points")
        nchan, nsamp = int(nchan), int(nsamp)
        keys: dict[str, list[str]] = {}
        for lineno, line in lines:
            word, _, rest = line.decode("latin-1").strip().partition(" ")
            if word.upper() == "END":
                break
            if lineno > MAX_OTHER_LINES:
                raise ProfileError(f"profile_file '{path}': no END line within the first {MAX_OTHER_LINES} lines")
            keys[word.upper().rstrip("S")] = [v.strip() for v in rest.replace(",", " ").split()]
        else:
            raise ProfileError(f"profile_file '{path}': no END line closes the ERD header")
        # NSAMP rows of NCHAN numbers, in any number of lines: only the first channel is kept
        need = nchan * nsamp
        elev = np.empty(nsamp)
        count = other = 0
        for lineno, line in lines:
            parts = line.replace(b",", b" ").split()
            if not parts:
                other = _count_other(path, lineno, other)
                continue
            if count + len(parts) > need:
                raise ProfileError(f"profile_file '{path}' line {lineno}: more numbers after END than the "
                                   f"{nchan} x {nsamp} announced")
            try:
                for j in range(-count % nchan, len(parts), nchan):
                    elev[(count + j) // nchan] = float(parts[j])
            except ValueError:
                raise ProfileError(f"profile_file '{path}' line {lineno}: {parts[j][:30].decode('latin-1')!r} "
                                   "is not a number") from None
            count += len(parts)
    if count < need:
        raise ProfileError(f"profile_file '{path}': {count} numbers after END, {nchan} x {nsamp} announced")
    try:
        scale = float((keys.get("SCALEFACTOR") or ["1"])[0])
    except ValueError:
        scale = math.nan
    if not math.isfinite(scale):
        raise ProfileError(f"profile_file '{path}': SCALEFACTORS {keys['SCALEFACTOR'][0]!r} is not a finite number")
    x_unit = LENGTH_UNITS.get(keys.get("XUNIT", ["m"])[0].lower())
    e_file = LENGTH_UNITS.get((keys.get("UNITSNAME") or ["m"])[0].lower())
    dist = _grid(path, x0, dx, nsamp, d_unit or x_unit or 1.0)
    return _finish(path, dist, elev * scale * (e_unit or e_file or 1.0))


def _crg_sections(path: Path) -> tuple[dict[str, str], list[str], str, tuple[int, int]]:
    """($ROAD_CRG keys lower-cased, D: channel lines, format, (byte offset, line number) of the
    road data)."""
    keys: dict[str, str] = {}
    channels: list[str] = []
    fmt = "KRBI"
    section = ""
    with open(path, "rb") as f:
        for lineno, raw in text_lines(path, f):
            if lineno > MAX_OTHER_LINES:
                raise ProfileError(f"profile_file '{path}': the OpenCRG header does not end (a line of '$$$$') "
                                   f"within its first {MAX_OTHER_LINES} lines")
            line = raw.decode("latin-1")
            if line.startswith("$"):
                word = line[1:].split("!")[0].strip().upper()
                if word.startswith("$$"):  # '$$$$...': the road data follows
                    return keys, channels, fmt, (f.tell(), lineno + 1)
                if word == "ROAD_CRG_FILE":
                    raise ProfileError(f"profile_file '{path}': OpenCRG file references ($ROAD_CRG_FILE) "
                                       "are not supported")
                section = word
                continue
            if line.startswith("*") or line.startswith("%"):
                continue
            text = line.split("!")[0].strip()
            if section == "ROAD_CRG" and "=" in text:
                k, _, v = text.partition("=")
                keys[k.strip().lower()] = v.strip()
            elif section == "KD_DEFINITION":
                if text.startswith("#:"):
                    fmt = text[2:6].upper()
                elif text.upper().startswith("D:"):
                    channels.append(text[2:].strip())
    raise ProfileError(f"profile_file '{path}': no road data section (a line of '$$$$' ends the header)")


def _crg_binary(path: Path, f: BinaryIO, fmt: str, ncols: int, rows: int | None, cols: list[int]) -> np.ndarray:
    size = 4 if fmt == "KRBI" else 8
    row_bytes = ncols * size
    have = os.fstat(f.fileno()).st_size - f.tell()
    if rows is not None:  # checked before reading: a header may claim any size
        need = rows * row_bytes
        if have not in (need, -(-need // 80) * 80):
            raise ProfileError(
                f"profile_file '{path}': the binary road data holds {have} bytes, {need} expected "
                f"({rows} rows of {ncols} channels, #:{fmt}, padded to 80-byte records): the file is "
                "damaged (a line-ending conversion of a binary file drops bytes) or its header is wrong")
    else:
        rows = have // row_bytes
        if rows > MAX_POINTS:
            raise _too_many_points(path, f"the binary road data holds {rows} rows")
    dtype = np.dtype(">f4" if size == 4 else ">f8")
    out = np.empty((rows, len(cols)))
    chunk = max(1, _CHUNK // row_bytes)
    for start in range(0, rows, chunk):
        n = min(chunk, rows - start)
        out[start:start + n] = np.frombuffer(f.read(n * row_bytes), dtype).reshape(n, ncols)[:, cols]
    return out


def _crg_ascii(path: Path, f: BinaryIO, fmt: str, ncols: int, rows: int | None, cols: list[int],
               first: int) -> np.ndarray:
    width = 10 if fmt == "LRFI" else 20
    per_row = -(-ncols // (80 // width))  # 80-character records a row spans
    limit = MAX_POINTS if rows is None else rows
    kept = array("d")
    n = other = 0
    row: list[str] = []
    for lineno, raw in text_lines(path, f, first):
        if not raw.strip():
            other = _count_other(path, lineno, other)
            continue
        row.append(raw.decode("latin-1"))
        if len(row) < per_row:
            continue
        n += 1
        if n > limit:
            if rows is None:
                raise _too_many_points(path, f"line {lineno} ends road data row {n}")
            raise ProfileError(f"profile_file '{path}' line {lineno}: more road data rows than the {rows} "
                               "its header announces (reference_line_start_u, _end_u, _increment)")
        fields = [ln[i:i + width] for ln in row for i in range(0, len(ln), width)]
        if len(fields) < ncols:
            raise ProfileError(f"profile_file '{path}': road data row {n} holds {len(fields)} of {ncols} numbers")
        try:
            kept.extend(math.nan if fields[j].strip().startswith("*") else float(fields[j]) for j in cols)
        except ValueError:
            raise ProfileError(f"profile_file '{path}': road data row {n} is not "
                               f"{ncols} numbers in {width}-character fields") from None
        row = []
    if row:
        raise ProfileError(f"profile_file '{path}': the road data ends inside row {n + 1} "
                           f"({len(row)} of its {per_row} lines)")
    if rows is not None and n != rows:
        raise ProfileError(f"profile_file '{path}': the road data holds {n} rows, its header announces {rows} "
                           "(reference_line_start_u, _end_u, _increment)")
    return np.array(kept).reshape(n, len(cols))


def _crg_data(path: Path, start: tuple[int, int], fmt: str, ncols: int, rows: int | None,
              cols: list[int]) -> np.ndarray:
    """The channels ``cols`` of the road data as a (rows, len(cols)) array; ``start`` (byte offset,
    line number) of the data, ``rows`` announced by the header (None: as many as there are). The
    other channels are read and dropped."""
    if fmt not in ("KRBI", "KDBI", "LRFI", "LDFI"):
        raise ProfileError(f"profile_file '{path}': OpenCRG data format #:{fmt} is not one of KRBI, KDBI, LRFI, LDFI")
    with open(path, "rb") as f:
        f.seek(start[0])
        if fmt in ("KRBI", "KDBI"):
            return _crg_binary(path, f, fmt, ncols, rows, cols)
        return _crg_ascii(path, f, fmt, ncols, rows, cols, start[1])


def read_crg(path: Path, units: str = "", lateral_offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Elevation along the reference line of an OpenCRG file at lateral offset v (m, left > 0)."""
    keys, channels, fmt, start = _crg_sections(path)

    def num(name: str, default: float | None = None) -> float:
        if name not in keys:
            if default is None:
                raise ProfileError(f"profile_file '{path}': $ROAD_CRG has no {name}")
            return default
        try:
            value = float(keys[name])
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise ProfileError(f"profile_file '{path}': {name} = {keys[name]!r} is not a finite number")
        return value

    du = num("reference_line_increment")
    if du <= 0:
        raise ProfileError(f"profile_file '{path}': reference_line_increment = {du:g} must be > 0")
    u0 = num("reference_line_start_u", 0.0)
    rows = None
    if "reference_line_end_u" in keys:
        span = (num("reference_line_end_u") - u0) / du  # rows - 1, +-inf if the difference overflows
        if span > MAX_POINTS - 0.5:
            raise _too_many_points(path, f"its header announces {span + 1:.10g} rows (reference_line_start_u, "
                                   "_end_u, _increment)")
        if span < 0.5:
            raise ProfileError(f"profile_file '{path}': reference_line_start_u, _end_u and _increment give "
                               f"{span + 1:.10g} rows; at least 2 are needed")
        rows = round(span) + 1
    sections: list[tuple[float, int]] = []
    slope = bank = None
    n_numbered = sum(1 for c in channels if re.match(r"long section \d+", c, re.I))
    dv = num("long_section_v_increment", 0.0) if n_numbered else 0.0
    v_right = num("long_section_v_right", -0.5 * dv * (n_numbered - 1))
    unit = None
    for j, c in enumerate(channels):
        name, _, cunit = c.partition(",")
        name = name.strip().lower()
        if m := re.match(r"long section at v\s*=\s*([-+0-9.eE]+)", name):
            try:
                v = float(m.group(1))
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise ProfileError(f"profile_file '{path}': channel 'D:{c}' has no finite v")
            sections.append((v, j))
            unit = cunit.strip().lower() or unit
        elif m := re.match(r"long section (\d+)", name):
            sections.append((v_right + (int(m.group(1)) - 1) * dv, j))
            unit = cunit.strip().lower() or unit
        elif name == "reference line slope":
            slope = j
        elif name == "reference line banking":
            bank = j
    if not sections:
        raise ProfileError(f"profile_file '{path}': no 'long section' channel in $KD_DEFINITION")
    sections.sort()
    vs = np.array([v for v, _ in sections])
    if len(vs) > 1 and np.any(np.diff(vs) <= 0):
        same = vs[np.flatnonzero(np.diff(vs) <= 0)[0]]
        raise ProfileError(f"profile_file '{path}': two long sections at v = {same:g} m "
                           "(long_section_v_right, long_section_v_increment or 'long section at v = X')")
    if not vs[0] - 1e-9 <= lateral_offset <= vs[-1] + 1e-9:
        raise ProfileError(f"profile_lateral_offset = {lateral_offset!r} m is outside the road of "
                           f"'{path}' [{vs[0]:g}, {vs[-1]:g}] m")
    i = int(np.clip(np.searchsorted(vs, lateral_offset, side="right") - 1, 0, max(len(vs) - 2, 0)))
    w = 0.0 if len(vs) == 1 else float(np.clip((lateral_offset - vs[i]) / (vs[i + 1] - vs[i]), 0.0, 1.0))
    # only the channels of the driven line are kept; on a section, its values only (a neighbour
    # may be missing)
    driven = [sections[i + int(w)][1]] if w in (0.0, 1.0) else [sections[i][1], sections[i + 1][1]]
    data = _crg_data(path, start, fmt, len(channels), rows, driven + [j for j in (slope, bank) if j is not None])
    z = data[:, 0] if len(driven) == 1 else (1 - w) * data[:, 0] + w * data[:, 1]
    d_unit, e_unit = parse_units(units)
    z = z * (e_unit or LENGTH_UNITS.get(unit or "m") or 1.0)
    ref = np.full(len(z), num("reference_line_start_z", 0.0))
    k = len(driven)
    if slope is not None:  # the reference line's own height: trapezoid of its slope
        s = data[:, k]
        ref += np.concatenate(([0.0], np.cumsum(0.5 * (s[1:] + s[:-1]) * du)))
        k += 1
    if bank is not None:
        ref += data[:, k] * lateral_offset
    return _finish(path, _grid(path, u0, du, len(z), d_unit or 1.0), z + ref)


def read_profile(path: str | Path, units: str = "", lateral_offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(distance m, elevation m) of a measured profile in any of the formats above."""
    path = Path(path)
    if not path.is_file():
        raise ProfileError(f"profile_file '{path}' does not exist")
    with open(path, "rb") as f:
        first = f.read(4096)
    text = first.decode("latin-1").lstrip()
    if path.suffix.lower() == ".crg" or text.startswith("$CT") or text.startswith("$ROAD_CRG"):
        return read_crg(path, units, lateral_offset)
    if b"\0" in first:
        raise ProfileError(f"profile_file '{path}' holds NUL bytes in its first {len(first)} bytes: binary "
                           "(or UTF-16) data, not a text profile; an OpenCRG file needs the suffix .crg")
    if text.upper().replace(" ", "").startswith("ERDFILE"):
        return read_erd(path, units)
    return read_columns(path, units)

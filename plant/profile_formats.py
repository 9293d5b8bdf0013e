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
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3, "ft": 0.3048, "in": 0.0254}


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


def read_columns(path: Path, units: str = "") -> tuple[np.ndarray, np.ndarray]:
    """Distance and elevation columns, CSV / ';' / whitespace separated; '#' comments; one header
    line before the data may name the units."""
    d_unit, e_unit = parse_units(units)
    dist, elev = [], []
    header_units = (None, None)
    with open(path, encoding="utf-8", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            parts = text.replace(",", " ").replace(";", " ").split()
            try:
                a, b = float(parts[0]), float(parts[1])
            except (ValueError, IndexError):
                if not dist and not any(ch.isdigit() for ch in text.split()[0][:1]):
                    names = re.split(r"[,;\t]|\s{2,}", text) if re.search(r"[,;\t]", text) else text.split()
                    if len(names) >= 2:
                        header_units = (_unit_in(path, names[0]), _unit_in(path, names[1]))
                    continue  # a header line before the data
                raise ProfileError(f"profile_file '{path}' line {lineno}: expected two numbers "
                                   f"(distance, elevation), got {text[:60]!r}") from None
            if not (math.isfinite(a) and math.isfinite(b)):
                raise ProfileError(f"profile_file '{path}' line {lineno}: non-finite value {text[:60]!r}")
            if dist and a <= dist[-1]:
                raise ProfileError(f"profile_file '{path}' line {lineno}: distance {a:g} does not "
                                   f"increase (previous {dist[-1]:g})")
            dist.append(a)
            elev.append(b)
    fd = d_unit or header_units[0] or 1.0
    fe = e_unit or header_units[1] or 1.0
    return _finish(path, fd * np.array(dist), fe * np.array(elev))


def read_erd(path: Path, units: str = "") -> tuple[np.ndarray, np.ndarray]:
    """The first channel of an ERD text file (see the module doc)."""
    d_unit, e_unit = parse_units(units)
    with open(path, encoding="latin-1") as f:
        lines = f.read().splitlines()
    try:
        head = [float(x) for x in lines[1].replace(",", " ").split()]
        nchan, nsamp, form, dx, x0 = int(head[0]), int(head[1]), head[3], head[4], head[5]
    except (IndexError, ValueError):
        raise ProfileError(f"profile_file '{path}' line 2: expected 'NCHAN, NSAMP, NPASS, FORMAT, DX, X0'") from None
    if form >= 0:
        raise ProfileError(f"profile_file '{path}': binary ERD data (format {form:g}, a .bin companion) "
                           "is not read; export the text layout")
    if not (nchan >= 1 and nsamp >= 2 and dx > 0):
        raise ProfileError(f"profile_file '{path}' line 2: NCHAN = {nchan}, NSAMP = {nsamp}, DX = {dx:g} "
                           "must be >= 1, >= 2 and > 0")
    keys: dict[str, list[str]] = {}
    end = None
    for i, line in enumerate(lines[2:], 2):
        word, _, rest = line.strip().partition(" ")
        if word.upper() == "END":
            end = i
            break
        keys[word.upper().rstrip("S")] = [v.strip() for v in rest.replace(",", " ").split()]
    if end is None:
        raise ProfileError(f"profile_file '{path}': no END line closes the ERD header")
    values = np.array(" ".join(lines[end + 1:]).replace(",", " ").split(), dtype=float)
    if len(values) < nchan * nsamp:
        raise ProfileError(f"profile_file '{path}': {len(values)} numbers after END, "
                           f"{nchan} x {nsamp} announced")
    elev = values[:nchan * nsamp].reshape(nsamp, nchan)[:, 0]
    scale = float(keys.get("SCALEFACTOR", ["1"])[0])
    x_unit = LENGTH_UNITS.get(keys.get("XUNIT", ["m"])[0].lower())
    e_file = LENGTH_UNITS.get((keys.get("UNITSNAME") or ["m"])[0].lower())
    dist = (x0 + dx * np.arange(nsamp)) * (d_unit or x_unit or 1.0)
    return _finish(path, dist, elev * scale * (e_unit or e_file or 1.0))


def _crg_sections(path: Path) -> tuple[dict[str, str], list[str], str, int]:
    """($ROAD_CRG keys lower-cased, D: channel lines, format, byte offset of the road data)."""
    raw = path.read_bytes()
    keys: dict[str, str] = {}
    channels: list[str] = []
    fmt = "KRBI"
    section = ""
    pos = 0
    while pos < len(raw):
        nl = raw.find(b"\n", pos)
        line = raw[pos:(len(raw) if nl < 0 else nl)].decode("latin-1").rstrip("\r")
        pos = len(raw) if nl < 0 else nl + 1
        if line.startswith("$"):
            word = line[1:].split("!")[0].strip().upper()
            if word.startswith("$$"):  # '$$$$...': the road data follows
                return keys, channels, fmt, pos
            if word == "ROAD_CRG_FILE":
                raise ProfileError(f"profile_file '{path}': OpenCRG file references ($ROAD_CRG_FILE) are not supported")
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


def _crg_data(path: Path, raw: bytes, fmt: str, ncols: int, rows: int | None) -> np.ndarray:
    """The road data as a (rows, ncols) array; ``rows`` announced by the header (None: as many
    as there are)."""
    if fmt in ("KRBI", "KDBI"):
        size = 4 if fmt == "KRBI" else 8
        if rows is not None:
            need = rows * ncols * size
            if len(raw) not in (need, -(-need // 80) * 80):
                raise ProfileError(
                    f"profile_file '{path}': the binary road data holds {len(raw)} bytes, {need} expected "
                    f"({rows} rows of {ncols} channels, #:{fmt}, padded to 80-byte records): the file is "
                    "damaged (a line-ending conversion of a binary file drops bytes) or its header is wrong")
        else:
            rows = len(raw) // (ncols * size)
        flat = np.frombuffer(raw[:rows * ncols * size], dtype=">f4" if size == 4 else ">f8")
        return flat.astype(float).reshape(rows, ncols)
    if fmt not in ("LRFI", "LDFI"):
        raise ProfileError(f"profile_file '{path}': OpenCRG data format #:{fmt} is not one of KRBI, KDBI, LRFI, LDFI")
    width = 10 if fmt == "LRFI" else 20
    per_record = 80 // width
    lines = [ln.rstrip("\r") for ln in raw.decode("latin-1").split("\n")]
    lines = [ln for ln in lines if ln.strip()]
    per_row = -(-ncols // per_record)
    rows = []
    for r in range(0, len(lines) - per_row + 1, per_row):
        fields = []
        for ln in lines[r:r + per_row]:
            fields += [ln[i:i + width] for i in range(0, len(ln), width)]
        try:
            rows.append([math.nan if f.strip().startswith("*") else float(f) for f in fields[:ncols]])
        except ValueError:
            raise ProfileError(f"profile_file '{path}': road data row {len(rows) + 1} is not "
                               f"{ncols} numbers in {width}-character fields") from None
        if len(rows[-1]) != ncols:
            raise ProfileError(f"profile_file '{path}': road data row {len(rows)} holds {len(rows[-1])} "
                               f"of {ncols} numbers")
    return np.array(rows, float).reshape(-1, ncols)


def read_crg(path: Path, units: str = "", lateral_offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Elevation along the reference line of an OpenCRG file at lateral offset v (m, left > 0)."""
    keys, channels, fmt, start = _crg_sections(path)

    def num(name: str, default: float | None = None) -> float:
        if name in keys:
            try:
                return float(keys[name])
            except ValueError:
                raise ProfileError(f"profile_file '{path}': {name} = {keys[name]!r} is not a number") from None
        if default is None:
            raise ProfileError(f"profile_file '{path}': $ROAD_CRG has no {name}")
        return default

    du = num("reference_line_increment")
    u0 = num("reference_line_start_u", 0.0)
    rows = round((num("reference_line_end_u") - u0) / du) + 1 if "reference_line_end_u" in keys else None
    data = _crg_data(path, path.read_bytes()[start:], fmt, len(channels), rows)
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
            sections.append((float(m.group(1)), j))
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
    if not vs[0] - 1e-9 <= lateral_offset <= vs[-1] + 1e-9:
        raise ProfileError(f"profile_lateral_offset = {lateral_offset!r} m is outside the road of "
                           f"'{path}' [{vs[0]:g}, {vs[-1]:g}] m")
    i = int(np.clip(np.searchsorted(vs, lateral_offset, side="right") - 1, 0, max(len(vs) - 2, 0)))
    w = 0.0 if len(vs) == 1 else float(np.clip((lateral_offset - vs[i]) / (vs[i + 1] - vs[i]), 0.0, 1.0))
    if w == 0.0 or w == 1.0:  # on a section: its values only (a neighbour may be missing)
        z = data[:, sections[i + int(w)][1]]
    else:
        z = (1 - w) * data[:, sections[i][1]] + w * data[:, sections[i + 1][1]]
    d_unit, e_unit = parse_units(units)
    z = z * (e_unit or LENGTH_UNITS.get(unit or "m") or 1.0)
    u = u0 + du * np.arange(len(z))
    ref = np.full(len(z), num("reference_line_start_z", 0.0))
    if slope is not None:  # the reference line's own height: trapezoid of its slope
        s = data[:, slope]
        ref += np.concatenate(([0.0], np.cumsum(0.5 * (s[1:] + s[:-1]) * du)))
    if bank is not None:
        ref += data[:, bank] * lateral_offset
    return _finish(path, u * (d_unit or 1.0), z + ref)


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
    if text.upper().replace(" ", "").startswith("ERDFILE"):
        return read_erd(path, units)
    return read_columns(path, units)

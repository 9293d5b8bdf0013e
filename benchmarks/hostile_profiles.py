"""Time and peak memory of reading hostile profile files: refused, or read within a bound.

    .venv/bin/python benchmarks/hostile_profiles.py [--rows 10000000] [--dir DIR]

Writes each file into DIR (default: a temporary folder, removed afterwards) and reads it in a
fresh Python process, with ``read_profile`` (and ``MeasuredRoad.from_file``, what ISORoad.fmu
does, for the file at the limit), so that each peak is its own. Prints per file its size, the
outcome (points read, or the start of the refusal), the wall time of the read and the process's
peak resident memory (VmHWM, Linux) above its level after the imports. The numbers are in
docs/real-roads.md.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from suspension_estimation.plant.profile_formats import MAX_POINTS  # noqa: E402

CHILD = """
import json, sys, time
from suspension_estimation.plant.profile_formats import ProfileError, read_profile
from suspension_estimation.plant.road import MeasuredRoad

def hwm():  # peak resident memory of this process (MB); ru_maxrss would count the parent's at fork
    return int(open("/proc/self/status").read().split("VmHWM:")[1].split()[0]) / 1024

base = hwm()
path, road = sys.argv[1], sys.argv[2] == "road"
t = time.perf_counter()
try:
    n = len(MeasuredRoad.from_file(path)._curve.s) if road else len(read_profile(path)[0])
    outcome = f"read, {n} points"
except ProfileError as e:
    outcome = "refused: " + str(e).replace(f"profile_file '{path}'", "").lstrip(": ")[:90]
print(json.dumps({"outcome": outcome, "seconds": time.perf_counter() - t, "base_mb": base, "peak_mb": hwm() - base}))
"""


def write_csv(path: Path, rows: int) -> None:
    """distance_m, elevation_m every 1 cm, as a profiler exports them."""
    with open(path, "w") as f:
        f.write("distance_m,elevation_m\n")
        for start in range(0, rows, 1_000_000):
            s = 0.01 * np.arange(start, min(rows, start + 1_000_000))
            f.write("\n".join(map("{:.2f},{:.6f}".format, s.tolist(), (0.01 * np.sin(s)).tolist())) + "\n")


def crg_header(fmt: str, channels: int, rows: int, extra: str = "") -> bytes:
    return ("$CT\nwritten by benchmarks/hostile_profiles.py\n$ROAD_CRG\nreference_line_start_u = 0.0\n"
            f"reference_line_end_u = {0.01 * (rows - 1)}\nreference_line_increment = 0.01\n"
            f"long_section_v_right = -2.0\nlong_section_v_increment = {4.0 / (channels - 1)}\n{extra}"
            f"$KD_DEFINITION\n#:{fmt}\n" + "".join(f"D:long section {i + 1},m\n" for i in range(channels))
            + "$\n" + "$" * 72 + "\n").encode()


def write_cases(folder: Path, rows: int) -> list[tuple[str, Path, str]]:
    """(what, file, mode) of every case; mode 'road' builds the FMU's road, 'read' only reads."""
    cases = []

    def case(what: str, name: str, mode: str = "read") -> Path:
        path = folder / name
        cases.append((what, path, mode))
        return path

    write_csv(case(f"CSV, {rows:.0e} rows", "huge.csv"), rows)
    write_csv(case(f"CSV at the limit, {MAX_POINTS:.0e} rows", "limit.csv"), MAX_POINTS)
    cases.append(("the same, into ISORoad's road (PCHIP)", folder / "limit.csv", "road"))
    case("one line of 100 MB", "long_line.csv").write_bytes(b"1" * 100_000_000)
    case("100 MB of random bytes", "garbage.csv").write_bytes(os.urandom(100_000_000))
    case("100 MB of random bytes named .crg", "garbage.crg").write_bytes(os.urandom(100_000_000))
    case("OpenCRG header claiming 1e9 rows", "claims.crg").write_bytes(
        crg_header("KRBI", 5, 1_000_000_000) + np.zeros(1000, ">f4").tobytes())
    case("OpenCRG header that never ends (1e6 lines)", "endless.crg").write_bytes(
        b"$CT\n" + b"* a comment line\n" * 1_000_000)
    case("ERD claiming NSAMP = 1e12", "claims.erd").write_text(
        "ERDFILEV2.00\n1, 1000000000000, 1, -1, 0.01, 0.0, 0\nEND\n0.0\n0.1\n")
    n_crg = 100_000  # 1 km at 1 cm, 401 long sections at 1 cm across 4 m: 160 MB of float32
    data = np.tile(np.float32(0.001) * np.arange(401, dtype=">f4"), (n_crg, 1)).astype(">f4")
    case(f"OpenCRG binary, {n_crg:.0e} rows x 401 channels", "wide.crg").write_bytes(
        crg_header("KRBI", 401, n_crg) + data.tobytes())
    return cases


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=10_000_000, help="rows of the huge CSV (default 1e7)")
    ap.add_argument("--dir", type=Path, help="where to write the files (kept); default a temporary folder")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.dir or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print("| file | size MB | outcome | time s | peak memory MB |\n| --- | --- | --- | --- | --- |")
        base = []
        for what, path, mode in write_cases(folder, args.rows):
            proc = subprocess.run([sys.executable, "-c", CHILD, str(path), mode], capture_output=True, text=True,
                                  timeout=600)
            if proc.returncode != 0:
                print(f"| {what} | failed: {proc.stderr.strip()[-200:]} |")
                continue
            r = json.loads(proc.stdout)
            base.append(r["base_mb"])
            print(f"| {what} | {path.stat().st_size / 1e6:.0f} | {r['outcome']} | {r['seconds']:.2f} | "
                  f"{r['peak_mb']:.0f} |", flush=True)
        print(f"\npeak memory: VmHWM above the process's {min(base, default=0):.0f}-{max(base, default=0):.0f} MB "
              "after its imports")
    return 0


if __name__ == "__main__":
    sys.exit(main())

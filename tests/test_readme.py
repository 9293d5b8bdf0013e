"""The README's Python examples run as written, against the FMUs the tests build
(``dist/`` in the text is replaced by their folder), in a process of their own."""
from __future__ import annotations

import re
import subprocess
import sys

from conftest import ROOT


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_the_readme_examples_run_as_written(dist, tmp_path):
    blocks = python_blocks((ROOT / "README.md").read_text())
    assert blocks, "README.md has no python example"
    script = tmp_path / "readme_example.py"
    script.write_text("\n\n".join(b.replace('"dist/', f'"{dist}/') for b in blocks))
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    # a pythonfmu binary may abort the process at exit, after everything was printed (PythonFMU
    # issue 229): the printed lines decide, and no Python error may have happened
    assert "Traceback" not in proc.stderr, proc.stderr
    out = proc.stdout
    mass = re.search(r"sprung mass ([\d.]+) kg, ISO class (\d)", out)
    assert mass, out + proc.stderr
    assert abs(float(mass.group(1)) - 410.0) < 0.05 * 410.0 and mass.group(2) == "3"
    assert re.search(r"road: error std [\d.]+ mm, reported std [\d.]+ mm", out)
    # the refused parameter is reported with the FMU's reason, not as a silent short result
    assert "SuspensionEstimator.fmu stopped at t = 0.0 s" in out
    assert "forgetting_factor = 2.0 is outside the allowed range (0.9, 1]" in out

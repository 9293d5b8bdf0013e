"""harness/studies/: one module per study over one shared runner, without an import circle
(checked on the source's import statements, also those inside functions, and by importing each
module alone in a fresh interpreter), and the registry behind ``python -m suspension_estimation.harness paper --study``."""
from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

from suspension_estimation.harness.studies import STUDIES, load
from suspension_estimation.harness.studies.runner import RunSpec, Study, run_one
from suspension_estimation.harness.studies.suite import CHECKPOINT, FMUS, PaperStudy, read_checkpoint

ROOT = Path(__file__).resolve().parents[1]
H = "suspension_estimation.harness"  # the folder harness/ as installed
FILES = {".".join(["suspension_estimation", *p.relative_to(ROOT).with_suffix("").parts]).removesuffix(".__init__"): p
         for p in (ROOT / "harness").rglob("*.py")}
STUDY_MODULES = sorted(m for m in FILES if m.startswith(f"{H}.studies")) + [f"{H}.sweep"]


def _imports(module: str) -> set[str]:
    """The modules of ``harness`` that ``module`` imports anywhere in its source."""
    path = FILES[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            parts = package.split(".")
            base = ".".join(parts[:len(parts) - node.level + 1]) if node.level else ""
            prefix = ".".join(x for x in (base, node.module) if x)
            names = [prefix] + [f"{prefix}.{a.name}" for a in node.names]
        else:
            continue
        out |= {n for n in names if n in FILES and n != module}
    return out


def test_the_harness_has_no_import_circle():
    graph = {m: _imports(m) for m in FILES}
    assert {f"{H}.studies.runner", f"{H}.studies.paper000"} <= set(graph)  # the parser sees the package
    assert f"{H}.studies.runner" in graph[f"{H}.sweep"] and f"{H}.studies.runner" in graph[f"{H}.studies.paper001"]
    assert not {m for m in graph[f"{H}.studies.runner"] if m.startswith((f"{H}.studies", f"{H}.sweep"))}
    state: dict[str, int] = {}  # 1 on the path, 2 done

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for n in sorted(graph[m]):
            assert state.get(n) != 1, "import circle: " + " -> ".join(path[path.index(n):] + [n])
            if n not in state:
                visit(n, path + [n])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])


@pytest.mark.parametrize("module", STUDY_MODULES)
def test_each_module_imports_alone(module):
    proc = subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True, text=True, cwd=ROOT,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr


def test_every_registered_study_loads_under_its_name():
    for name in STUDIES:
        s = load(name)
        assert isinstance(s, Study) and s.name == name
    with pytest.raises(ValueError, match="no study 'robustness'.*table2, 10ms, mass, class"):
        load("robustness")


def test_the_studies_chosen_and_their_runs(tmp_path):
    assert PaperStudy().names == ("table2", "mass")
    assert PaperStudy(study10ms=True, class_seeds=1).names == ("table2", "10ms", "mass", "class")
    s = PaperStudy(studies=("class",), seeds=2, dist=tmp_path)
    assert s.names == ("class",) and s.class_seeds == 2  # --study class alone: --seeds seeds
    specs = s.specs()
    assert len(specs) == 5 * 3 * 2 and {x.study for x in specs} == {"class"}
    assert s.runs() == {"class": load("class").runs["class"]}
    both = PaperStudy(studies=("mass", "10ms"), seeds=1, classes=(3,), dist=tmp_path)
    assert [x.study for x in both.specs()] == ["table2_10ms"] * 6 + ["mass"]  # registry order


def test_a_run_without_its_function_fails_with_the_reason(tmp_path):
    r = run_one(RunSpec("mass", 3, 1, 1.0, 0.0, 1e-3, str(tmp_path)))
    assert not r["ok"] and "no run function" in r["error"] and "'mass'" in r["error"]


def test_cli_study_chooses_the_studies(dist, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "suspension_estimation.harness", "paper", "--study", "mass", "--seeds", "1", "--step",
                           "0.002", "-q", "--dist", str(dist), "--out", str(tmp_path)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    data = json.loads((tmp_path / "paper_runs.json").read_text())
    assert data["config"]["studies"] == ["mass"] and [r["spec"]["study"] for r in data["runs"]] == ["mass"]
    md = (tmp_path / "paper_tables.md").read_text()
    assert "(b) Vehicle-mass paper" in md and "(a) MME&KF" not in md
    assert sorted(f.name for f in tmp_path.iterdir()) == ["mass_paper001.png", "paper_runs.json", "paper_tables.md",
                                                          "runs.jsonl"]
    bad = subprocess.run([sys.executable, "-m", "suspension_estimation.harness", "paper", "--study", "nope", "--dist", str(dist)],
                         capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1 and "no study 'nope'" in bad.stderr, bad.stderr


def test_a_resumed_study_runs_only_what_the_checkpoint_lacks(dist, tmp_path):
    def study(resume: bool) -> PaperStudy:
        return PaperStudy(studies=("table2",), seeds=2, duration=0.3, warmup=0.1, classes=(3,), workers=1,
                          dist=dist, out=tmp_path, resume=resume).run(progress=False)

    first = study(False)
    n = len(first.results)
    assert n >= 2 and first.ran == n and first.reused == 0
    ck = tmp_path / CHECKPOINT
    lines = ck.read_text().splitlines()
    assert len(lines) == n + 1  # the FMU digests, then one line per run
    again = study(True)
    assert again.ran == 0 and again.reused == n
    # through JSON, so that NaN (a score a run does not define) compares equal to itself
    assert ([json.dumps(r["estimators"], sort_keys=True) for r in again.results]
            == [json.dumps(r["estimators"], sort_keys=True) for r in first.results])
    assert [r["spec"] for r in again.results] == [r["spec"] for r in first.results]
    tables = lambda s: s.markdown().split("## Where the time goes")[0]  # noqa: E731
    assert "PASS" in tables(first) or "MISS" in tables(first)
    assert tables(again) == tables(first)
    ck.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][:40])  # the last run torn mid-write
    third = study(True)
    assert third.ran == 1 and third.reused == n - 1
    assert [r["spec"] for r in third.results] == [r["spec"] for r in first.results]
    fresh = study(False)  # without resume the checkpoint starts again
    assert fresh.ran == n and len(ck.read_text().splitlines()) == n + 1
    other = tmp_path / "other"
    other.mkdir()
    for f in FMUS:
        (other / f).write_bytes((Path(dist) / f).read_bytes() + (b"x" if f == "QuarterCar.fmu" else b""))
    with pytest.raises(ValueError, match="other FMUs"):
        read_checkpoint(ck, other)

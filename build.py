"""Build the project's FMUs into dist/ and write the SSP systems that wire them.

    python build.py [--dist DIR] [--force] [NAME ...]
    python build.py --docs          # write docs/fmu-interface.md and the README's FMU table

Every FMU bundles the plain-Python core (plant/, estimators/) and the adapter package
fmu_src/suspension_fmi/. Before the FMUs are built, the road classifier's model
(estimators/data/response_class_iso.json, plain data bundled with estimators/) is trained again
from simulated data with fixed seeds (estimators.response_class_train) when its training code,
the plant, scikit-learn or numpy changed, or the file is missing or edited; the file is also kept
in the repository, and a retraining writes it byte for byte the same
(tests/test_response_class.py). With all three FMUs built, it also writes the fmucontainer
wiring file SuspensionSystem.csv and builds the container FMU SuspensionSystem.fmu from it
(harness/container.py). An FMU is rebuilt only when its sources or build options changed: a hash
of them per FMU is kept in dist/.build-stamps.json (``--force`` rebuilds all). Exits non-zero
with the reason if a build fails.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

ROOT = Path(__file__).resolve().parent
SRC = ROOT / "fmu_src"

# model identifier -> packages it bundles besides the adapter package
FMUS: dict[str, tuple[str, ...]] = {
    "ISORoad": ("plant",),
    "QuarterCar": ("plant",),
    "SuspensionEstimator": ("plant", "estimators"),
}


# FmuBuilder options of every FMU (capability flags of the model description)
BUILD_OPTIONS = {"needsExecutionTool": "true", "canHandleVariableCommunicationStepSize": "true",
                 "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true"}
STAMPS = ".build-stamps.json"


def _version(dist_name: str) -> str:
    try:
        return version(dist_name)
    except PackageNotFoundError:
        return "none"


def source_hash(paths: list[Path], options: dict) -> str:
    """SHA-256 of ``options`` and of every file under ``paths`` (name and content; compiled Python
    left out): what a build's output depends on."""
    h = hashlib.sha256(json.dumps(options, sort_keys=True).encode())
    for top in paths:
        files = [top] if top.is_file() else sorted(f for f in top.rglob("*") if f.is_file())
        for f in files:
            if "__pycache__" in f.parts or f.suffix == ".pyc":
                continue
            h.update(f.relative_to(top.parent).as_posix().encode() + b"\0")
            h.update(f.read_bytes())
    return h.hexdigest()


def read_stamps(dist: Path) -> dict[str, str]:
    try:
        return json.loads((dist / STAMPS).read_text())
    except (OSError, ValueError):
        return {}


def write_stamps(dist: Path, stamps: dict[str, str]) -> None:
    (dist / STAMPS).write_text(json.dumps(stamps, indent=1, sort_keys=True) + "\n")


def build(dist: Path, names: list[str] | None = None, force: bool = False) -> list[Path]:
    """Build the FMUs ``names`` (default all) into ``dist``, each only if its stamp differs (or
    ``force``). Returns the FMU files, built or up to date."""
    unknown = sorted(set(names or ()) - set(FMUS))
    if unknown:
        raise ValueError(f"unknown FMU name(s) {', '.join(unknown)}; known: {', '.join(FMUS)}")
    dist.mkdir(parents=True, exist_ok=True)
    stamps = read_stamps(dist)
    options = {**BUILD_OPTIONS, "pythonfmu": _version("pythonfmu")}
    built = []
    for name, packages in FMUS.items():
        if names and name not in names:
            continue
        script = SRC / f"{name}.py"
        if not script.is_file():
            print(f"skip {name}: {script.relative_to(ROOT)} does not exist yet")
            continue
        files = [SRC / "suspension_fmi", *(ROOT / p for p in packages)]
        out = dist / f"{name}.fmu"
        key = source_hash([script, *files], options)
        if not force and out.is_file() and stamps.get(name) == key:
            print(f"{name}.fmu is up to date")
        else:
            from pythonfmu.builder import FmuBuilder

            stamps.pop(name, None)
            write_stamps(dist, stamps)  # an interrupted build leaves no stamp that claims otherwise
            out = Path(FmuBuilder.build_FMU(script, dest=dist, project_files=files, **BUILD_OPTIONS))
            stamps[name] = key
            write_stamps(dist, stamps)
            print(f"built {out.relative_to(ROOT) if out.is_relative_to(ROOT) else out}")
        built.append(out)
    return built


def train_if_changed(dist: Path, force: bool = False) -> tuple[Path, bool]:
    """Retrain the road classifier's model (module doc) unless its stamp in ``dist`` says its
    inputs and the file itself are unchanged. Returns (model file, retrained)."""
    from estimators.response_class import ISO_MODEL, MODEL_DIR
    from estimators.response_class_train import write_iso_model

    out = MODEL_DIR / ISO_MODEL
    stamps = read_stamps(dist)
    est = ROOT / "estimators"
    key = source_hash([est / "response_class.py", est / "response_class_train.py", ROOT / "plant"],
                      {"sklearn": _version("scikit-learn"), "numpy": _version("numpy")})
    stamp = [key, hashlib.sha256(out.read_bytes()).hexdigest() if out.is_file() else None]
    if not force and stamps.get(ISO_MODEL) == stamp:
        return out, False
    write_iso_model(out)
    dist.mkdir(parents=True, exist_ok=True)
    stamps = read_stamps(dist)
    stamps[ISO_MODEL] = [key, hashlib.sha256(out.read_bytes()).hexdigest()]
    write_stamps(dist, stamps)
    return out, True


def build_container_if_changed(dist: Path, force: bool = False) -> tuple[Path, bool]:
    """``dist/SuspensionSystem.fmu`` from the three FMUs (harness/container.py), rebuilt only when
    one of them, container.py or fmu-manipulation-toolbox changed. Returns (file, rebuilt)."""
    from harness.container import CONTAINER, build_container

    stamps = read_stamps(dist)
    key = source_hash([ROOT / "harness" / "container.py"],
                      {"fmus": [stamps.get(n) for n in FMUS], "toolbox": _version("fmu-manipulation-toolbox")})
    out = dist / f"{CONTAINER}.fmu"
    if not force and out.is_file() and stamps.get(CONTAINER) == key:
        return out, False
    stamps.pop(CONTAINER, None)
    write_stamps(dist, stamps)
    out = build_container(dist)
    stamps[CONTAINER] = key
    write_stamps(dist, stamps)
    return out, True


# -- the variable contract as documentation -------------------------------------------------
INTERFACE_DOC = ROOT / "docs" / "fmu-interface.md"
README = ROOT / "README.md"
DOCS_COMMAND = "python build.py --docs"
TABLE_BEGIN = f"<!-- fmu-table: generated by `{DOCS_COMMAND}` from fmu_src/suspension_fmi/contract.py -->"
TABLE_END = "<!-- fmu-table: end -->"

_ROLES = {"ISORoad": "road source", "QuarterCar": "quarter-car plant", "SuspensionEstimator": "estimators"}
_INTRO = """\
# FMU interface contract

Generated by `{command}` from `fmu_src/suspension_fmi/contract.py`; do not edit by hand.

`python build.py` writes three FMI 2.0 Co-Simulation FMUs to `dist/`. Their model identifiers,
file names and the variables below are a public interface: they are wired by these names in
FMPy, SSP files, FMU containers and other tools, so a name, unit or meaning changes only together
with the contract.

- SI units everywhere, declared in `modelDescription.xml` (`unit` on every Real, with
  `UnitDefinitions`), and a one-line `description` on every variable.
- Vertical displacements are measured upwards from static equilibrium (gravity is balanced by
  the static spring preload and drops out).
- Integers that select a mode list their values under "allowed". ISO 8608 classes are numbered
  1..8 for A..H.
- A parameter outside "allowed" makes the FMU refuse at the end of initialization (an error
  logged naming the variable and its range, then `fmi2Discard` from every `doStep`); an input
  outside it is refused the same way at the step.
- The communication step size of `doStep` is the sample time; it may change between steps.
"""


def _contract():
    """``CONTRACTS`` of fmu_src/suspension_fmi/contract.py (it imports ``plant`` from the root)."""
    for p in (ROOT, SRC):
        if str(p) not in sys.path:
            sys.path.insert(0, str(p))
    from suspension_fmi.contract import CONTRACTS, allowed_text

    return CONTRACTS, allowed_text


def _start_text(var) -> str:
    if var.start is None:
        return ""
    if isinstance(var.start, bool):
        return str(var.start).lower()
    if isinstance(var.start, str):
        return f'"{var.start}"'
    return f"{var.start:g}" if isinstance(var.start, float) else str(var.start)


def interface_doc() -> str:
    """docs/fmu-interface.md: one table per FMU, every variable of the contract."""
    contracts, allowed_text = _contract()
    lines = [_INTRO.format(command=DOCS_COMMAND)]
    for name, variables in contracts.items():
        lines += [f"## `{name}.fmu`: {_ROLES.get(name, name)} (model identifier `{name}`)", "",
                  "| name | causality | type | unit | start | allowed | meaning |",
                  "| --- | --- | --- | --- | --- | --- | --- |"]
        for v in variables:
            allowed = allowed_text(v) if v.allowed is not None else ""
            cells = [f"`{v.name}`", v.causality, v.type, v.unit or "–", _start_text(v), allowed, v.description]
            lines.append("| " + " | ".join(c.replace("|", r"\|") for c in cells) + " |")
        lines.append("")
    return "\n".join(lines)


def interface_table() -> str:
    """The README's compact table: what each FMU takes and gives, between the marker comments."""
    contracts, _ = _contract()

    def names(variables, causality, units=True):
        return ", ".join(f"`{v.name}`" + (f" ({v.unit})" if units and v.unit else "")
                         for v in variables if v.causality == causality)

    lines = [TABLE_BEGIN, "", "| FMU | inputs | outputs | parameters |", "| --- | --- | --- | --- |"]
    for name, variables in contracts.items():
        lines.append(f"| `{name}` | {names(variables, 'input') or '–'} | {names(variables, 'output')} | "
                     f"{names(variables, 'parameter', units=False)} |")
    lines += ["", TABLE_END]
    return "\n".join(lines)


def readme_with_table(text: str) -> str:
    """``text`` with the part between the table markers replaced by ``interface_table()``."""
    begin, end = text.find(TABLE_BEGIN), text.find(TABLE_END)
    if begin < 0 or end < begin:
        raise ValueError(f"README.md has no FMU table markers ({TABLE_BEGIN} ... {TABLE_END})")
    return text[:begin] + interface_table() + text[end + len(TABLE_END):]


def write_docs() -> list[Path]:
    INTERFACE_DOC.parent.mkdir(exist_ok=True)
    INTERFACE_DOC.write_text(interface_doc())
    README.write_text(readme_with_table(README.read_text()))
    return [INTERFACE_DOC, README]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="output folder (default dist/)")
    ap.add_argument("names", nargs="*", help="model identifiers to build (default all)")
    ap.add_argument("--force", action="store_true", help="rebuild even what is up to date")
    ap.add_argument("--docs", action="store_true",
                    help="write docs/fmu-interface.md and the README's FMU table from the contract, build nothing")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    try:
        if args.docs:
            for p in write_docs():
                print(f"wrote {p.relative_to(ROOT)}")
            return 0
        model, trained = train_if_changed(args.dist, force=args.force)
        print(f"trained {model.relative_to(ROOT)}" if trained else f"{model.name} is up to date")
        built = build(args.dist, args.names, force=args.force)
        if args.names:
            return 0
        from harness.ssp import write_system_ssps

        for p in write_system_ssps(args.dist):
            print(f"wrote {p.name}")
        if len(built) == len(FMUS):
            out, rebuilt = build_container_if_changed(args.dist, force=args.force)
            print(f"wrote {out.with_suffix('.csv').name}, built {out.name}" if rebuilt else f"{out.name} is up to date")
    except Exception as e:  # noqa: BLE001 - one line for the user, non-zero exit
        print(f"build failed: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Build the project's FMUs into dist/ and write the SSP systems that wire them.

    python build.py [--dist DIR] [--force] [--version VERSION] [NAME ...]
    python build.py --docs          # write docs/fmu-interface.md and the README's FMU table

Every FMU bundles the plain-Python core (plant/, estimators/) and the adapter package
fmu_src/suspension_fmi/ under a package name private to its build,
``_suspension_estimation_<version>_<8 hex of its sources' hash>`` (``private_name``), and its
script as the module ``<that name>_<model identifier>``: a user's own modules named plant,
estimators, harness or suspension_fmi cannot shadow them, and FMUs of two builds load side by
side in one process. The version is pyproject.toml's unless ``--version`` says otherwise.
Before the FMUs are built, the road classifier's model (estimators/data/response_class_iso.json,
plain data bundled with estimators/) is trained again from simulated data with fixed seeds
(estimators.response_class_train) when its training code, the plant, scikit-learn or numpy
changed, or the file is missing or edited; the file is also kept in the repository, and a
retraining writes it byte for byte the same (tests/test_response_class.py). The LQR weight
schedule of the half car's controller (controllers/data/lqr_schedule.json, bundled with
controllers/) is regenerated the same way by controllers.schedule_train, with pymoo's NSGA-II
and a fixed seed, when its sources or pymoo changed or the file was edited; the file itself
records what it was trained from (tests/test_controller.py). With all the
FMUs built, it also writes the fmucontainer wiring files and builds the container FMUs from them
(harness/container.py: SuspensionSystem.fmu, HalfCarSystem.fmu). An FMU is rebuilt only when
its sources, the private name or the build options changed: a hash of them per FMU is kept in
dist/.build-stamps.json (``--force`` rebuilds all). Exits non-zero with the reason if a build
fails.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import re
import shutil
import sys
import tempfile
import tomllib
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

ROOT = Path(__file__).resolve().parent
SRC = ROOT / "fmu_src"
PACKAGE = "suspension_estimation"  # the import package of the distribution (pyproject.toml)
# subpackage bundled into the FMUs -> its source folder
SOURCES = {"plant": ROOT / "plant", "estimators": ROOT / "estimators", "suspension_fmi": SRC / "suspension_fmi",
           "controllers": ROOT / "controllers"}

# model identifier -> packages it bundles besides the adapter package
FMUS: dict[str, tuple[str, ...]] = {
    "ISORoad": ("plant",),
    "QuarterCar": ("plant",),
    "SuspensionEstimator": ("plant", "estimators"),
    "HalfCar": ("plant",),
    "HalfCarEstimator": ("plant", "estimators"),
    "SuspensionController": ("plant", "controllers"),
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


def project_version() -> str:
    """The version in pyproject.toml."""
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def bundled(name: str) -> list[Path]:
    """The FMU script of model ``name`` and the source folders it bundles."""
    return [SRC / f"{name}.py", *(SOURCES[p] for p in ("suspension_fmi", *FMUS[name]))]


def private_name(name: str, version_string: str) -> str:
    """The package name FMU ``name`` bundles its sources under:
    ``_suspension_estimation_<version>_<first 8 hex of the SHA-256 of its script and the sources it
    bundles>`` (a character of the version other than a letter, digit or _ becomes _).

    One name per FMU, not one shared by the FMUs of a build: a host may delete an FMU's folder
    once it is done with it (``fmpy.simulate_fmu`` does), and a package shared with an FMU loaded
    later would then be looked up in that deleted folder."""
    if not version_string.strip():
        raise ValueError("the version string is empty")
    digest = source_hash(bundled(name), {})[:8]
    return f"_{PACKAGE}_{re.sub(r'[^0-9A-Za-z_]', '_', version_string)}_{digest}"


_IMPORT = re.compile(rf"^(\s*(?:from|import)\s+){PACKAGE}(?=[.\s])", re.MULTILINE)
_PLAIN = re.compile(rf"^\s*(?:from|import)\s+(?:{'|'.join([*SOURCES, 'harness'])})\b", re.MULTILINE)


def stage(script: Path, packages: list[Path], private: str, version_string: str, into: Path) -> Path:
    """Write into ``into`` the FMU script of ``script`` importing ``private`` instead of
    suspension_estimation (as ``<private>_<script name>``) and the package ``private`` holding
    the source folders ``packages``. Returns the script written."""
    text, n = _IMPORT.subn(rf"\g<1>{private}", script.read_text())
    if n == 0 or re.search(rf"\b{PACKAGE}\b", text) or _PLAIN.search(text):
        raise ValueError(f"{script.name} must import the project only as `from {PACKAGE}.<sub> import ...`")
    pkg = into / private
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text(
        f'"""suspension-estimation-fmu {version_string}: the sources bundled in this FMU, under a name '
        f'private to its build."""\n__version__ = {version_string!r}\n')
    for folder in packages:
        shutil.copytree(folder, pkg / folder.name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    out = into / f"{private}_{script.name}"
    out.write_text(text)
    return out


def read_stamps(dist: Path) -> dict[str, str]:
    try:
        return json.loads((dist / STAMPS).read_text())
    except (OSError, ValueError):
        return {}


def write_stamps(dist: Path, stamps: dict[str, str]) -> None:
    (dist / STAMPS).write_text(json.dumps(stamps, indent=1, sort_keys=True) + "\n")


def build(dist: Path, names: list[str] | None = None, force: bool = False,
          version_string: str | None = None) -> list[Path]:
    """Build the FMUs ``names`` (default all) into ``dist``, each only if its stamp differs (or
    ``force``), each bundling its sources as ``private_name(name, version_string)`` (default
    version: pyproject.toml's). Returns the FMU files, built or up to date."""
    unknown = sorted(set(names or ()) - set(FMUS))
    if unknown:
        raise ValueError(f"unknown FMU name(s) {', '.join(unknown)}; known: {', '.join(FMUS)}")
    dist.mkdir(parents=True, exist_ok=True)
    stamps = read_stamps(dist)
    version_string = project_version() if version_string is None else version_string
    options = {**BUILD_OPTIONS, "pythonfmu": _version("pythonfmu")}
    built = []
    for name in FMUS:
        if names and name not in names:
            continue
        script = SRC / f"{name}.py"
        if not script.is_file():
            print(f"skip {name}: {script.relative_to(ROOT)} does not exist yet")
            continue
        out = dist / f"{name}.fmu"
        private = private_name(name, version_string)
        key = source_hash(bundled(name), {**options, "package": private})
        if not force and out.is_file() and stamps.get(name) == key:
            print(f"{name}.fmu is up to date")
        else:
            stamps.pop(name, None)
            write_stamps(dist, stamps)  # an interrupted build leaves no stamp that claims otherwise
            out = _build_fmu(script, bundled(name)[1:], private, version_string, dist)
            stamps[name] = key
            write_stamps(dist, stamps)
            print(f"built {out.relative_to(ROOT) if out.is_relative_to(ROOT) else out}")
        built.append(out)
    return built


def _build_fmu(script: Path, packages: list[Path], private: str, version_string: str, dist: Path) -> Path:
    from pythonfmu.builder import FmuBuilder

    with tempfile.TemporaryDirectory(prefix="fmu-stage-") as tmp:
        staged = stage(script, packages, private, version_string, Path(tmp))
        try:
            return Path(FmuBuilder.build_FMU(staged, dest=dist, project_files=[Path(tmp) / private],
                                             **BUILD_OPTIONS))
        finally:
            # pythonfmu imports the script from the staging folder and leaves it on sys.path
            sys.path[:] = [p for p in sys.path if p != tmp]
            for m in [m for m in sys.modules if m.split(".")[0] in (private, staged.stem)]:
                del sys.modules[m]


def train_if_changed(dist: Path, force: bool = False) -> tuple[Path, bool]:
    """Retrain the road classifier's model (module doc) unless its stamp in ``dist`` says its
    inputs and the file itself are unchanged. Returns (model file, retrained)."""
    from suspension_estimation.estimators.response_class import ISO_MODEL, MODEL_DIR
    from suspension_estimation.estimators.response_class_train import write_iso_model

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


def schedule_if_changed(force: bool = False) -> tuple[Path, bool]:
    """Regenerate the LQR weight schedule (module doc) unless the file is current: it records the
    hash of the sources it was trained from and of its own rows (schedule_train.is_current), so
    the check holds in any dist/, and a retraining (1.5 min) is not paid by every fresh build
    folder the tests make. Returns (schedule file, regenerated)."""
    from suspension_estimation.controllers.schedule import DATA_DIR, SCHEDULE
    from suspension_estimation.controllers.schedule_train import is_current, write_schedule

    out = DATA_DIR / SCHEDULE
    if not force and is_current(out):
        return out, False
    return write_schedule(out), True


def build_container_if_changed(dist: Path, name: str = "SuspensionSystem", force: bool = False) -> tuple[Path, bool]:
    """``dist/<name>.fmu``, a container of harness/container.py's CONTAINERS, from the FMUs it
    wires, rebuilt only when one of them, container.py, ssp.py (the wiring) or fmu-manipulation-
    toolbox changed. Returns (file, rebuilt)."""
    from suspension_estimation.harness.container import CONTAINERS, build_container
    from suspension_estimation.harness.ssp import SYSTEMS

    container = CONTAINERS[name]
    stamps = read_stamps(dist)
    wired = SYSTEMS[container.system][0]
    key = source_hash([ROOT / "harness" / "container.py", ROOT / "harness" / "ssp.py"],
                      {"fmus": [stamps.get(n) for n in wired], "toolbox": _version("fmu-manipulation-toolbox")})
    out = dist / f"{name}.fmu"
    if not force and out.is_file() and stamps.get(name) == key:
        return out, False
    stamps.pop(name, None)
    write_stamps(dist, stamps)
    out = build_container(dist, container=container)
    stamps[name] = key
    write_stamps(dist, stamps)
    return out, True


# -- the variable contract as documentation -------------------------------------------------
INTERFACE_DOC = ROOT / "docs" / "fmu-interface.md"
README = ROOT / "README.md"
DOCS_COMMAND = "python build.py --docs"
TABLE_BEGIN = f"<!-- fmu-table: generated by `{DOCS_COMMAND}` from fmu_src/suspension_fmi/contract.py -->"
TABLE_END = "<!-- fmu-table: end -->"

_ROLES = {"ISORoad": "road source", "QuarterCar": "quarter-car plant", "SuspensionEstimator": "estimators",
          "HalfCar": "half-car plant", "SuspensionController": "half-car active suspension",
          "HalfCarEstimator": "half-car observers"}
_INTRO = """\
# FMU interface contract

Generated by `{command}` from `fmu_src/suspension_fmi/contract.py`; do not edit by hand.

`python build.py` writes the FMI 2.0 Co-Simulation FMUs below to `dist/`. Their model identifiers,
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
    """``CONTRACTS`` of fmu_src/suspension_fmi/contract.py (the installed package)."""
    from suspension_estimation.suspension_fmi.contract import CONTRACTS, allowed_text

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
    ap.add_argument("--version", dest="version_string", metavar="VERSION",
                    help="version string in the FMUs' private package name (default: pyproject.toml's)")
    ap.add_argument("--docs", action="store_true",
                    help="write docs/fmu-interface.md and the README's FMU table from the contract, build nothing")
    args = ap.parse_args(argv)
    try:
        if args.docs:
            for p in write_docs():
                print(f"wrote {p.relative_to(ROOT)}")
            return 0
        model, trained = train_if_changed(args.dist, force=args.force)
        print(f"trained {model.relative_to(ROOT)}" if trained else f"{model.name} is up to date")
        schedule, trained = schedule_if_changed(force=args.force)
        print(f"trained {schedule.relative_to(ROOT)}" if trained else f"{schedule.name} is up to date")
        built = build(args.dist, args.names, force=args.force, version_string=args.version_string)
        if args.names:
            return 0
        from suspension_estimation.harness.ssp import write_system_ssps

        for p in write_system_ssps(args.dist):
            print(f"wrote {p.name}")
        if len(built) == len(FMUS):
            from suspension_estimation.harness.container import CONTAINERS

            for name in CONTAINERS:
                out, rebuilt = build_container_if_changed(args.dist, name, force=args.force)
                print(f"wrote {out.with_suffix('.csv').name}, built {out.name}" if rebuilt else f"{out.name} is up to date")
    except Exception as e:  # noqa: BLE001 - one line for the user, non-zero exit
        print(f"build failed: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

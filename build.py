"""Build the project's FMUs into dist/ and write the SSP systems that wire them.

    python build.py [--dist DIR]

Every FMU bundles the plain-Python core (plant/, estimators/) and the adapter package
fmu_src/suspension_fmi/. Before the FMUs are built, the road classifier's model
(estimators/data/response_class_iso.json, plain data bundled with estimators/) is trained again
from simulated data with fixed seeds (estimators.response_class_train); the file is also kept
in the repository, and a rebuild writes it byte for byte the same (tests/test_response_class.py). With all three FMUs built, it also writes the fmucontainer wiring file
SuspensionSystem.csv and builds the container FMU SuspensionSystem.fmu from it
(harness/container.py). Exits non-zero with the reason if a build fails.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent
SRC = ROOT / "fmu_src"

# model identifier -> packages it bundles besides the adapter package
FMUS: dict[str, tuple[str, ...]] = {
    "ISORoad": ("plant",),
    "QuarterCar": ("plant",),
    "SuspensionEstimator": ("plant", "estimators"),
}


def build(dist: Path, names: list[str] | None = None) -> list[Path]:
    from pythonfmu.builder import FmuBuilder

    unknown = sorted(set(names or ()) - set(FMUS))
    if unknown:
        raise ValueError(f"unknown FMU name(s) {', '.join(unknown)}; known: {', '.join(FMUS)}")
    dist.mkdir(parents=True, exist_ok=True)
    built = []
    for name, packages in FMUS.items():
        if names and name not in names:
            continue
        script = SRC / f"{name}.py"
        if not script.is_file():
            print(f"skip {name}: {script.relative_to(ROOT)} does not exist yet")
            continue
        files = [SRC / "suspension_fmi", *(ROOT / p for p in packages)]
        out = FmuBuilder.build_FMU(script, dest=dist, project_files=files,
                                   needsExecutionTool="true", canHandleVariableCommunicationStepSize="true",
                                   canGetAndSetFMUstate="true", canSerializeFMUstate="true")
        print(f"built {out.relative_to(ROOT) if out.is_relative_to(ROOT) else out}")
        built.append(Path(out))
    return built


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="output folder (default dist/)")
    ap.add_argument("names", nargs="*", help="model identifiers to build (default all)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    try:
        from estimators.response_class_train import write_iso_model

        print(f"trained {write_iso_model().relative_to(ROOT)}")
        build(args.dist, args.names)
        try:
            from harness.ssp import write_system_ssps
        except ImportError:
            write_system_ssps = None
        if write_system_ssps is not None and not args.names:
            for p in write_system_ssps(args.dist):
                print(f"wrote {p.name}")
        if not args.names and all((args.dist / f"{n}.fmu").is_file() for n in FMUS):
            from harness.container import build_container

            out = build_container(args.dist)
            print(f"wrote {out.with_suffix('.csv').name}, built {out.name}")
    except Exception as e:  # noqa: BLE001 - one line for the user, non-zero exit
        print(f"build failed: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env bash
# Set up a virtual environment in .venv with the project, the sweeps' and the tests' dependencies
# (pip install -e ".[test]"), then build the FMUs into dist/.
# Idempotent: pip runs again only when pyproject.toml changed, and an FMU is rebuilt only when its
# sources or build options changed (build.py keeps a hash of them in dist/.build-stamps.json).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
say() { echo "setup: $*" >&2; }
if [ ! -x .venv/bin/python ]; then
  say "creating the virtual environment .venv with $PY (a few seconds)"
  "$PY" -m venv .venv
fi
stamp=.venv/.installed-pyproject
want="$(sha256sum pyproject.toml | cut -d' ' -f1) .[test]"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && .venv/bin/python -c "import suspension_estimation.harness, suspension_estimation.estimators" 2>/dev/null; then
  say "dependencies unchanged since the last set-up (pyproject.toml), not reinstalled"
else
  say "installing the project and its dependencies into .venv (pip install -e \".[test]\": numpy, scipy, FMPy," \
      "pythonfmu, matplotlib, Dask, pyarrow, ...; about 2 min on a fresh machine, seconds when all is there)"
  log=$(mktemp)
  if ! { .venv/bin/python -m pip install --quiet --disable-pip-version-check --upgrade pip &&
         .venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[test]"; } >"$log" 2>&1; then
    cat "$log" >&2
    say "pip install failed (output above)"
    rm -f "$log"
    exit 1
  fi
  rm -f "$log"
  echo "$want" >"$stamp"
fi
if ! ldconfig -p 2>/dev/null | grep -q 'libtbb\.so\.12'; then
  # Ecos (ecospy, the tests' third master) links Intel TBB: Debian's libtbb12
  say "installing Debian's libtbb12 for Ecos (apt-get)"
  sudo=""
  [ "$(id -u)" = 0 ] || sudo=sudo
  if ! { $sudo apt-get install -y -q libtbb12 >/dev/null 2>&1 ||
         { $sudo apt-get update -q >/dev/null 2>&1 && $sudo apt-get install -y -q libtbb12 >/dev/null 2>&1; }; }; then
    say "could not install libtbb12: run 'apt-get install libtbb12' as root; the Ecos tests fail without it"
  fi
fi
say "building the FMUs into dist/ (a few seconds; what is up to date is kept)"
.venv/bin/python build.py

#!/usr/bin/env bash
# Set up a virtual environment in .venv with the project and its test tools, then build the FMUs.
# Idempotent: re-running only installs what is missing and rebuilds dist/.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --disable-pip-version-check --upgrade pip
.venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[test]"
.venv/bin/python build.py

#!/usr/bin/env bash
# Set up a virtual environment in .venv with the project and its test tools, then build the FMUs.
# Idempotent: re-running only installs what is missing and rebuilds dist/.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
log=$(mktemp)
if ! { .venv/bin/python -m pip install --quiet --disable-pip-version-check --upgrade pip &&
       .venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[test]"; } >"$log" 2>&1; then
  cat "$log" >&2
  echo "setup: pip install failed (output above)" >&2
  rm -f "$log"
  exit 1
fi
rm -f "$log"
.venv/bin/python build.py

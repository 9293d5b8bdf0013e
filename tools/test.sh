#!/usr/bin/env bash
# Fresh machine to test results: set up, build the FMUs, run the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
.venv/bin/python -m pytest "$@"

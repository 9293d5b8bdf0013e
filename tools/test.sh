#!/usr/bin/env bash
# Fresh machine to test results: set up (tools/setup.sh), build the FMUs, run the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
echo "test: running the test suite; it builds its own copy of the FMUs first (about 4-5 min on 2 idle cores)" >&2
.venv/bin/python -m pytest "$@"

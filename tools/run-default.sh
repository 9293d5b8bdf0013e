#!/usr/bin/env bash
# Fresh machine to results: set up, build the FMUs, co-simulate the default scenario, print and plot.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
.venv/bin/python -m harness run default "$@"

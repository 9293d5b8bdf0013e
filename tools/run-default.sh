#!/usr/bin/env bash
# Fresh machine to results: set up (tools/setup.sh), build the FMUs, co-simulate the default
# scenario, print the scores and write the CSV and plots to results/default/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
echo "run: co-simulating the default scenario, road -> plant -> estimator, 20 s at 1 ms (about 10 s, then the plots)" >&2
.venv/bin/python -m harness run default "$@"

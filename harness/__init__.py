"""Co-simulation harness: a Gauss-Seidel master over FMPy (cosim), SSP system files (ssp),
TOML scenarios (scenario), running them (runner), plots and the ``python -m suspension_estimation.harness`` CLI."""

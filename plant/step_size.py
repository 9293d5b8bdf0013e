"""Communication steps that differ only by rounding are the same step.

Many masters (``fmpy.simulate_fmu``, fmusim, libcosim) compute the step as t_{n+1} - t_n with
t_n = t_0 + n*dt, so a nominally constant dt arrives as a dozen values that differ in the last
bits (|error| <= about 4.4e-16 * t_n). Comparing h exactly made the plant and the estimator
re-discretise on most steps. A step within ``STEP_RTOL`` (relative) of the step a model was built
for is treated as that step: for t_n / dt up to about 2e9 the rounding stays below it, while a
real change of step (1 -> 5 -> 2 ms) is a factor, far above it. Integrating over h(1 + 1e-6)
instead of h changes a state by a relative 1e-6 of one step's increment, below any sensor noise.
"""
from __future__ import annotations

STEP_RTOL = 1e-6


def same_step(h: float, h_model: float | None) -> float:
    """``h_model`` when ``h`` (s) differs from it by at most STEP_RTOL relative, else ``h``."""
    if h_model is not None and abs(h - h_model) <= STEP_RTOL * h_model:
        return h_model
    return h

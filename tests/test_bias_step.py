"""estimators/bias_step.py: which filter a mid-run disagreement says is misled, on synthetic
innovation means."""
from __future__ import annotations

import numpy as np

from suspension_estimation.estimators.bias_step import BIAS_LIMIT, BiasStep

H = 1e-3
M_S = 410.0


def run(judge: BiasStep, seconds: float, t0: float, y_kf, y_anchor, force=lambda t: 0.0, seed: int = 1) -> float:
    """White unit innovations plus the given means (functions of time), from ``t0``; returns the
    time reached."""
    rng = np.random.default_rng(seed)
    t = t0
    for _ in range(int(round(seconds / H))):
        t += H
        e = rng.normal(0.0, 1.0, 2)
        judge.update(y_kf(t) + e[0], y_anchor(t) + e[1], force(t), H, t, M_S)
    return t


def test_a_jump_of_the_anchors_mean_alone_says_the_force_error_filter_is_misled():
    """A body bias: the anchor's deflection innovations jump, the force-error filter's do not."""
    j = BiasStep()
    t = run(j, 5.0, 0.0, lambda t: 0.0, lambda t: 0.0)
    assert j.judge(t) is None  # white noise: nothing to tell apart
    t = run(j, 0.1, t, lambda t: 0.0, lambda t: 3.0)
    assert j.judge(t) is True


def test_a_jump_both_filters_see_says_the_anchor_is():
    """A deflection step: both filters' deflection innovations jump together."""
    j = BiasStep()
    t = run(j, 5.0, 0.0, lambda t: 0.0, lambda t: 0.0)
    t = run(j, 0.1, t, lambda t: 2.0, lambda t: 3.0)
    assert j.judge(t) is False


def test_no_jump_stands_out_from_a_mean_that_is_already_large():
    """A car that is not the model: the anchor's mean sits at 0.5 (22 stds of a 1 s mean); the
    same rise as above is no jump, and the anchor is judged wrong."""
    j = BiasStep()
    t = run(j, 5.0, 0.0, lambda t: 0.0, lambda t: 0.5)
    t = run(j, 0.1, t, lambda t: 0.0, lambda t: 3.0)
    assert j.judge(t) is False


def test_the_bias_taken_up_is_the_force_change_over_the_mass():
    """After the judgement, the force states moving by -m_s b read as a body bias b, averaged over
    the window (5 s on: within 2 %); beyond BIAS_LIMIT it is out of range; released, it is forgotten."""
    for b, beyond in ((0.2, False), (0.5, True), (-0.5, True)):
        j = BiasStep()
        t = run(j, 5.0, 0.0, lambda t: 0.0, lambda t: 0.0, force=lambda t: 100.0)
        t = run(j, 0.1, t, lambda t: 0.0, lambda t: 3.0, force=lambda t: 100.0)
        assert j.judge(t) is True
        run(j, 5.0, t, lambda t: 0.0, lambda t: 3.0, force=lambda t: 100.0 - M_S * b)
        assert abs(j.bias - b) < 0.02 * abs(b)  # the window's lag
        assert j.beyond_range == beyond == (abs(b) > BIAS_LIMIT)
        j.release()
        assert j.bias == 0.0 and not j.beyond_range

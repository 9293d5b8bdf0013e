"""Which filter is misled when the default road estimator's two filters part mid-run
(anchored_road.py): the anchor, or the force-error filter.

A body accelerometer whose bias steps is read by the force-error filter as a force on the body, so
the whole corner accelerates with it, while the anchor (the exact linear model) takes it as noise
and is nearly right. A deflection sensor whose zero moves is the anchor's error instead (its
linear spring reads the offset d as a force nothing balances), and the force-error filter takes
it up as a force k_s d. The anchor's innovations are alike for both: d and a body bias
-k_s d / m_s are the same error in its body equation. The force-error filter's deflection
innovations are not: a jump of the deflection reaches both filters at once, a body bias reaches
the deflection only through the anchor's model. So the force-error filter is judged misled when
the anchor's deflection-innovation mean has just jumped (beyond ``LIMIT``, and ``JUMP`` times its
rms over the ``LEVEL_WINDOW`` s before it left ``QUIET``, at most ``ONSET`` s ago: on a car that is
not the model the anchor's mean wanders at 12-17, and no jump stands out) and the force-error
filter's own mean is below ``RATIO`` of it. The measurements behind the numbers are in
docs/real-sensors.md, "A bias that steps mid-run".

Once judged so, the bias the force-error states take up (the change of their force since the
judgement over m_s, averaged over ``WINDOW`` s) estimates the step: beyond ``BIAS_LIMIT`` it is
outside the range a filter absorbs (``beyond_range``).
"""
from __future__ import annotations

import math

WINDOW = 1.0  # s, of the innovation means
LIMIT = 10.0  # the anchor's mean, in stds of a mean
RATIO = 0.4  # the force-error filter's mean over the anchor's
QUIET, ONSET = 6.0, 0.5  # stds of a mean, s
LEVEL_WINDOW, JUMP = 5.0, 4.0  # s, times the rms
BIAS_LIMIT = 0.35  # m/s^2


class BiasStep:
    """The means of the two filters' deflection innovations (each over its innovation std) and of
    the force-error filter's force states, one full update at a time."""

    def __init__(self) -> None:
        self.means = [0.0, 0.0]  # force-error filter, anchor
        self._a = 1.0  # the weight of the last update: a mean of white noise has a variance a / (2 - a)
        self._loud_from: float | None = None  # s, since when the anchor's mean is beyond QUIET
        self._level = 0.0  # its mean square over LEVEL_WINDOW s, in its variances
        self._level_before = 0.0  # ... when it last left QUIET
        self._force = 0.0  # N, the force states' mean
        self._force_judged: float | None = None  # N, that mean when the filter was judged misled
        self.bias = 0.0  # m/s^2, the body bias taken up since

    def update(self, y_kf: float, y_anchor: float, force: float, h: float, time: float, m_s: float) -> None:
        """The deflection innovations over their stds (force-error filter, anchor), the force
        states' sum ``force`` (N), the step ``h`` (s), the time (s) and the model's m_s (kg)."""
        a = self._a = min(h / WINDOW, 1.0)
        m = self.means
        m[0] += a * (y_kf - m[0])
        m[1] += a * (y_anchor - m[1])
        m2 = self._squared(m[1])
        if m2 <= QUIET ** 2:
            self._loud_from = None
        elif self._loud_from is None:
            self._loud_from, self._level_before = time, self._level
        self._level += min(h / LEVEL_WINDOW, 1.0) * (m2 - self._level)
        self._force += a * (force - self._force)
        if self._force_judged is not None:
            self.bias += a * (-(force - self._force_judged) / m_s - self.bias)

    def _squared(self, mean: float) -> float:
        """A mean squared, in the variances of a mean of white noise."""
        return mean * mean * (2.0 - self._a) / self._a

    def judge(self, time: float) -> bool | None:
        """True: the force-error filter is misled (the bias estimate starts); False: the anchor
        is; None: not told apart yet (the anchor's mean within LIMIT)."""
        m_kf, m_anchor = self.means
        if self._squared(m_anchor) <= LIMIT ** 2:
            return None
        jumped = (self._loud_from is not None and time - self._loud_from <= ONSET
                  and self._squared(m_anchor) > JUMP ** 2 * self._level_before)
        if jumped and m_kf * m_anchor < RATIO * m_anchor ** 2:
            self._force_judged, self.bias = self._force, 0.0
            return True
        return False

    def release(self) -> None:
        """The filters agree again: no bias estimate until the next judgement."""
        self._force_judged, self.bias = None, 0.0

    @property
    def beyond_range(self) -> bool:
        return abs(self.bias) > BIAS_LIMIT

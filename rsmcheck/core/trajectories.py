"""Desired trajectories of the controllers (paper Sect. 3: "time-varying with polynomial law
when it is necessary to reach a desired system configuration").

A quintic rest-to-rest blend s(τ) = 10τ³ − 15τ⁴ + 6τ⁵, τ = (t − t0)/T clipped to [0, 1]:
zero velocity and acceleration at both ends, so a move starts and ends without a jerk step
that would excite the flexible links.  Peak speed 1.875·D/T at mid-move, peak acceleration
5.7735·D/T².
"""

from __future__ import annotations

import numpy as np

PEAK_SPEED = 1.875  # max ds/dτ
PEAK_ACCEL = 5.773502691896258  # max d²s/dτ² = 10/sqrt(3)


def quintic(t: float, t0: float, duration: float) -> tuple[float, float, float]:
    """s, ds/dt, d²s/dt² of the rest-to-rest quintic blend from t0 over `duration` s."""
    if duration <= 0.0:
        return 1.0, 0.0, 0.0
    tau = (t - t0) / duration
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= 1.0:
        return 1.0, 0.0, 0.0
    s = tau**3 * (10.0 + tau * (-15.0 + 6.0 * tau))
    ds = 30.0 * tau**2 * (1.0 - tau) ** 2 / duration
    dds = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / duration**2
    return s, ds, dds


class Quintic:
    """A vector quintic move p(t) = p0 + s(t)·(p1 − p0) from t0 over `duration`."""

    def __init__(self, p0, p1, t0: float, duration: float):
        self.p0 = np.asarray(p0, float).copy()
        self.p1 = np.asarray(p1, float).copy()
        self.t0 = float(t0)
        self.duration = float(duration)

    def __call__(self, t: float) -> np.ndarray:
        s, _, _ = quintic(t, self.t0, self.duration)
        return self.p0 + s * (self.p1 - self.p0)

    def velocity(self, t: float) -> np.ndarray:
        _, ds, _ = quintic(t, self.t0, self.duration)
        return ds * (self.p1 - self.p0)

    def final_pose(self) -> np.ndarray:
        return self.p1

    def done(self, t: float) -> bool:
        return t >= self.t0 + self.duration

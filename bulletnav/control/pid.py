"""A PID controller with explicit ``dt``, output clamping and anti-windup."""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass
class PID:
    """``u = kp e + ki * integral(e) + kd de/dt``, clamped to ``[out_min, out_max]``.

    Anti-windup: the integral is clamped to ``+/- integral_limit`` and is not accumulated
    while the output is saturated in the direction the error pushes (conditional
    integration). The derivative acts on the error, skipped on the first update after
    :meth:`reset` so a fresh controller does not kick.
    """

    kp: float
    ki: float = 0.0
    kd: float = 0.0
    out_min: float = -math.inf
    out_max: float = math.inf
    integral_limit: float = math.inf
    integral: float = field(default=0.0, init=False)
    _prev_error: float | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.out_min > self.out_max:
            raise ValueError(f"PID out_min {self.out_min} > out_max {self.out_max}")

    def reset(self) -> None:
        self.integral = 0.0
        self._prev_error = None

    def update(self, error: float, dt: float) -> float:
        """Advance by ``dt`` seconds with the current ``error``; returns the clamped output."""
        if dt <= 0 or not math.isfinite(dt):
            raise ValueError(f"PID dt must be a positive finite number of seconds, got {dt}")
        derivative = 0.0 if self._prev_error is None else (error - self._prev_error) / dt
        self._prev_error = error
        candidate = self.integral + error * dt
        candidate = max(-self.integral_limit, min(self.integral_limit, candidate))
        unclamped = self.kp * error + self.ki * candidate + self.kd * derivative
        saturated_high = unclamped > self.out_max and error > 0
        saturated_low = unclamped < self.out_min and error < 0
        if not (saturated_high or saturated_low):
            self.integral = candidate
        out = self.kp * error + self.ki * self.integral + self.kd * derivative
        return max(self.out_min, min(self.out_max, out))

"""Shared by the two jet solvers' tests: the push-then-suck nozzle pulse."""

from __future__ import annotations

import math

import pytest


class PushSuckPulse:
    """u = U sin(pi t / T) for t < T, then -s U sin for T < t < 2T (push, then suck)."""

    def __init__(self, u: float, period: float, suck: float = 0.5) -> None:
        self.u, self.p, self.s = u, period, suck

    def velocity(self, t: float) -> float:
        if t < self.p:
            return self.u * math.sin(math.pi * t / self.p)
        if t < 2 * self.p:
            return -self.s * self.u * math.sin(math.pi * (t - self.p) / self.p)
        return 0.0

    def displacement(self, t: float) -> float:
        c = self.u * self.p / math.pi
        if t < self.p:
            return c * (1.0 - math.cos(math.pi * t / self.p))
        if t < 2 * self.p:
            return 2 * c - self.s * c * (1.0 - math.cos(math.pi * (t - self.p) / self.p))
        return 2 * c - 2 * self.s * c


@pytest.fixture
def push_suck() -> PushSuckPulse:
    """U = 4, T = 1.5 (dimensionless), half the push sucked back."""
    return PushSuckPulse(4.0, 1.5)

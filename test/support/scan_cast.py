"""A test-only 360° lidar: exact ray casting against circles and wall segments (seeded noise), the
independent truth the surroundings tests compare the perception's obstacles with."""

from __future__ import annotations

import math

import numpy as np

BEAMS = 720
INC = 2.0 * math.pi / BEAMS
ANGLE_MIN = -math.pi
RANGE_MIN, RANGE_MAX = 0.2, 30.0


def cast(x: float, y: float, yaw: float, circles=(), walls=(), noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """A 360° scan from (x, y, yaw): nearest hit of each beam on circles (cx, cy, r) and wall
    segments ((x0, y0), (x1, y1)); +inf where nothing is within RANGE_MAX."""
    a = yaw + ANGLE_MIN + INC * np.arange(BEAMS)
    dx, dy = np.cos(a), np.sin(a)
    best = np.full(BEAMS, np.inf)
    for cx, cy, r in circles:
        ox, oy = x - cx, y - cy
        b = ox * dx + oy * dy
        disc = b * b - (ox * ox + oy * oy - r * r)
        t = np.where(disc >= 0, -b - np.sqrt(np.maximum(disc, 0)), np.inf)
        best = np.minimum(best, np.where(t > 0, t, np.inf))
    for (x0, y0), (x1, y1) in walls:
        ex, ey = x1 - x0, y1 - y0
        den = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((x0 - x) * ey - (y0 - y) * ex) / den
            u = ((x0 - x) * dy - (y0 - y) * dx) / den
        hit = (np.abs(den) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
        best = np.minimum(best, np.where(hit, t, np.inf))
    if noise:
        best = best + np.random.default_rng(seed).normal(0.0, noise, BEAMS)
    best[best >= RANGE_MAX] = np.inf
    return best.astype(np.float32)

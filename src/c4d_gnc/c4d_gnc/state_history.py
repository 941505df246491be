"""The navigation state at IMU rate over the last second or so: what a delayed measurement is compared with.

Why: an external pose (VIO, motion capture) or a GNSS fix arrives tens of milliseconds after it was
sampled; comparing it with the *current* estimate turns that latency into a position error of
speed × latency (6 cm at 2 m/s and 30 ms). The filter keeps, per IMU sample, the estimate's
position, velocity, attitude and the IMU-only dead-reckoning shadow, and looks up the entry at a
measurement's sample time. When an update corrects the current state the same correction is
added to every stored entry (`shift`), so the next delayed measurement is not compared with a
history that has not seen the previous correction (which would count it twice).

Storage: preallocated numpy arrays written twice (at i and i + capacity), so the last `count`
samples are always one contiguous slice — a lookup is one `np.searchsorted` and no copy.
"""

from __future__ import annotations

import numpy as np

# columns of the state rows
P, V, Q, PI, VI = slice(0, 3), slice(3, 6), slice(6, 10), slice(10, 13), slice(13, 16)
WIDTH = 16


class StateHistory:
    """Ring buffer of (t, p, v, q (w, x, y, z), inertial p, inertial v) at IMU rate."""

    def __init__(self, capacity: int = 600) -> None:
        if capacity < 2:
            raise ValueError("history capacity must be >= 2")
        self.capacity = capacity
        self._t = np.full(2 * capacity, -np.inf)
        self._x = np.zeros((2 * capacity, WIDTH))
        self._head = -1  # ring index of the newest sample
        self.count = 0

    def clear(self) -> None:
        self._head, self.count = -1, 0

    def push(self, t: float, p: np.ndarray, v: np.ndarray, q: tuple[float, float, float, float],
             pi: np.ndarray, vi: np.ndarray) -> None:
        """Append one sample (t strictly increasing; an older t clears the buffer: the clock jumped)."""
        if self.count and t <= self._t[self._head]:
            self.clear()
        h = (self._head + 1) % self.capacity
        row = self._x[h]
        row[P], row[V], row[Q], row[PI], row[VI] = p, v, q, pi, vi
        self._x[h + self.capacity] = row
        self._t[h] = self._t[h + self.capacity] = t
        self._head = h
        self.count = min(self.count + 1, self.capacity)

    def _window(self) -> tuple[np.ndarray, np.ndarray]:
        if self.count < self.capacity:
            return self._t[: self.count], self._x[: self.count]
        start = self._head + 1
        return self._t[start: start + self.capacity], self._x[start: start + self.capacity]

    @property
    def oldest_t(self) -> float:
        return float(self._window()[0][0]) if self.count else np.inf

    @property
    def newest_t(self) -> float:
        return float(self._t[self._head]) if self.count else -np.inf

    def at(self, t: float) -> np.ndarray | None:
        """The state row at time t (linear interpolation between the two samples around it; the
        quaternion part is the nearer sample's), or None when t is outside the stored span."""
        times, rows = self._window()
        if not self.count or t < times[0] or t > times[-1]:
            return None
        k = int(np.searchsorted(times, t))
        if times[k] == t or k == 0:
            return rows[k].copy()
        t0, t1 = times[k - 1], times[k]
        a = (t - t0) / (t1 - t0)
        out = rows[k - 1] * (1.0 - a) + rows[k] * a
        out[Q] = rows[k if a >= 0.5 else k - 1, Q]
        return out

    def shift(self, dp: np.ndarray, dv: np.ndarray) -> None:
        """Add an update's position / velocity correction to every stored estimate (not to the
        inertial shadow: that one is never corrected)."""
        if self.count:
            self._x[:, P] += dp
            self._x[:, V] += dv

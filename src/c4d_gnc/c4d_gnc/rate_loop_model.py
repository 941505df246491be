"""Linear model of one attitude axis (attitude P → rate PD → motors → rigid body), for tuning.

What: `step_response(kp, ...)` integrates the roll (or pitch) loop's small-signal model for an
attitude step and `step_metrics()` reads overshoot and the 10→50 % rise off any trace (modelled,
simulated or flown). Model: ω_sp = 2·k_att·sin(e/2) limited to ±max_rate (the attitude P of
control/rotation.py); α_cmd = k_p·(ω_sp − ω) − k_d·ω̇ (the rate PID with D on the measurement; the
I term is left out — at 8 1/s² it moves nothing in the 0.3 s of a step); one tick of delay
(gyro sampled, command applied next tick); first-order motors (τ = the airframe's time
constant); rigid body ω̇ = α (the controller multiplies by the inertia, so α is the plant input).
Why: a user doubling MC_ROLLRATE_P should know what to expect — docs/parameters.md quotes the
predictions and test/test_live_params.py checks the flown response against them.
"""

from __future__ import annotations

import math

Trace = list[tuple[float, float]]


def step_response(kp: float, kd: float = 0.5, k_att: float = 9.0, tau_m: float = 0.03, tick_s: float = 0.002,
                  step: float = math.radians(15.0), max_rate: float = math.radians(220.0), duration_s: float = 0.8) -> Trace:
    """(t, angle) of the modelled axis after an attitude step of `step` rad at t = 0."""
    angle = rate = rate_prev = accel = delayed = 0.0
    trace: Trace = []
    for k in range(int(duration_s / tick_s)):
        rate_sp = max(-max_rate, min(max_rate, 2.0 * k_att * math.sin((step - angle) / 2.0)))
        command = kp * (rate_sp - rate) - kd * (rate - rate_prev) / tick_s
        rate_prev = rate
        accel += (delayed - accel) * tick_s / tau_m  # the motors see last tick's command
        delayed = command
        rate += accel * tick_s
        angle += rate * tick_s
        trace.append((k * tick_s, angle))
    return trace


def step_metrics(trace: Trace, start: float, end: float) -> tuple[float, float]:
    """(overshoot as a fraction of the step, time from 10 % to 50 % of the step [s]; NaN if never
    crossed) of a trace that steps from `start` to `end`. Crossings are interpolated between samples."""
    size = end - start
    progress = [(t, (v - start) / size) for t, v in trace]

    def crossing(level: float) -> float:
        for (t0, p0), (t1, p1) in zip(progress, progress[1:], strict=False):
            if p0 < level <= p1:
                return t0 + (level - p0) / (p1 - p0) * (t1 - t0)
        return math.nan

    return max(p for _, p in progress) - 1.0, crossing(0.5) - crossing(0.1)

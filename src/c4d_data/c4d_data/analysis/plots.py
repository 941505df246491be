"""Report figures (matplotlib, Agg backend, PNG). Each function draws one figure from
FlightData and returns the file it saved, or None when the data it needs was not recorded.

Why separate from the report: figures are the bulk of the analysis code and are tested by
what they produce (a non-blank PNG), while report.py only decides layout and wording.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from .extract import FlightData

MODES = {0: "unknown", 1: "rate", 2: "attitude", 3: "position", 4: "auto", 5: "kill"}
NAV = {0: "none", 1: "takeoff", 2: "mission", 3: "hold", 4: "goto", 5: "rtl", 6: "land"}
FAILSAFE = {0: "none", 1: "warn", 2: "hold", 3: "rtl", 4: "land", 5: "terminate"}


def _save(fig, out: Path, name: str) -> Path:
    path = out / f"{name}.png"
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _armed_shading(ax, data: FlightData) -> None:
    status = data.series["status"]
    if not len(status):
        return
    armed = status["armed"] > 0.5
    edges = np.flatnonzero(np.diff(armed.astype(int))) + 1
    bounds = [0, *edges, len(armed)]
    for a, b in zip(bounds[:-1], bounds[1:], strict=False):
        if armed[a]:
            ax.axvspan(status.t[a], status.t[min(b, len(armed) - 1)], color="tab:green", alpha=0.08, lw=0)


def trajectory(data: FlightData, out: Path) -> Path | None:
    state, sp, truth, caps = (data.series[k] for k in ("state", "setpoint", "truth", "captures"))
    if not len(state):
        return None
    fig, (top, alt) = plt.subplots(1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [1, 1.6]})
    top.plot(state["x"], state["y"], label="estimate", lw=1.2)
    if len(truth):
        top.plot(truth["x"], truth["y"], label="ground truth (sim frame)", lw=0.8, alpha=0.7)
    if len(sp):
        top.plot(sp["x"], sp["y"], "--", label="setpoint", lw=1)
    plan = data.kept.get("plan")
    if plan is not None:
        pts = [(i.x, i.y) for i in plan.items if i.frame == 1 and np.isfinite(i.x) and np.isfinite(i.y)]
        if pts:
            top.plot(*zip(*pts, strict=True), "k^", ms=6, label="planned waypoints")
    if len(caps):
        top.plot(caps["x"], caps["y"], "r*", ms=9, label="captures")
    top.set(xlabel="east [m]", ylabel="north [m]", title="top view")
    top.axis("equal")
    top.legend(fontsize=7)
    alt.plot(state.t, state["z"], label="estimate")
    if len(truth):
        alt.plot(truth.t, truth["z"], label="ground truth", alpha=0.7)
    if len(sp):
        alt.plot(sp.t, sp["z"], "--", label="setpoint")
    _armed_shading(alt, data)
    alt.set(xlabel="time [s]", ylabel="altitude above home [m]", title="altitude (green: armed)")
    alt.legend(fontsize=7)
    return _save(fig, out, "trajectory")


def tracking(data: FlightData, out: Path) -> Path | None:
    state, sp = data.series["state"], data.series["setpoint"]
    if not len(state) or len(sp) < 2:
        return None
    active = (state.t >= sp.t[0]) & (state.t <= sp.t[-1])
    t = state.t[active]
    fig, (ax_p, ax_v) = plt.subplots(2, 1, figsize=(11, 5.5), sharex=True)
    for axis, ref, est, label in ((ax_p, "", "", "position"), (ax_v, "v", "v", "velocity")):
        for c in "xyz":
            target = np.interp(t, sp.t, sp[ref + c])
            axis.plot(t, state[est + c][active] - target, lw=0.9, label=f"{c} error")
        axis.set(ylabel=f"{label} error [{'m' if label == 'position' else 'm/s'}]")
        axis.axhline(0, color="k", lw=0.5)
        axis.legend(fontsize=7, ncol=3)
    ax_p.set_title("tracking error: estimate - guidance setpoint (while setpoints stream)")
    ax_v.set_xlabel("time [s]")
    return _save(fig, out, "tracking")


def attitude(data: FlightData, out: Path) -> Path | None:
    state = data.series["state"]
    if not len(state):
        return None
    fig, (ax_a, ax_r) = plt.subplots(2, 1, figsize=(11, 5.5), sharex=True)
    for name in ("roll", "pitch"):
        ax_a.plot(state.t, np.degrees(state[name]), lw=0.9, label=name)
    ax_a.set(ylabel="angle [deg]", title="attitude (yaw on the right axis) and body rates")
    yaw_axis = ax_a.twinx()
    yaw_axis.plot(state.t, np.degrees(state["yaw"]), color="tab:green", lw=0.9, label="yaw")
    yaw_axis.set_ylabel("yaw [deg, ENU]")
    ax_a.legend(fontsize=7, loc="upper left")
    for name in "pqr":
        ax_r.plot(state.t, np.degrees(state[name]), lw=0.7, label={"p": "roll rate", "q": "pitch rate", "r": "yaw rate"}[name])
    ax_r.set(xlabel="time [s]", ylabel="rate [deg/s]")
    ax_r.legend(fontsize=7, ncol=3)
    return _save(fig, out, "attitude")


def motors(data: FlightData, out: Path) -> Path | None:
    act = data.series["actuators"]
    if not len(act) or act.extra is None or not act.extra.shape[1]:
        return None
    fig, ax = plt.subplots(figsize=(11, 3.8))
    for k in range(act.extra.shape[1]):
        ax.plot(act.t, act.extra[:, k], lw=0.6, label=f"motor {k}")
    _armed_shading(ax, data)
    ax.set(xlabel="time [s]", ylabel="normalised output [0, 1]", title="motor outputs (green: armed)", ylim=(-0.02, 1.02))
    ax.legend(fontsize=7, ncol=min(8, act.extra.shape[1]))
    return _save(fig, out, "motors")


def battery(data: FlightData, out: Path) -> Path | None:
    bat = data.series["battery"]
    if not len(bat):
        return None
    fig, (ax_v, ax_i) = plt.subplots(2, 1, figsize=(11, 4.5), sharex=True)
    ax_v.plot(bat.t, bat["voltage"], label="voltage [V]")
    soc = ax_v.twinx()
    soc.plot(bat.t, 100 * bat["percentage"], color="tab:orange", label="charge [%]")
    soc.set_ylabel("charge [%]")
    ax_v.set(ylabel="voltage [V]", title="battery")
    ax_i.plot(bat.t, bat["current"], color="tab:red")
    ax_i.set(xlabel="time [s]", ylabel="current [A]")
    return _save(fig, out, "battery")


def tick_load(data: FlightData, out: Path) -> Path | None:
    stats = data.series["stats"]
    if not len(stats):
        return None
    fig, (hist, over) = plt.subplots(1, 2, figsize=(12, 3.8))
    bins = np.linspace(0, max(100.0, float(np.nanmax(stats["load_max"]))), 40)
    hist.hist(stats["load_mean"], bins=bins, alpha=0.7, label="mean load per report window")
    hist.hist(stats["load_max"], bins=bins, alpha=0.7, label="worst tick per report window")
    hist.set(xlabel="tick load [% of the tick period]", ylabel="windows (1 s)", title="tick-load histogram")
    hist.legend(fontsize=7)
    over.plot(stats.t, stats["load_mean"], label="mean")
    over.plot(stats.t, stats["load_max"], label="max")
    over.bar(stats.t, stats["overruns"], color="tab:red", alpha=0.6, label="overruns")
    over.set(xlabel="time [s]", ylabel="[%] / overruns", title="tick load over the flight")
    over.legend(fontsize=7)
    return _save(fig, out, "tick_load")


def jitter(data: FlightData, out: Path) -> Path | None:
    stats, act = data.series["stats"], data.series["actuators"]
    if not len(stats) and len(act) < 3:
        return None
    fig, (over, hist) = plt.subplots(1, 2, figsize=(12, 3.8))
    if len(stats):
        for name in ("jitter_mean", "jitter_p99", "jitter_max"):
            over.plot(stats.t, stats[name], marker=".", label=name.replace("jitter_", ""))
    over.set(xlabel="time [s]", ylabel="release jitter [µs]", title="executive release jitter (profiler, per window)")
    over.legend(fontsize=7)
    if len(act) >= 3:
        period = np.diff(act["stamp"]) * 1e6
        nominal = float(np.median(period))
        dev = period - nominal
        hist.hist(np.clip(dev, -2000, 2000), bins=80, color="tab:purple")
        hist.set_yscale("log")
        hist.set(xlabel=f"actuator period - {nominal:.0f} µs [µs]", ylabel="ticks",
                 title="actuator command period deviation")
    return _save(fig, out, "jitter")


def health(data: FlightData, out: Path) -> Path | None:
    status = data.series["status"]
    events = data.events.get("health", [])
    if not len(status) and not events:
        return None
    fig, axes = plt.subplots(4, 1, figsize=(11, 6), sharex=True)
    rows = (("mode", MODES, "flight mode"), ("nav", NAV, "AUTO state"), ("failsafe", FAILSAFE, "failsafe (core)"))
    for axis, (col, names, label) in zip(axes[:3], rows, strict=True):
        if len(status):
            axis.step(status.t, status[col], where="post")
            used = sorted(set(status[col].astype(int)) | {0})
            axis.set_yticks(used, [names.get(v, str(v)) for v in used], fontsize=7)
        axis.set_ylabel(label, fontsize=8)
    if events:
        axes[3].step([t for t, _ in events], [int.from_bytes(m.level, "little") if isinstance(m.level, bytes)
                                              else int(m.level) for _, m in events], where="post", color="tab:red")
        axes[3].set_yticks([0, 1, 2, 3], ["ok", "warn", "error", "stale"], fontsize=7)
    axes[3].set(ylabel="health level", xlabel="time [s]")
    axes[0].set_title("health and failsafe timeline")
    return _save(fig, out, "health")


def mission(data: FlightData, out: Path) -> Path | None:
    ms = data.series["mission"]
    if not len(ms):
        return None
    fig, (prog, item) = plt.subplots(2, 1, figsize=(11, 4.5), sharex=True)
    prog.plot(ms.t, 100 * ms["progress"], label="progress [%]")
    prog.set(ylabel="progress [%]", title="mission progress")
    dist = prog.twinx()
    dist.plot(ms.t, ms["distance"], color="tab:orange", lw=0.8)
    dist.set_ylabel("distance to item [m]")
    item.step(ms.t, ms["item"], where="post", label="current item")
    item.set(xlabel="time [s]", ylabel="current item")
    return _save(fig, out, "mission")


def capture_map(data: FlightData, out: Path) -> Path | None:
    caps, state = data.series["captures"], data.series["state"]
    if not len(caps):
        return None
    fig, ax = plt.subplots(figsize=(6.5, 6))
    if len(state):
        ax.plot(state["x"], state["y"], color="0.6", lw=0.8, label="flight path")
    ax.scatter(caps["x"], caps["y"], c=caps["index"], cmap="viridis", s=50, zorder=3, label="captures")
    for k, x, y in zip(caps["index"], caps["x"], caps["y"], strict=True):
        ax.annotate(str(int(k)), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set(xlabel="east [m]", ylabel="north [m]", title="capture map")
    ax.axis("equal")
    ax.legend(fontsize=7)
    return _save(fig, out, "captures")


def link(data: FlightData, out: Path, numeric: dict[str, list[tuple[float, float]]]) -> Path | None:
    if not numeric:
        return None
    fig, ax = plt.subplots(figsize=(11, 3.8))
    for key, points in sorted(numeric.items())[:12]:
        ax.plot([t for t, _ in points], [v for _, v in points], marker=".", lw=0.8, label=key)
    ax.set(xlabel="time [s]", title="telemetry link statistics")
    ax.legend(fontsize=7, ncol=3)
    return _save(fig, out, "link")

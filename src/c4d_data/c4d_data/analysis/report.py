"""Flight analysis report: one HTML page (index.html) with PNG plots next to it.

Why: after every flight the same questions come back — did it track its setpoints, how did
attitude, motors and battery behave, did the executive keep its schedule (per-task timing,
tick load, release jitter), what did health decide, how far did the mission get, where were
the pictures taken, how was the telemetry link. Every section is always present; a section
whose topic was not recorded says so instead of disappearing, so reports compare line by line.
"""

from __future__ import annotations

import html
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from ..bag_reader import BagContents, open_bag
from . import plots
from .extract import FlightData, extract
from .summary import FIGURE_LABELS, format_figure, summarize

SECTIONS = {"overview": "Recording", "summary": "Flight summary", "trajectory": "Trajectory vs setpoints",
            "tracking": "Tracking errors",
            "attitude": "Attitude and rates", "motors": "Motor outputs", "battery": "Battery",
            "executor": "Executor timing", "jitter": "Release jitter", "health": "Health and failsafe timeline",
            "mission": "Mission progress", "captures": "Capture map", "link": "Telemetry link statistics"}
MISSION_STATES = {0: "no plan", 1: "ready", 2: "active", 3: "paused", 4: "completed", 5: "aborted"}
CSS = """body{font-family:sans-serif;margin:2em;max-width:1200px}table{border-collapse:collapse;font-size:12px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#eee}td:first-child{text-align:left}
img{max-width:100%;border:1px solid #ddd}.missing{color:#a00}"""


def _table(header: list[str], rows: list[list[Any]]) -> str:
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.0f}"
        return html.escape(str(v))

    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _img(path: Path | None, missing: str) -> str:
    return f'<p><img src="{path.name}" alt="{path.stem}"></p>' if path else f'<p class="missing">{missing}</p>'


def _overview(data: FlightData) -> str:
    c = data.contents
    rows = [[name, t.type_name, t.count, t.count / c.duration_s if c.duration_s > 0 else 0.0]
            for name, t in sorted(c.topics.items())]
    state = "complete" if c.complete else f"INCOMPLETE: {html.escape(c.problem)} (run repair)"
    custom = (c.rosbag2 or {}).get("custom_data") or {}
    extra = "".join(f"<br>{html.escape(k)}: {html.escape(str(v))}" for k, v in sorted(custom.items()))
    return (f"<p>{html.escape(c.path.name)}: {c.message_count} messages, {len(c.topics)} topics, "
            f"{c.duration_s:.1f} s, {c.path.stat().st_size / 2**20:.1f} MiB, file {state}{extra}</p>"
            + _table(["topic", "type", "messages", "rate [Hz]"], rows))


def _summary(contents: BagContents) -> str:
    """The flight's figures, exactly as the fleet catalog stores them (data-value: full precision)."""
    if not contents.complete:
        return '<p class="missing">incomplete recording: run repair for the summary figures</p>'
    figures = summarize(contents)[0].as_dict()
    rows = "".join(f'<tr><td>{label}{f" [{unit}]" if unit else ""}</td><td data-figure="{key}" '
                   f'data-value="{html.escape(str(figures[key]))}">{html.escape(format_figure(figures[key]))}</td></tr>'
                   for key, (label, unit) in FIGURE_LABELS.items())
    return f'<table id="figures"><tr><th>figure</th><th>value</th></tr>{rows}</table>'


def _executor(data: FlightData, out: Path) -> str:
    parts = []
    if data.task_stats:
        agg: dict[str, dict[str, Any]] = defaultdict(lambda: defaultdict(list))
        for _, tasks in data.task_stats:
            for task in tasks:
                a = agg[task.name]
                for key in ("count", "rate_hz", "duty_mean_us", "duty_max_us", "budget_us", "budget_overruns",
                            "cpu_percent", "period_std_us", "divider"):
                    a[key].append(float(getattr(task, key)))
        schedule = {e.name: e for e in data.kept["schedule"].entries} if "schedule" in data.kept else {}
        rows = []
        for name, a in agg.items():
            n = np.array(a["count"])
            weights = n if n.sum() else None
            entry = schedule.get(name)
            rows.append([name, int(a["divider"][-1]), entry.phase if entry else "", entry.offset_us if entry else "",
                         float(np.mean(a["rate_hz"])), float(np.average(a["duty_mean_us"], weights=weights)),
                         max(a["duty_max_us"]), a["budget_us"][-1], int(sum(a["budget_overruns"])),
                         float(np.mean(a["period_std_us"])), float(np.mean(a["cpu_percent"])), int(n.sum())])
        parts.append(_table(["task", "divider", "phase", "offset [µs]", "rate [Hz]", "duty mean [µs]", "duty max [µs]",
                             "budget [µs]", "budget overruns", "period std [µs]", "CPU [%]", "runs"], rows))
    else:
        parts.append('<p class="missing">no executor statistics recorded (gnc/executor_stats)</p>')
    stats = data.series["stats"]
    if len(stats):
        parts.append(f"<p>{int(stats['ticks'].sum())} ticks, {int(stats['overruns'].sum())} overruns, load mean "
                     f"{np.mean(stats['load_mean']):.1f} %, worst tick {np.max(stats['load_max']):.1f} %, core CPU "
                     f"{np.mean(stats['cpu']):.1f} %</p>")
    if "schedule" in data.kept:
        s = data.kept["schedule"]
        parts.append(f"<p>schedule: method {html.escape(s.method)}, Ω {s.omega_us:.0f} µs, Σδ {s.sum_delta_us:.0f} µs, "
                     f"certificate {'holds' if s.certificate_holds else 'does not hold'}</p>")
    parts.append(_img(plots.tick_load(data, out), "no tick-load data recorded"))
    return "".join(parts)


def _health(data: FlightData, out: Path) -> str:
    rows, last = [], None
    for t, m in data.events.get("health", []):
        values = {kv.key: kv.value for kv in m.values}
        key = (m.message, values.get("failsafe"), values.get("reason"), values.get("active"), values.get("dead_nodes"))
        if key != last:
            rows.append([f"{t:.2f}", m.message, values.get("failsafe", ""), values.get("reason", ""),
                         values.get("active", ""), values.get("dead_nodes", "")])
            last = key
    table = _table(["t [s]", "summary", "failsafe", "reason", "active events", "dead nodes"], rows) if rows else \
        '<p class="missing">no health summary recorded (health/summary)</p>'
    return _img(plots.health(data, out), "no vehicle status or health recorded") + table


def _mission(data: FlightData, out: Path) -> str:
    ms = data.series["mission"]
    rows, last = [], None
    for k in range(len(ms)):
        key = (int(ms["state"][k]), int(ms["item"][k]))
        if key != last:
            rows.append([f"{ms.t[k]:.2f}", MISSION_STATES.get(key[0], key[0]), key[1], int(ms["total"][k]),
                         float(100 * ms["progress"][k])])
            last = key
    table = _table(["t [s]", "state", "item", "items", "progress [%]"], rows) if rows else ""
    return _img(plots.mission(data, out), "no mission state recorded (mission/state)") + table


def _captures(data: FlightData, out: Path) -> str:
    caps = data.series["captures"]
    rows = [[int(caps["index"][k]), f"{caps.t[k]:.2f}", caps["x"][k], caps["y"][k], caps["z"][k]] for k in range(len(caps))]
    table = _table(["capture", "t [s]", "east [m]", "north [m]", "up [m]"], rows) if rows else ""
    return _img(plots.capture_map(data, out), "no captures recorded (payload/captures)") + table


def _flatten(message: Any, prefix: str = "") -> dict[str, Any]:
    """Key/values of any link-statistics message: DiagnosticArray/Status key-values, or plain fields."""
    if hasattr(message, "status") and isinstance(message.status, list):
        out: dict[str, Any] = {}
        for status in message.status:
            out.update(_flatten(status, f"{status.name}/" if status.name else ""))
        return out
    if hasattr(message, "values") and isinstance(message.values, list):
        return {prefix + kv.key: kv.value for kv in message.values}
    fields = {k: v for k, v in vars(message).items() if isinstance(v, (int, float, str, bool)) and not k.startswith("_")}
    return {prefix + k: v for k, v in fields.items()}


def _link(data: FlightData, out: Path) -> str:
    events = data.events.get("link", [])
    if not events:
        return '<p class="missing">no link statistics recorded (bridge/link_stats)</p>'
    numeric: dict[str, list[tuple[float, float]]] = defaultdict(list)
    last: dict[str, Any] = {}
    for t, m in events:
        for key, value in _flatten(m).items():
            last[key] = value
            try:
                numeric[key].append((t, float(value)))
            except (TypeError, ValueError):
                pass
    table = _table(["key", "last value"], [[k, v] for k, v in sorted(last.items())])
    plot = _img(plots.link(data, out, numeric), "no numeric link figures")
    return f"<p>{len(events)} link statistics messages</p>{plot}{table}"


def write_report(bag: str | Path, out: str | Path, progress: bool = True) -> Path:
    """Analyse `bag` and write out/index.html with its PNG plots; returns the index path."""
    contents = open_bag(bag)
    data = extract(contents, progress=progress)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    body = {
        "overview": _overview(data),
        "summary": _summary(contents),
        "trajectory": _img(plots.trajectory(data, out), "no state estimate recorded (navigation/state)"),
        "tracking": _img(plots.tracking(data, out), "no guidance setpoints recorded (guidance/setpoint): nothing to track"),
        "attitude": _img(plots.attitude(data, out), "no state estimate recorded (navigation/state)"),
        "motors": _img(plots.motors(data, out), "no actuator commands recorded (control/actuators)"),
        "battery": _img(plots.battery(data, out), "no battery state recorded (sensors/battery)"),
        "executor": _executor(data, out),
        "jitter": _img(plots.jitter(data, out), "no executor statistics or actuator commands recorded"),
        "health": _health(data, out),
        "mission": _mission(data, out),
        "captures": _captures(data, out),
        "link": _link(data, out),
    }
    toc = "".join(f'<li><a href="#{key}">{title}</a></li>' for key, title in SECTIONS.items())
    sections = "".join(f'<section id="{key}"><h2>{title}</h2>{body[key]}</section>' for key, title in SECTIONS.items())
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Flight report — {html.escape(contents.path.name)}"
            f"</title><style>{CSS}</style></head><body><h1>Flight report — {html.escape(contents.path.name)}</h1>"
            f"<ul>{toc}</ul>{sections}</body></html>")
    index = out / "index.html"
    index.write_text(page)
    return index

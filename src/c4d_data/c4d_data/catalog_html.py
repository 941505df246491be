"""The catalog's static HTML index: a sortable table of every flight (links to each flight's
report and file) and cross-flight trend plots — a first prognostics view.

Why static: the index must open from a USB stick or a CI artifact with no server and no network
(plots are PNG files next to index.html, sorting is 20 lines of inline script). The trend plots
show per vehicle, over its flights in time order, what wears: energy per km (battery and
propulsion ageing), tracking error (tuning, vibration, mechanical play), worst tick load
(computer margin); the trend table fits a straight line to energy per km per vehicle and says
by how much it grows per 100 flights.
"""

from __future__ import annotations

import html
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from .analysis.summary import FIGURE_LABELS, format_figure

TABLE = ["start_utc", "vehicle", "airframe", "duration_s", "distance_m", "max_altitude_m", "tracking_rms_m",
         "tracking_max_m", "overruns", "worst_tick_load_pct", "failsafes", "battery_used_pct", "energy_wh_per_km",
         "captures"]
HEAD = {"start_utc": "start (UTC)", "vehicle": "vehicle", "airframe": "airframe"} | {
    k: f"{label} [{unit}]" if unit else label for k, (label, unit) in FIGURE_LABELS.items()}
TRENDS = [("energy_wh_per_km", "energy per km [Wh/km]", "trend_energy_per_km"),
          ("tracking_rms_m", "tracking error RMS [m]", "trend_tracking"),
          ("worst_tick_load_pct", "worst tick load [%]", "trend_tick_load"),
          ("battery_used_pct", "battery used [%]", "trend_battery")]
CSS = """body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;font-size:12px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#eee;cursor:pointer;user-select:none}
td.t{text-align:left}img{max-width:48%;border:1px solid #ddd;margin:2px}th.asc:after{content:" \\25B2"}
th.desc:after{content:" \\25BC"}"""
SCRIPT = """document.querySelectorAll("table.sortable th").forEach(function (th) {
  th.addEventListener("click", function () {
    var table = th.closest("table"), body = table.tBodies[0], col = th.cellIndex;
    var asc = !th.classList.contains("asc");
    table.querySelectorAll("th").forEach(function (h) { h.classList.remove("asc", "desc"); });
    th.classList.add(asc ? "asc" : "desc");
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = a.cells[col].dataset.v, y = b.cells[col].dataset.v;
      var nx = parseFloat(x), ny = parseFloat(y), c;
      if (x === "" || y === "") { c = (x === "") - (y === ""); return c; }
      c = (isNaN(nx) || isNaN(ny)) ? x.localeCompare(y) : nx - ny;
      return asc ? c : -c;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  });
});"""


def _series(flights: list[dict[str, Any]], key: str) -> dict[str, tuple[list[int], list[float]]]:
    """vehicle -> (flight number of that vehicle, value) where the value exists."""
    out: dict[str, tuple[list[int], list[float]]] = defaultdict(lambda: ([], []))
    count: dict[str, int] = defaultdict(int)
    for f in flights:  # flights come in start order
        vehicle = f["vehicle"] or "?"
        count[vehicle] += 1
        if f[key] is not None:
            out[vehicle][0].append(count[vehicle])
            out[vehicle][1].append(float(f[key]))
    return dict(out)


def _trend_plot(flights: list[dict[str, Any]], key: str, label: str, out: Path, name: str) -> Path | None:
    series = _series(flights, key)
    if not any(v for _, v in series.values()):
        return None
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for vehicle, (n, v) in sorted(series.items()):
        ax.plot(n, v, ".", ms=4, label=vehicle)
        if len(n) >= 3:
            slope, intercept = np.polyfit(n, v, 1)
            ax.plot([n[0], n[-1]], [intercept + slope * n[0], intercept + slope * n[-1]], "-", lw=1, alpha=0.7)
    ax.set(xlabel="flight number of the vehicle", ylabel=label, title=f"{label} over flights (line: linear fit)")
    if len(series) <= 12:
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    path = out / f"{name}.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def prognostics(flights: list[dict[str, Any]]) -> list[list[Any]]:
    """Per vehicle: flights, energy per km of the fit at the first and last flight, growth per 100 flights [%]."""
    rows = []
    for vehicle, (n, v) in sorted(_series(flights, "energy_wh_per_km").items()):
        if len(n) < 3:
            rows.append([vehicle, len(n), None, None, None])
            continue
        slope, intercept = np.polyfit(n, v, 1)
        first, last = intercept + slope * n[0], intercept + slope * n[-1]
        rows.append([vehicle, len(n), float(first), float(last), float(100 * 100 * slope / first) if first else None])
    return rows


def _cell(key: str, value: Any, text: str | None = None) -> str:
    raw = "" if value is None else str(value)
    shown = text if text is not None else (html.escape(raw) if isinstance(value, str) else format_figure(value))
    cls = ' class="t"' if isinstance(value, str) or value is None and key in ("vehicle", "airframe") else ""
    return f'<td{cls} data-v="{html.escape(raw)}">{shown}</td>'


def write_index(flights: list[dict[str, Any]], out: str | Path) -> Path:
    """Write out/index.html (+ trend PNGs); `flights` are catalog rows in start order."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    head = "".join(f"<th>{html.escape(HEAD[k])}</th>" for k in TABLE) + "<th>report</th><th>file</th>"
    rows = []
    for f in flights:
        cells = "".join(_cell(k, f[k]) for k in TABLE)
        report = (f'<a href="{html.escape(os.path.relpath(f["report"], out))}">report</a>'
                  if f["report"] else "—")
        name = Path(f["file"]).name
        link = f'<a href="{html.escape(os.path.relpath(f["file"], out))}">{html.escape(name)}</a>'
        rows.append(f"<tr>{cells}{_cell('report', 'report' if f['report'] else '', report)}"
                    f"{_cell('file', name, link)}</tr>")
    plots = []
    for key, label, name in TRENDS:
        path = _trend_plot(flights, key, label, out, name)
        plots.append(f'<img src="{path.name}" alt="{html.escape(label)}">' if path
                     else f"<p>{html.escape(label)}: not recorded in any flight</p>")
    trend_rows = "".join("<tr>" + "".join(_cell("", v) for v in r) + "</tr>" for r in prognostics(flights))
    vehicles = len({f["vehicle"] for f in flights})
    hours = sum(f["duration_s"] or 0 for f in flights) / 3600
    km = sum(f["distance_m"] or 0 for f in flights) / 1000
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Flight catalog</title><style>{CSS}</style>"
            f"</head><body><h1>Flight catalog</h1><p>{len(flights)} flights, {vehicles} vehicles, {hours:.2f} h, "
            f"{km:.2f} km flown. Click a column header to sort.</p>"
            f"<h2>Trends over flights</h2>{''.join(plots)}"
            "<h3>Energy per km trend (linear fit per vehicle)</h3><table class='sortable'><thead><tr><th>vehicle</th>"
            "<th>flights</th><th>first [Wh/km]</th><th>last [Wh/km]</th><th>growth per 100 flights [%]</th></tr></thead>"
            f"<tbody>{trend_rows}</tbody></table>"
            f"<h2>Flights</h2><table class='sortable' id='flights'><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table><script>{SCRIPT}</script></body></html>")
    index = out / "index.html"
    index.write_text(page)
    return index

"""The re-simulation diff report: one HTML page with summary figures and matplotlib PNGs (like
c4d_data.analysis): trajectory recorded vs re-simulated, estimate and command differences over time,
first divergence of each stream marked."""

from __future__ import annotations

import html
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from .run import Result, Stream


def _divergence(ax, stream: Stream, t0: float) -> None:
    if stream.first_divergence is not None:
        ax.axvline(stream.first_divergence - t0, color="tab:red", linestyle="--", label="first divergence")
        ax.legend(loc="upper left")


def _figures(r: Result, out: Path) -> list[str]:
    names, t0 = [], r.core_start_s
    s = r.state
    if s.t:
        fig, ax = plt.subplots(figsize=(6, 5))
        ax.plot([v[0] for v in s.recorded], [v[1] for v in s.recorded], label="recorded", lw=2)
        ax.plot([v[0] for v in s.resim], [v[1] for v in s.resim], label="re-simulated", lw=1, ls="--")
        ax.set_xlabel("east [m]")
        ax.set_ylabel("north [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend()
        ax.set_title("navigation/state position")
        fig.savefig(out / "trajectory.png", dpi=90)
        plt.close(fig)
        names.append("trajectory.png")
    for stream, unit, name in ((r.state, "max |Δ position, velocity| [m, m/s]", "state_diff.png"),
                               (r.actuators, "max |Δ motor command| [-]", "command_diff.png")):
        if not stream.t:
            continue
        fig, ax = plt.subplots(figsize=(9, 3.2))
        ax.plot([t - t0 for t in stream.t], stream.diff, lw=1)
        ax.set_xlabel("time since arm [s]")
        ax.set_ylabel(unit)
        ax.set_title(stream.name)
        _divergence(ax, stream, t0)
        fig.tight_layout()
        fig.savefig(out / name, dpi=90)
        plt.close(fig)
        names.append(name)
    return names


def _row(stream: Stream, t0: float) -> str:
    first = "none (bit-identical)" if stream.first_divergence is None else (
        f"{stream.first_divergence - t0:.3f} s after arm (key {stream.first_key})")
    return (f"<tr><td>{stream.name}</td><td>{stream.compared}</td><td>{stream.identical}</td>"
            f"<td>{stream.only_resim}</td><td>{first}</td><td>{stream.max_diff:.6g}</td></tr>")


def write(r: Result, out: Path) -> Path:
    """Write `out`/index.html (+ PNGs); returns the page."""
    out.mkdir(parents=True, exist_ok=True)
    figures = _figures(r, out)
    rate = r.flight_s / r.wall_s if r.wall_s > 0 else float("inf")
    nav = (f"navigation {r.nav_wall_s:.2f} s of it" if r.processes == 1
           else f"navigation in a second process, busy {r.nav_wall_s:.2f} s alongside the core")
    problems = "".join(f"<li>{html.escape(k)}: {v} sample(s) named by the journal but not in the file</li>"
                       for k, v in r.counts.missing.items())
    problems += "".join(f"<li>{html.escape(k)}: {v} input(s) not re-simulated</li>"
                        for k, v in r.counts.unsupported.items())
    if r.flight.nav.lost or r.flight.core.lost:
        problems += f"<li>journal batches lost: navigation {r.flight.nav.lost}, core {r.flight.core.lost}</li>"
    modes = "same" if r.modes_resim == r.modes_recorded[-len(r.modes_resim):] else "different"
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>resim {html.escape(r.flight.path.name)}</title>
<style>body{{font-family:sans-serif;margin:2em}} table{{border-collapse:collapse}}
td,th{{border:1px solid #999;padding:4px 8px}}</style>
</head><body><h1>Re-simulation of {html.escape(r.flight.path.name)}</h1>
<p>Overrides: {html.escape(' '.join(r.overrides) or 'none')} — verdict: <b>{'bit-identical' if r.exact else 'differs'}</b></p>
<p>Re-simulated {r.flight_s:.1f} s of flight (from the core's arm snapshot) in {r.wall_s:.2f} s: {rate:.1f}× real time
({nav}).</p>
<table><tr><th>stream</th><th>compared</th><th>identical</th><th>not in the recording</th><th>first divergence</th>
<th>max difference</th></tr>{_row(r.state, r.core_start_s)}{_row(r.actuators, r.core_start_s)}</table>
<p>Mode sequence (armed, mode, nav) re-simulated: {html.escape(str(r.modes_resim))} — recorded vehicle/status: {modes}</p>
<ul>{problems or '<li>every journalled input was found and re-run</li>'}</ul>
{''.join(f'<p><img src="{n}" alt="{n}"></p>' for n in figures)}
</body></html>"""
    index = out / "index.html"
    index.write_text(page)
    return index

"""Flight catalog (issue 21 items 4-5) without a graph: 200 synthetic flights written with the
project's MCAP writer, plus files that must be skipped (not an MCAP, another tool's MCAP,
interrupted, damaged chunk).

- the streaming summary equals an independent computation from the report's own series
  (analysis.extract, numpy over whole arrays);
- every catalog row equals that summary (SQL through the command line);
- re-indexing adds nothing; a changed file is re-indexed alone; a removed one leaves;
- bad files give one warning line each and never stop the run; exit codes for bad arguments,
  bad SQL and nothing indexable.
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from c4d_data.analysis.extract import extract
from c4d_data.analysis.summary import SETPOINT_GAP_S, summarize
from c4d_data.bag_reader import open_bag
from c4d_data.bag_writer import BagWriter
from c4d_data.catalog import main as catalog
from c4d_data.catalog_synthetic import FlightSpec, fleet_specs, write_flight

COUNT = 200


def reference(path: Path) -> dict[str, float]:
    """The summary figures recomputed from the report's series (whole arrays, numpy)."""
    data = extract(open_bag(path), progress=False)
    st, sp, bat, stats, status = (data.series[k] for k in ("state", "setpoint", "battery", "stats", "status"))
    dt = np.diff(st.t)
    speed = np.sqrt(st["vx"] ** 2 + st["vy"] ** 2 + st["vz"] ** 2)
    ok = (dt > 0) & (dt <= SETPOINT_GAP_S)
    right = np.searchsorted(sp.t, st.t, side="left")
    inside = (right > 0) & (right < len(sp.t))
    inside[inside] &= (sp.t[right[inside]] - sp.t[right[inside] - 1]) <= SETPOINT_GAP_S
    err = np.sqrt(sum((st[c][inside] - np.interp(st.t[inside], sp.t, sp[c])) ** 2 for c in "xyz"))
    bdt = np.diff(bat.t)
    power = bat["voltage"][1:] * np.abs(bat["current"][1:])
    fs = status["failsafe"].astype(int)
    entries = [k for k in range(len(fs)) if fs[k] in (2, 3, 4, 5) and (k == 0 or fs[k] != fs[k - 1])]
    return {"distance_m": float(np.sum(speed[1:][ok] * dt[ok])), "max_altitude_m": float(st["z"].max()),
            "tracking_rms_m": float(np.sqrt(np.mean(err ** 2))), "tracking_max_m": float(err.max()),
            "tracking_samples": int(inside.sum()), "overruns": int(stats["overruns"].sum()),
            "worst_tick_load_pct": float(stats["load_max"].max()), "failsafes": len(entries),
            "battery_used_pct": float(100 * (bat["percentage"][0] - bat["percentage"][-1])),
            "energy_wh": float(np.sum(power[(bdt > 0) & (bdt <= 5)] * bdt[(bdt > 0) & (bdt <= 5)]) / 3600),
            "captures": len(data.series["captures"])}


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """200 short synthetic flights over 4 vehicles (one in 17 with an RTL failsafe) + bad files."""
    root = tmp_path_factory.mktemp("fleet")
    for k, spec in enumerate(fleet_specs(COUNT, duration_s=3.0, state_hz=20.0, bulk=False)):
        folder = root / f"v{k % 4}"
        folder.mkdir(exist_ok=True)
        write_flight(folder / f"flight_{k:04d}.mcap", spec)
    bad = root / "bad"
    bad.mkdir()
    (bad / "notes.mcap").write_text("this is not a recording\n")
    foreign = BagWriter(bad / "foreign.mcap")
    foreign.add_topic("/chatter", "std_msgs/msg/String", "string data\n", "")
    foreign.write("/chatter", b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00", 1, 1)
    foreign.close()
    whole = write_flight(bad / "whole.mcap", FlightSpec(seed=999, duration_s=20.0, state_hz=100.0))
    data = whole.read_bytes()
    (bad / "interrupted.mcap").write_bytes(data[: len(data) * 6 // 10])  # a crash: no summary
    damaged = bytearray(data)
    middle = len(damaged) // 3
    damaged[middle:middle + 64] = bytes(64)  # inside a zstd chunk: the summary still indexes it
    (bad / "damaged.mcap").write_bytes(bytes(damaged))
    whole.unlink()
    return root


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    code = catalog(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_summary_equals_an_independent_computation(tmp_path):
    path = write_flight(tmp_path / "f.mcap", FlightSpec(seed=3, duration_s=30.0, state_hz=100.0, failsafe_at_s=20.0))
    figures = summarize(open_bag(path))[0].as_dict()
    ref = reference(path)
    assert figures["failsafes"] == ref["failsafes"] == 1 and figures["failsafe_actions"] == "RTL"
    assert figures["captures"] == ref["captures"] > 0
    assert figures["overruns"] == ref["overruns"]
    assert abs(figures["tracking_samples"] - ref["tracking_samples"]) <= 2  # log-time ties at the stream's two ends
    for key in ("distance_m", "max_altitude_m", "worst_tick_load_pct", "battery_used_pct", "energy_wh"):
        assert figures[key] == pytest.approx(ref[key], rel=1e-9), key
    for key in ("tracking_rms_m", "tracking_max_m"):
        assert figures[key] == pytest.approx(ref[key], rel=1e-3), key
    assert figures["energy_wh_per_km"] == pytest.approx(figures["energy_wh"] / figures["distance_m"] * 1000)


def test_catalog_of_200_flights_matches_their_summaries(fleet, capsys):
    db = fleet / "catalog.sqlite"
    code, out, err = _run([str(fleet), "--db", str(db), "-j", "2"], capsys)
    assert code == 0, err
    assert f"{COUNT} flights indexed, 0 unchanged, 4 skipped" in out, out
    warnings = err.strip().splitlines()
    assert len(warnings) == 4, err
    by_file = {Path(line.split(": ")[2]).name: line for line in warnings}
    assert "not an MCAP file" in by_file["notes.mcap"]
    assert "not a c4d flight" in by_file["foreign.mcap"] and "/navigation/state" in by_file["foreign.mcap"] \
        and "/chatter" in by_file["foreign.mcap"]
    assert "incomplete recording" in by_file["interrupted.mcap"] and "repair" in by_file["interrupted.mcap"]
    assert "damaged" in by_file["damaged.mcap"]
    con = sqlite3.connect(db)
    rows = {Path(r[0]).name: r for r in con.execute(
        "SELECT file, vehicle, airframe, duration_s, distance_m, max_altitude_m, tracking_rms_m, tracking_max_m, "
        "overruns, worst_tick_load_pct, failsafes, battery_used_pct, energy_wh_per_km, captures FROM flights")}
    assert len(rows) == COUNT
    assert con.execute("SELECT count(DISTINCT flight_id) FROM bins").fetchone()[0] == COUNT
    assert {r[1] for r in rows.values()} == {"synth-1", "synth-2", "synth-3", "synth-4"}
    assert sum(r[10] for r in rows.values()) == len([k for k in range(COUNT) if k % 17 == 5])
    for name in sorted(rows)[::10]:  # every 10th flight against its own summary
        path = next(fleet.rglob(name))
        f = summarize(open_bag(path))[0].as_dict()
        expected = [f[k] for k in ("duration_s", "distance_m", "max_altitude_m", "tracking_rms_m", "tracking_max_m",
                                   "overruns", "worst_tick_load_pct", "failsafes", "battery_used_pct",
                                   "energy_wh_per_km", "captures")]
        assert list(rows[name][3:]) == expected, name

    # the same through --sql (text table, 10 significant digits)
    code, out, err = _run(["--db", str(db), "--sql", "SELECT vehicle, count(*) AS n, round(sum(distance_m), 3) AS km "
                           "FROM flights GROUP BY vehicle ORDER BY vehicle"], capsys)
    assert code == 0, err
    lines = out.strip().splitlines()
    assert lines[0].split() == ["vehicle", "n", "km"] and lines[-1] == "(4 rows)"
    for line in lines[2:-1]:
        vehicle, n, km = line.split()
        expected = con.execute("SELECT count(*), round(sum(distance_m), 3) FROM flights WHERE vehicle = ?",
                               (vehicle,)).fetchone()
        assert (int(n), float(km)) == expected

    # re-index: nothing new, rows untouched (same indexed_at and ids)
    before = con.execute("SELECT id, file, indexed_at FROM flights ORDER BY id").fetchall()
    code, out, err = _run([str(fleet), "--db", str(db)], capsys)
    assert code == 0 and f"0 flights indexed, {COUNT} unchanged, 0 skipped, 4 skipped before" in out, out + err
    assert err == ""
    assert con.execute("SELECT id, file, indexed_at FROM flights ORDER BY id").fetchall() == before

    # one file changed, one removed: exactly those move
    changed = next(fleet.rglob("flight_0007.mcap"))
    changed.unlink()
    write_flight(changed, FlightSpec(seed=7007, duration_s=5.0, state_hz=20.0))
    os.utime(changed, ns=(changed.stat().st_atime_ns, changed.stat().st_mtime_ns + 10**9))
    next(fleet.rglob("flight_0008.mcap")).unlink()
    code, out, err = _run([str(fleet), "--db", str(db)], capsys)
    assert code == 0 and f"1 flights indexed, {COUNT - 2} unchanged" in out and f"; {COUNT - 1} in" in out, out
    assert con.execute("SELECT duration_s FROM flights WHERE file = ?", (str(changed.resolve()),)).fetchone()[0] \
        == pytest.approx(5.0)
    con.close()


def test_bad_arguments_and_sql(fleet, tmp_path, capsys):
    code, _, err = _run([str(tmp_path / "nowhere")], capsys)
    assert code == 2 and err.count("\n") == 1 and "no such folder" in err
    code, _, err = _run([str(fleet / "bad"), "--db", str(tmp_path / "bad.sqlite")], capsys)
    assert code == 1 and "nothing could be indexed" in err  # the four warnings, then the error
    empty = tmp_path / "empty"
    empty.mkdir()
    code, _, err = _run([str(empty)], capsys)
    assert code == 1 and "no *.mcap files" in err
    code, out, err = _run(["--db", str(fleet / "catalog.sqlite"), "--sql", "SELEC * FROM flights"], capsys)
    assert code == 1 and err.startswith("catalog: error: SQL: ") and err.count("\n") == 1 and out == ""
    code, _, err = _run(["--db", str(fleet / "catalog.sqlite"), "--sql", "DELETE FROM flights"], capsys)
    assert code == 1 and "readonly" in err  # queries never change the catalog
    code, _, err = _run(["--db", str(tmp_path / "none.sqlite"), "--sql", "SELECT 1"], capsys)
    assert code == 1 and "no catalog database" in err
    with pytest.raises(SystemExit) as exc:
        catalog([])
    assert exc.value.code == 2

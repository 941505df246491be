"""The flight catalog's database: an SQLite file with one row per flight, its 10-s bins, and
the files that could not be indexed.

Why SQLite (not DuckDB): it is in Python's standard library (no pin, no 50 MB wheel, nothing
to build on an onboard computer or a ground station), a single file that any tool opens, and
safe to update incrementally in place. A fleet's catalog is small — one row per flight plus
one per 10 s of flight, ~360 000 bin rows for 1000 one-hour flights — so a row store answers
the cross-flight queries (GROUP BY vehicle, window functions for trends) in milliseconds; a
columnar engine would only pay off at a hundred times that.

Incremental: a file is (re)indexed only when its path is new or its size or modification time
changed; files that failed are remembered the same way in `skipped` and retried only when they
change.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

FLIGHT_COLUMNS: list[tuple[str, str, str]] = [  # name, SQL type, description (docs/data.md schema table)
    ("id", "INTEGER PRIMARY KEY", "row id (bins.flight_id)"),
    ("file", "TEXT UNIQUE NOT NULL", "absolute path of the MCAP file"),
    ("size_bytes", "INTEGER", "file size when indexed"),
    ("mtime_ns", "INTEGER", "file modification time when indexed [ns]"),
    ("vehicle", "TEXT", "custom data c4d.vehicle, else the first folder below the catalogued folder"),
    ("airframe", "TEXT", "custom data c4d.airframe, else '<n> motors' from control/actuators"),
    ("start_utc", "TEXT", "first message, ISO 8601 UTC"),
    ("start_ns", "INTEGER", "first message log time [ns since the epoch]"),
    ("duration_s", "REAL", "last - first message [s]"),
    ("messages", "INTEGER", "messages in the file"),
    ("distance_m", "REAL", "integral of |estimated velocity| [m]"),
    ("max_altitude_m", "REAL", "highest estimated altitude above home [m]"),
    ("tracking_rms_m", "REAL", "RMS |estimate - interpolated setpoint| [m]"),
    ("tracking_max_m", "REAL", "max |estimate - interpolated setpoint| [m]"),
    ("tracking_samples", "INTEGER", "state samples the tracking figures use"),
    ("overruns", "INTEGER", "executive tick overruns (gnc/executor_stats)"),
    ("ticks", "INTEGER", "executive ticks in the statistics windows"),
    ("worst_tick_load_pct", "REAL", "worst tick busy time / tick period [%]"),
    ("failsafes", "INTEGER", "entries into HOLD/RTL/LAND/TERMINATE"),
    ("failsafe_actions", "TEXT", "their sequence, e.g. RTL>LAND"),
    ("battery_used_pct", "REAL", "first - last state of charge [%]"),
    ("energy_wh", "REAL", "integral of voltage * |current| [Wh]"),
    ("energy_wh_per_km", "REAL", "energy / distance [Wh/km] (NULL under 10 m)"),
    ("captures", "INTEGER", "payload captures (NULL: topic not recorded)"),
    ("report", "TEXT", "the flight's report (index.html), NULL until --html made or found one"),
    ("indexed_at", "TEXT", "when this row was written (UTC)"),
]
BIN_COLUMNS: list[tuple[str, str, str]] = [
    ("flight_id", "INTEGER NOT NULL REFERENCES flights(id) ON DELETE CASCADE", "flights.id"),
    ("bin", "INTEGER NOT NULL", "bin number: t_start_s / 10"),
    ("t_start_s", "REAL", "bin start from the start of the recording [s]"),
    ("altitude_max_m", "REAL", "highest estimated altitude [m]"),
    ("altitude_mean_m", "REAL", "mean estimated altitude [m]"),
    ("speed_mean_m_s", "REAL", "mean |estimated velocity| [m/s]"),
    ("tracking_rms_m", "REAL", "RMS tracking error of the samples in the bin [m]"),
    ("voltage_mean_v", "REAL", "mean battery voltage [V]"),
    ("power_mean_w", "REAL", "mean battery power [W]"),
    ("load_max_pct", "REAL", "worst tick load of the statistics windows ending in the bin [%]"),
    ("overruns", "INTEGER", "overruns of those windows"),
]
SCHEMA = (
    "CREATE TABLE IF NOT EXISTS flights (" + ", ".join(f"{n} {t}" for n, t, _ in FLIGHT_COLUMNS) + ");"
    "CREATE TABLE IF NOT EXISTS bins (" + ", ".join(f"{n} {t}" for n, t, _ in BIN_COLUMNS)
    + ", PRIMARY KEY (flight_id, bin));"
    "CREATE TABLE IF NOT EXISTS skipped (file TEXT PRIMARY KEY, size_bytes INTEGER, mtime_ns INTEGER, reason TEXT);"
    "CREATE INDEX IF NOT EXISTS flights_vehicle ON flights (vehicle, start_ns);"
)


class CatalogDB:
    """Read/write access to one catalog file (one writer: the catalog command's main process)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.con = sqlite3.connect(self.path)
        self.con.execute("PRAGMA foreign_keys = ON")
        self.con.executescript(SCHEMA)

    def close(self) -> None:
        self.con.close()

    def known(self) -> dict[str, tuple[int, int, bool]]:
        """file -> (size, mtime_ns, indexed) of every file seen before (indexed False: skipped)."""
        rows = {f: (s, m, True) for f, s, m in self.con.execute("SELECT file, size_bytes, mtime_ns FROM flights")}
        for f, s, m in self.con.execute("SELECT file, size_bytes, mtime_ns FROM skipped"):
            rows.setdefault(f, (s, m, False))
        return rows

    def put_flight(self, row: dict[str, Any], bins: Iterable[dict[str, Any]]) -> int:
        """Insert or replace a flight (and its bins); returns its id."""
        with self.con:
            self.con.execute("DELETE FROM flights WHERE file = ?", (row["file"],))
            self.con.execute("DELETE FROM skipped WHERE file = ?", (row["file"],))
            names = [n for n, _, _ in FLIGHT_COLUMNS if n != "id" and n in row]
            cur = self.con.execute(f"INSERT INTO flights ({', '.join(names)}) VALUES ({', '.join('?' * len(names))})",
                                   [row[n] for n in names])
            flight_id = int(cur.lastrowid or 0)
            bin_names = [n for n, _, _ in BIN_COLUMNS]
            self.con.executemany(f"INSERT INTO bins ({', '.join(bin_names)}) VALUES ({', '.join('?' * len(bin_names))})",
                                 [[flight_id] + [b[n] for n in bin_names[1:]] for b in bins])
        return flight_id

    def put_skipped(self, file: str, size: int, mtime_ns: int, reason: str) -> None:
        with self.con:
            self.con.execute("DELETE FROM flights WHERE file = ?", (file,))
            self.con.execute("INSERT OR REPLACE INTO skipped VALUES (?, ?, ?, ?)", (file, size, mtime_ns, reason))

    def set_report(self, flight_id: int, report: str | None) -> None:
        with self.con:
            self.con.execute("UPDATE flights SET report = ? WHERE id = ?", (report, flight_id))

    def forget(self, files: Iterable[str]) -> int:
        """Remove files that no longer exist; returns how many flights went."""
        gone = list(files)
        with self.con:
            n = sum(self.con.execute("DELETE FROM flights WHERE file = ?", (f,)).rowcount for f in gone)
            self.con.executemany("DELETE FROM skipped WHERE file = ?", [(f,) for f in gone])
        return n

    def flights(self) -> list[dict[str, Any]]:
        cur = self.con.execute("SELECT * FROM flights ORDER BY start_ns, file")
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur]


def run_query(path: str | Path, sql: str) -> tuple[list[str], list[Sequence[Any]]]:
    """Run one SQL statement on the catalog, read-only; raises sqlite3.Error on bad SQL."""
    path = Path(path)
    if not path.is_file():
        raise sqlite3.OperationalError(f"no catalog database at {path} (index some folders first)")
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        cur = con.execute(sql)
        names = [d[0] for d in cur.description] if cur.description else []
        return names, cur.fetchall()
    finally:
        con.close()


def format_table(names: list[str], rows: list[Sequence[Any]]) -> str:
    """Aligned text table; floats with 10 significant digits, NULL as empty."""
    def cell(v: Any) -> str:
        if v is None:
            return ""
        if isinstance(v, float):
            return f"{v:.10g}"
        return str(v)

    text = [[cell(v) for v in r] for r in rows]
    widths = [max([len(n)] + [len(r[k]) for r in text]) for k, n in enumerate(names)]
    lines = ["  ".join(n.ljust(w) for n, w in zip(names, widths, strict=True)).rstrip(),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip() for r in text]
    lines.append(f"({len(rows)} row{'s' if len(rows) != 1 else ''})")
    return "\n".join(lines)

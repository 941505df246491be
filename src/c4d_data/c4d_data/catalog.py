"""`catalog DIR… [--db PATH] [--sql QUERY] [--html OUT_DIR]`: the fleet flight catalog.

Indexes every flight recording (*.mcap) under the given folders into an SQLite database (one
row per flight, 10-s bins; catalog_db.py), answers SQL from the command line and writes a static
HTML index with cross-flight trend plots (catalog_html.py).

Why this shape: the per-flight figures are the ones of the flight's own report (the same
streaming FlightSummarizer, analysis/summary.py), so the catalog and the report never disagree.
Files are indexed in a process pool, each streamed message by message (memory bounded whatever
the file's length; only the few summary topics are decoded), and only files that are new or
changed (path, size, modification time) are read again. A file that cannot be indexed — not an
MCAP, damaged, interrupted (repair it first), or from another tool (no c4d topics) — gives one
warning line and is skipped; the exit status is non-zero only for bad arguments (2) or when
nothing at all could be indexed (1).
"""

from __future__ import annotations

import argparse
import os
import sqlite3
import sys
import time
from collections.abc import Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from .bag_reader import BagError, Decoders, iter_messages, open_bag
from .catalog_db import CatalogDB, format_table, run_query

DEFAULT_DB = "catalog.sqlite"
ACTUATORS = "/control/actuators"


def find_flights(roots: list[Path]) -> list[tuple[Path, Path]]:
    """(file, root) of every *.mcap under the roots, sorted, each file once."""
    seen: dict[Path, Path] = {}
    for root in roots:
        for path in sorted(root.rglob("*.mcap")):
            if path.is_file():
                seen.setdefault(path.resolve(), root.resolve())
    return sorted(seen.items())


def _vehicle(path: Path, root: Path, custom: dict[str, Any]) -> str:
    if custom.get("c4d.vehicle"):
        return str(custom["c4d.vehicle"])
    rel = path.relative_to(root)
    return rel.parts[0] if len(rel.parts) > 1 else root.name


def _airframe(contents: Any, custom: dict[str, Any]) -> str | None:
    if custom.get("c4d.airframe"):
        return str(custom["c4d.airframe"])
    if ACTUATORS not in contents.topics:
        return None
    decoders = Decoders()
    for topic, message in iter_messages(contents, [ACTUATORS], log_time_order=False):
        return f"{len(decoders.decode(topic, message.data).outputs)} motors"
    return None


def index_file(path: str, root: str) -> dict[str, Any]:
    """Worker (process pool): the catalog row and bins of one file, or {'error': reason}.
    Never raises: one bad file must not stop the others."""
    from .analysis.summary import CORE_TOPICS, missing_topics, summarize

    file = Path(path)
    try:
        st = file.stat()
        contents = open_bag(file)
        if not contents.complete:
            return {"error": f"incomplete recording ({contents.problem}): run `repair {file}` first",
                    "size": st.st_size, "mtime_ns": st.st_mtime_ns}
        missing = missing_topics(contents)
        if len(missing) == len(CORE_TOPICS):
            found = ", ".join(sorted(contents.topics)[:6]) or "no topics"
            return {"error": f"not a c4d flight: none of the c4d topics {', '.join(CORE_TOPICS)} recorded "
                             f"(it has {found}{', ...' if len(contents.topics) > 6 else ''})",
                    "size": st.st_size, "mtime_ns": st.st_mtime_ns}
        figures, bins = summarize(contents)
        custom = (contents.rosbag2 or {}).get("custom_data") or {}
        row = figures.as_dict()
        row.update(file=str(file), size_bytes=st.st_size, mtime_ns=st.st_mtime_ns,
                   vehicle=_vehicle(file, Path(root), custom), airframe=_airframe(contents, custom),
                   start_ns=contents.start_ns,
                   start_utc=datetime.fromtimestamp(contents.start_ns * 1e-9, UTC).isoformat(timespec="milliseconds"),
                   indexed_at=datetime.now(UTC).isoformat(timespec="seconds"))
        warning = f"missing {', '.join(missing)}: their figures are empty" if missing else ""
        return {"row": row, "bins": bins, "warning": warning}
    except BagError as exc:
        reason = str(exc)
    except Exception as exc:  # a decoder or a file system error: report it, keep going
        reason = f"unexpected {type(exc).__name__}: {exc}"
    try:
        st = file.stat()
        size, mtime = st.st_size, st.st_mtime_ns
    except OSError:
        size, mtime = -1, -1
    prefix = f"{file}: "
    return {"error": reason[len(prefix):] if reason.startswith(prefix) else reason, "size": size, "mtime_ns": mtime}


def make_report(bag: str, out: str, flight_id: int = 0) -> dict[str, Any]:
    """Worker: write the flight's report into `out`; {'report': index path} or {'error': reason}
    (`flight_id` only travels along)."""
    from .analysis.report import write_report

    try:
        return {"report": str(write_report(bag, out, progress=False))}
    except (BagError, OSError) as exc:
        return {"error": str(exc)}
    except Exception as exc:
        return {"error": f"unexpected {type(exc).__name__}: {exc}"}


def _bounded(pool: ProcessPoolExecutor, fn: Any, jobs: list[tuple[Any, ...]],
             window: int) -> Iterator[tuple[tuple[Any, ...], Any]]:
    """pool.map with at most `window` jobs in flight, results in submission order."""
    pending: list[tuple[tuple[Any, ...], Future[Any]]] = []
    it = iter(jobs)
    for job in it:
        pending.append((job, pool.submit(fn, *job)))
        if len(pending) >= window:
            done = pending.pop(0)
            yield done[0], done[1].result()
    for job, future in pending:
        yield job, future.result()


def _existing_report(bag: Path) -> Path | None:
    """The report `analyze` writes by default (<stem>_report/index.html), if newer than the bag."""
    index = bag.with_name(bag.stem + "_report") / "index.html"
    try:
        return index if index.stat().st_mtime_ns >= bag.stat().st_mtime_ns else None
    except OSError:
        return None


def warn(text: str) -> None:
    print(f"catalog: warning: {text}", file=sys.stderr)


def index(db: CatalogDB, roots: list[Path], jobs: int) -> tuple[int, int, int, int]:
    """Index new/changed files; returns (indexed, unchanged, skipped now, skipped before)."""
    files = find_flights(roots)
    known = db.known()
    present = {str(f) for f, _ in files}
    under = [str(r.resolve()) + os.sep for r in roots]
    db.forget(f for f in known if f not in present and any(f.startswith(u) for u in under))
    todo, unchanged, bad_before = [], 0, 0
    for file, root in files:
        st = file.stat()
        seen = known.get(str(file))
        if seen and seen[:2] == (st.st_size, st.st_mtime_ns):
            unchanged += seen[2]
            bad_before += not seen[2]
            continue
        todo.append((str(file), str(root)))
    indexed = skipped = 0
    if todo:
        with ProcessPoolExecutor(max_workers=max(1, min(jobs, len(todo)))) as pool:
            for (file_s, _), result in _bounded(pool, index_file, todo, 4 * jobs):
                if "error" in result:
                    warn(f"{file_s}: {result['error']}; skipped")
                    db.put_skipped(file_s, result["size"], result["mtime_ns"], result["error"])
                    skipped += 1
                    continue
                if result["warning"]:
                    warn(f"{file_s}: {result['warning']}")
                db.put_flight(result["row"], result["bins"])
                indexed += 1
    return indexed, unchanged, skipped, bad_before


def reports(db: CatalogDB, out: Path, jobs: int) -> int:
    """Find or write every flight's report; returns how many were written."""
    todo = []
    for row in db.flights():
        if row["report"] and Path(row["report"]).is_file():
            continue
        existing = _existing_report(Path(row["file"]))
        if existing is not None:
            db.set_report(row["id"], str(existing))
            continue
        todo.append((row["file"], str(out / "reports" / f"{Path(row['file']).stem}_{row['id']}"), row["id"]))
    written = 0
    if todo:
        with ProcessPoolExecutor(max_workers=max(1, min(jobs, len(todo)))) as pool:
            for (bag, _, flight_id), result in _bounded(pool, make_report, todo, 4 * jobs):
                if "error" in result:
                    warn(f"{bag}: no report ({result['error']})")
                    continue
                db.set_report(flight_id, result["report"])
                written += 1
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="catalog", description="Fleet flight catalog: index flight recordings "
                                     "(*.mcap under the folders) into an SQLite database, query it, write an HTML index.")
    parser.add_argument("dirs", nargs="*", metavar="DIR", help="folders searched recursively for *.mcap")
    parser.add_argument("--db", default=None, help=f"database file (default: {DEFAULT_DB} in the first DIR, "
                                                   "or in the current folder without DIR)")
    parser.add_argument("--sql", help="run this SQL on the catalog (read-only) and print the result as a table")
    parser.add_argument("--html", metavar="OUT_DIR", help="write the static HTML index (and missing flight reports)")
    parser.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: CPUs)")
    args = parser.parse_args(argv)
    if not (args.dirs or args.sql or args.html):
        parser.error("give folders to index, --sql or --html")
    if args.jobs < 1:
        parser.error("--jobs must be >= 1")
    roots = [Path(d) for d in args.dirs]
    for root in roots:
        if not root.is_dir():
            print(f"catalog: error: {root}: no such folder", file=sys.stderr)
            return 2
    db_path = Path(args.db) if args.db else (roots[0] if roots else Path.cwd()) / DEFAULT_DB
    started = time.monotonic()
    if roots:
        if not find_flights(roots):
            print(f"catalog: error: no *.mcap files under {', '.join(map(str, roots))}", file=sys.stderr)
            return 1
        try:
            db = CatalogDB(db_path)
        except (sqlite3.Error, OSError) as exc:
            print(f"catalog: error: cannot open the database {db_path}: {exc}", file=sys.stderr)
            return 1
        try:
            indexed, unchanged, skipped, bad_before = index(db, roots, args.jobs)
            total = len(db.flights())
        finally:
            db.close()
        before = f", {bad_before} skipped before and unchanged" if bad_before else ""
        print(f"catalog: {indexed} flights indexed, {unchanged} unchanged, {skipped} skipped{before}; "
              f"{total} in {db_path} ({time.monotonic() - started:.1f} s)")
        if total == 0:
            print("catalog: error: nothing could be indexed", file=sys.stderr)
            return 1
    if args.html:
        if not db_path.is_file():
            print(f"catalog: error: no catalog database at {db_path} (index some folders first)", file=sys.stderr)
            return 1
        from .catalog_html import write_index

        out = Path(args.html)
        db = CatalogDB(db_path)
        try:
            written = reports(db, out, args.jobs)
            page = write_index(db.flights(), out)
        except OSError as exc:
            print(f"catalog: error: cannot write the HTML index in {out}: {exc.strerror or exc}", file=sys.stderr)
            return 1
        finally:
            db.close()
        print(f"catalog: HTML index {page} ({written} reports written)")
    if args.sql:
        try:
            names, rows = run_query(db_path, args.sql)
        except sqlite3.Error as exc:
            print(f"catalog: error: SQL: {exc}", file=sys.stderr)
            return 1
        try:
            print(format_table(names, rows), flush=True)
        except BrokenPipeError:  # `catalog --sql ... | head`: the reader has what it wanted
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


if __name__ == "__main__":
    sys.exit(main())

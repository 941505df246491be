"""Command lines: `analyze` (= `c4d-analyze`), `repair`, `info`, `catalog` (catalog.py).

Each prints one line `<tool>: error: <reason>` on stderr and exits non-zero on bad input (bad
arguments: 2, unusable file or failed write: 1); what a recording holds is never modified
except by `repair --in-place`, which replaces the file only once the repaired copy is complete.
"""

from __future__ import annotations

import argparse
import sys
from datetime import UTC, datetime
from pathlib import Path

from .bag_reader import BagError, open_bag


def _stamp(ns: int) -> str:
    return datetime.fromtimestamp(ns * 1e-9, UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + " UTC"


def info_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="info", description="Describe a rosbag2 MCAP recording (like `ros2 bag info`).")
    parser.add_argument("bag")
    args = parser.parse_args(argv)
    try:
        c = open_bag(args.bag)
    except BagError as exc:
        print(f"info: error: {exc}", file=sys.stderr)
        return 1
    print(f"Files:             {c.path}")
    print(f"Bag size:          {c.path.stat().st_size / 2**20:.2f} MiB")
    print(f"Storage id:        mcap (profile {c.profile}, written by {c.library})")
    print(f"Complete:          {'yes' if c.complete else 'NO — ' + c.problem + ' (run repair)'}")
    print(f"Duration:          {c.duration_s:.3f} s")
    if c.message_count:
        print(f"Start:             {_stamp(c.start_ns)}")
        print(f"End:               {_stamp(c.end_ns)}")
    print(f"Messages:          {c.message_count}")
    custom = (c.rosbag2 or {}).get("custom_data") or {}
    for key, value in sorted(custom.items()):
        print(f"Custom data:       {key} = {value}")
    print("Topic information:")
    width = max((len(n) for n in c.topics), default=0)
    for name, t in sorted(c.topics.items()):
        print(f"  Topic: {name:<{width}} | Type: {t.type_name} | Count: {t.count} | Serialization Format: cdr")
    return 0


def repair_main(argv: list[str] | None = None) -> int:
    from .repair import default_output, repair

    parser = argparse.ArgumentParser(prog="repair", description="Rewrite an interrupted recording with a summary "
                                                                "(index, statistics, rosbag2 metadata).")
    parser.add_argument("bag")
    parser.add_argument("-o", "--output", help="output file (default: <name>.repaired.mcap)")
    parser.add_argument("--in-place", action="store_true", help="replace the input once the repaired copy is complete")
    args = parser.parse_args(argv)
    if args.in_place and args.output:
        parser.error("--in-place and --output exclude each other")
    try:
        source, written = repair(args.bag, args.output, args.in_place)
    except BagError as exc:
        print(f"repair: error: {exc}", file=sys.stderr)
        return 1
    state = "was complete" if source.complete else f"was incomplete ({source.problem})"
    target = written.path if args.in_place else Path(args.output or default_output(Path(args.bag)))
    print(f"repair: {args.bag} {state}; wrote {target}: {written.message_count} messages on "
          f"{len(written.counts)} topics, {(written.end_ns - written.start_ns) * 1e-9:.3f} s")
    return 0


def analyze_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="c4d-analyze", description="Flight analysis report (HTML + PNG plots) "
                                                                     "from a c4d flight recording.")
    parser.add_argument("bag", help="MCAP flight recording")
    parser.add_argument("-o", "--output", help="report directory (default: <bag name>_report next to the file)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    from .analysis.report import write_report

    bag = Path(args.bag)
    out = Path(args.output) if args.output else bag.with_name(bag.stem + "_report")
    try:
        index = write_report(bag, out, progress=not args.quiet)
    except BagError as exc:
        print(f"c4d-analyze: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"c4d-analyze: error: cannot write the report in {out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    print(f"c4d-analyze: report {index}")
    return 0


def catalog_main(argv: list[str] | None = None) -> int:
    from .catalog import main

    return main(argv)


if __name__ == "__main__":
    sys.exit(analyze_main())

"""`resim FLIGHT.mcap [-p node.param:=value ...] [--from T --to T] [--out NEW.mcap] [--report DIR]`.

Re-runs navigation and the GNC core over a recorded flight (c4d_resim.run), prints one summary line
per stream, writes the HTML diff report (default: <flight>_resim/ next to the file) and, with --out, the
re-simulated MCAP. Bad input — not an MCAP, an MCAP without c4d journals (names the missing topics), a
truncated file (points to `repair`), an unknown or out-of-range override — one line
`resim: error: ...` on stderr, exit 2 (arguments, overrides) or 1 (files).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="resim", description="Deterministic re-simulation of a recorded flight.")
    parser.add_argument("flight", help="flight MCAP written by the c4d recorder")
    parser.add_argument("-p", dest="overrides", action="append", default=[], metavar="NODE.PARAM:=VALUE",
                        help="parameter override (navigation.* or core.*), repeatable")
    parser.add_argument("--from", dest="t_from", type=float, default=None, help="compare from T [s after arm]")
    parser.add_argument("--to", dest="t_to", type=float, default=None, help="compare up to T [s after arm]")
    parser.add_argument("--out", help="write the re-simulated flight to this MCAP")
    parser.add_argument("--report", help="report directory (default: <flight>_resim next to the file)")
    parser.add_argument("--processes", type=int, choices=(1, 2), default=None,
                        help="1: navigation and core in one process; 2: navigation in a second one "
                             "(default: 2 when two CPUs are usable); the bytes are the same")
    args = parser.parse_args(argv)
    from c4d_data.bag_reader import BagError
    from c4d_gnc.journal import JournalError

    from . import report
    from .flight import FlightError
    from .overrides import OverrideError, parse
    from .run import resimulate

    try:
        parse(args.overrides)
    except OverrideError as exc:
        print(f"resim: error: {exc}", file=sys.stderr)
        return 2
    window = None
    if args.t_from is not None or args.t_to is not None:
        window = (args.t_from if args.t_from is not None else 0.0, args.t_to if args.t_to is not None else float("inf"))
        if window[1] < window[0]:
            print(f"resim: error: --to {window[1]} is before --from {window[0]}", file=sys.stderr)
            return 2
    try:
        result = resimulate(args.flight, args.overrides, window, args.out, args.processes)
    except OverrideError as exc:
        print(f"resim: error: {exc}", file=sys.stderr)
        return 2
    except (BagError, FlightError, JournalError) as exc:
        print(f"resim: error: {exc}", file=sys.stderr)
        return 1
    flight = Path(args.flight)
    out = Path(args.report) if args.report else flight.with_name(flight.stem + "_resim")
    try:
        index = report.write(result, out)
    except OSError as exc:
        print(f"resim: error: cannot write the report in {out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    for s in (result.state, result.actuators):
        first = "bit-identical" if s.first_divergence is None else \
            f"first divergence {s.first_divergence - result.core_start_s:.3f} s after arm"
        print(f"resim: {s.name}: {s.identical}/{s.compared} identical, {first}, max difference {s.max_diff:.3g}")
    print(f"resim: {result.flight_s:.1f} s of flight in {result.wall_s:.2f} s "
          f"({result.flight_s / max(result.wall_s, 1e-9):.1f}x real time); report {index}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

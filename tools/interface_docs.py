"""Generate the QoS, topic, service and action tables of docs/ARCHITECTURE.md from the code.

Why: the tables are the contract newcomers read; written by hand they drifted from the code (a
`state` deadline that was never set, topics that did not exist). Now the QoS table comes from
`c4d_ros.qos.Profile` (the QoSProfile objects the nodes use, so it states what DDS is told) and
the topic, service and action tables from `c4d_ros.manifest`, which
`test/test_interface_manifest.py` checks against the live graph.

    python tools/interface_docs.py          rewrite the tables between the marker comments
    python tools/interface_docs.py --check  exit 1 (and name the stale tables) when the docs differ

Each table sits between `<!-- BEGIN generated: NAME -->` and `<!-- END generated: NAME -->`
(NAME = qos, topics, services, actions); everything outside the markers is left as written.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from c4d_ros.manifest import MANIFEST
from c4d_ros.qos import Profile

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "ARCHITECTURE.md"
COMMAND = "python tools/interface_docs.py"

RELIABILITY = {ReliabilityPolicy.RELIABLE: "reliable", ReliabilityPolicy.BEST_EFFORT: "best effort"}
DURABILITY = {DurabilityPolicy.VOLATILE: "volatile", DurabilityPolicy.TRANSIENT_LOCAL: "transient local"}


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def short_type(ros_type: str) -> str:
    """`sensor_msgs/msg/Imu` -> `sensor_msgs/Imu` (the docs' spelling)."""
    package, _, name = ros_type.split("/")
    return f"{package}/{name}"


def listed(names: Iterable[str]) -> str:
    return ", ".join(names) or "—"


def history(qos: QoSProfile) -> str:
    return f"keep last {qos.depth}" if qos.history == HistoryPolicy.KEEP_LAST else "keep all"


def duration(value: Duration) -> str:
    """A QoS duration as the docs say it: 0 is DDS's 'not set' (infinite)."""
    return "none" if value.nanoseconds == 0 else f"{value.nanoseconds / 1e9:g} s"


def qos_table() -> str:
    rows = []
    for profile in Profile:
        qos = profile.qos
        rows.append((f"`{profile.name.lower()}`", RELIABILITY[qos.reliability], DURABILITY[qos.durability], history(qos),
                     duration(qos.deadline), profile.value.use))
    return markdown_table(("name", "reliability", "durability", "history", "deadline", "use"), rows)


def topics_table() -> str:
    rows = [(f"`{t.name}`", short_type(t.type), t.profile.name.lower(), t.rate, listed(t.producers), listed(t.all_consumers),
             t.about) for t in MANIFEST.topics]
    return markdown_table(("topic", "type", "QoS", "rate", "producers", "consumers", "notes"), rows)


def services_table() -> str:
    rows = [(f"`{s.name}`", short_type(s.type), s.rate, s.server, listed(s.clients), s.about) for s in MANIFEST.services]
    return markdown_table(("service", "type", "rate", "server", "clients", "notes"), rows)


def actions_table() -> str:
    rows = [(f"`{a.name}`", short_type(a.type), a.server, a.about) for a in MANIFEST.actions]
    return markdown_table(("action", "type", "server", "notes"), rows)


TABLES: dict[str, Callable[[], str]] = {"qos": qos_table, "topics": topics_table, "services": services_table,
                                        "actions": actions_table}


class MarkerError(ValueError):
    """The document lacks a BEGIN/END marker pair for a generated table."""


def regenerate(text: str) -> str:
    """`text` with every generated table replaced by what the code says now."""
    for name, make in TABLES.items():
        pattern = re.compile(rf"(<!-- BEGIN generated: {name} -->\n).*?(<!-- END generated: {name} -->)", re.DOTALL)
        if not pattern.search(text):
            raise MarkerError(f"no '<!-- BEGIN generated: {name} -->' ... '<!-- END generated: {name} -->' pair")
        table = make()
        text = pattern.sub(lambda m, table=table: m.group(1) + table + "\n" + m.group(2), text, count=1)
    return text


def stale_tables(old: str, new: str) -> list[str]:
    def section(text: str, name: str) -> str:
        found = re.search(rf"<!-- BEGIN generated: {name} -->.*?<!-- END generated: {name} -->", text, re.DOTALL)
        return found.group(0) if found else ""
    return [name for name in TABLES if section(old, name) != section(new, name)]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when the generated tables are stale; write nothing")
    parser.add_argument("--doc", type=Path, default=DOC, help="the document to update (default: docs/ARCHITECTURE.md)")
    args = parser.parse_args(argv)
    old = args.doc.read_text()
    try:
        new = regenerate(old)
    except MarkerError as exc:
        print(f"interface_docs: error: {args.doc}: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if new != old:
            print(f"interface_docs: {args.doc} is stale ({', '.join(stale_tables(old, new))}): run `{COMMAND}`",
                  file=sys.stderr)
            return 1
        print(f"interface_docs: {args.doc} is up to date")
        return 0
    if new != old:
        args.doc.write_text(new)
        print(f"interface_docs: rewrote {', '.join(stale_tables(old, new))} in {args.doc}")
    else:
        print(f"interface_docs: {args.doc} already up to date")
    return 0


if __name__ == "__main__":
    sys.exit(main())

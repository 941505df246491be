"""docs/ARCHITECTURE.md's QoS, topic and service tables are what the code says.

Why: the tables are generated from c4d_ros.qos and c4d_ros.manifest (tools/interface_docs.py);
a manifest change without regenerating them must fail here, in seconds and without DDS.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
TOOL = ROOT / "tools" / "interface_docs.py"


def test_generated_tables_are_up_to_date():
    done = subprocess.run([sys.executable, str(TOOL), "--check"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr


def test_check_reports_a_stale_table(tmp_path):
    doc = tmp_path / "ARCHITECTURE.md"
    doc.write_text((ROOT / "docs" / "ARCHITECTURE.md").read_text().replace("| `sensors/imu` |", "| `sensors/imu_old` |"))
    done = subprocess.run([sys.executable, str(TOOL), "--check", "--doc", str(doc)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 1 and "topics" in done.stderr, done.stdout + done.stderr

"""The test harness itself: domain leases avoid ids already used, stragglers are found by domain."""

from __future__ import annotations

import os
import subprocess
import sys

import ros_domain
from c4d_testing import RUN_TOKEN, leftover_processes


def test_acquire_skips_avoided_ids_unless_nothing_else_is_free(tmp_path, monkeypatch):
    monkeypatch.setattr(ros_domain, "LOCK_DIR", str(tmp_path))
    first = ros_domain.acquire(start=5, avoid={5, 6})
    assert first.domain_id == 7
    held = [first] + [ros_domain.acquire(start=5, avoid={5, 6}) for _ in range(97)]
    assert {lease.domain_id for lease in held} == set(range(1, 101)) - {5, 6}
    assert ros_domain.acquire(start=5, avoid={5, 6}).domain_id in (5, 6)  # only avoided ones left
    for lease in held:
        lease.release()


def test_leftover_processes_filters_by_run_token_and_domain():
    env = {**os.environ, "C4D_TEST_RUN": RUN_TOKEN, "ROS_DOMAIN_ID": "77"}
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"], env=env)
    try:
        for _ in range(50):
            if any(pid == proc.pid for pid, _ in leftover_processes(RUN_TOKEN, 77)):
                break
            subprocess.run(["sleep", "0.1"], check=True)
        assert [pid for pid, _ in leftover_processes(RUN_TOKEN, 77)] == [proc.pid]
        assert proc.pid not in [pid for pid, _ in leftover_processes(RUN_TOKEN, 78)]
    finally:
        proc.kill()
        proc.wait()

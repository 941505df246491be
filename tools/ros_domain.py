"""Allocate a ROS_DOMAIN_ID that no other process on this machine is using.

Why: tests and checks run real DDS participants; two runs on one machine (a developer's and
CI's, or two test groups) must never discover each other. Each caller takes an exclusive
`flock` on /tmp/c4d-ros-domain-<id>.lock for as long as it holds the returned handle; the
lock dies with the process, so a crashed run never leaks a domain.

Domains 1..100 are used (0 is the ROS default that people's own graphs use; Linux keeps
ports for domains up to 101 free of the ephemeral range).
"""

from __future__ import annotations

import fcntl
import os
from typing import IO

LOCK_DIR = os.environ.get("C4D_DOMAIN_LOCK_DIR", "/tmp")
FIRST_DOMAIN = 1
LAST_DOMAIN = 100


class DomainLease:
    """An exclusively held ROS domain id; release() (or process exit) frees it."""

    def __init__(self, domain_id: int, handle: IO[str]) -> None:
        self.domain_id = domain_id
        self._handle = handle

    def release(self) -> None:
        if not self._handle.closed:
            fcntl.flock(self._handle, fcntl.LOCK_UN)
            self._handle.close()


def acquire(start: int | None = None, avoid: frozenset[int] | set[int] = frozenset()) -> DomainLease:
    """Lock the first free domain id, scanning from `start` (default: derived from the pid).

    Ids in `avoid` (e.g. the ones this test session already used, so a straggler process of an
    earlier test group can never meet the next group) are taken only when nothing else is free."""
    span = LAST_DOMAIN - FIRST_DOMAIN + 1
    first = start if start is not None else FIRST_DOMAIN + os.getpid() % span
    order = [FIRST_DOMAIN + (first - FIRST_DOMAIN + k) % span for k in range(span)]
    for domain_id in [d for d in order if d not in avoid] + [d for d in order if d in avoid]:
        handle = open(os.path.join(LOCK_DIR, f"c4d-ros-domain-{domain_id}.lock"), "a")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            continue
        return DomainLease(domain_id, handle)
    raise RuntimeError(f"all ROS domain ids {FIRST_DOMAIN}..{LAST_DOMAIN} are in use")

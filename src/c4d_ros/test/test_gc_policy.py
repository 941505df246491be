"""c4d_ros.gc_policy.LoopGc: freeze after start-up, no automatic collection, young ones when due, full ones rarely.

Why: an automatic full collection in navigation pauses it ~11 ms (5 IMU samples); the policy must
really switch automatic collection off and still collect garbage, or it leaks or it does nothing.
"""

from __future__ import annotations

import gc

import pytest

from c4d_ros.gc_policy import LoopGc


@pytest.fixture
def restore_gc():
    yield
    gc.enable()
    gc.unfreeze()


def test_first_tick_freezes_then_young_and_periodic_full_collections(restore_gc) -> None:
    now = [100.0]
    policy = LoopGc(young_threshold=500, full_period_s=10.0, clock=lambda: now[0])
    assert policy.tick() == 2 and not gc.isenabled() and gc.get_freeze_count() > 0
    assert policy.tick() is None  # nothing allocated yet
    garbage = []
    for _ in range(2000):  # cyclic garbage the disabled automatic GC leaves alone
        a: list = []
        a.append(a)
        garbage.append(a)
    garbage.clear()
    assert gc.get_count()[0] > 500
    assert policy.tick() in (0, 1) and gc.get_count()[0] < 500
    now[0] += 10.0
    assert policy.tick() == 2 and policy.collections[2] == 2
    policy.release()
    assert gc.isenabled() and gc.get_freeze_count() == 0

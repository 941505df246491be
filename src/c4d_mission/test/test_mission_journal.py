"""Mission journal without ROS: exact round trip, atomic replace, corrupt files, the resume decision,
and a killed executor continued from its checkpoint."""

import json
import math
import os
from pathlib import Path

import pytest

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import Item, Plan
from c4d_common.plan_files import load_plan
from c4d_common.vehicle import Command, FailsafeAction, Landed, MissionAction, MissionStatus, Mode, Nav
from c4d_mission.arbitration import CommandArbiter
from c4d_mission.executor import Checkpoint, MissionExecutor, Vehicle
from c4d_mission.mission_journal import JournalEntry, JournalError, MissionJournal, VehicleCheck, resume_status

ROOT = Path(__file__).resolve().parents[3]
HOME = GeoOrigin(43.5629, 1.4815, 146.0)
FLYING = VehicleCheck(True, Landed.IN_AIR, Mode.AUTO, FailsafeAction.NONE)


def survey() -> Plan:
    return load_plan(ROOT / "missions" / "survey.yaml").with_id(7)


def entry(status=MissionStatus.ACTIVE, current=3) -> JournalEntry:
    return JournalEntry(survey(), Checkpoint(7, status, current, current - 1, 6.0, "start", "distance", 5.0, 2))


def test_round_trip_is_exact(tmp_path):
    journal = MissionJournal(tmp_path / "mission" / "state.json")  # parent created
    saved = entry()
    journal.save(saved)
    loaded = journal.load()
    # NaN != NaN: compare the serialised forms, which spell every float exactly
    assert repr(loaded) == repr(saved)
    assert loaded.checkpoint == saved.checkpoint and loaded.plan.plan_id == 7
    assert any(math.isnan(i.x) for i in loaded.plan.items)  # take-off: "current" position kept as NaN
    journal.save(JournalEntry(None, Checkpoint(0, MissionStatus.NO_PLAN, 0, -1, 5.0, "start")))
    assert journal.load().plan is None


def test_no_file_is_no_entry(tmp_path):
    assert MissionJournal(tmp_path / "missing.json").load() is None


def test_write_is_atomic(tmp_path, monkeypatch):
    path = tmp_path / "state.json"
    journal = MissionJournal(path)
    journal.save(entry(current=2))
    before = path.read_text()

    def killed(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", killed)
    with pytest.raises(OSError):
        journal.save(entry(current=4))
    assert path.read_text() == before  # the old journal is intact ...
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.json"]  # ... and no temporary file is left
    monkeypatch.undo()
    journal.save(entry(current=4))
    assert journal.load().checkpoint.current == 4


@pytest.mark.parametrize("text", [
    "", "{", "[]", '{"version": 1}', '{"version": 9, "plan": null, "checkpoint": {}}',
    '{"version": 1, "plan": null, "checkpoint": {"plan_id": 0, "status": "FLYING", "current": 0, '
    '"last_reached": -1, "speed": 5.0, "phase": "start"}}',
])
def test_corrupt_journal_is_one_error(tmp_path, text):
    path = tmp_path / "state.json"
    path.write_text(text)
    with pytest.raises(JournalError) as err:
        MissionJournal(path).load()
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_inconsistent_journal_is_refused(tmp_path):
    journal = MissionJournal(tmp_path / "state.json")
    journal.save(entry(current=3))
    doc = json.loads(journal.path.read_text())
    doc["checkpoint"]["current"] = 99
    journal.path.write_text(json.dumps(doc))
    with pytest.raises(JournalError, match="item 99 outside"):
        journal.load()
    doc["checkpoint"]["current"], doc["plan"]["plan_id"] = 3, 8
    journal.path.write_text(json.dumps(doc))
    with pytest.raises(JournalError, match="plan id 8"):
        journal.load()


def test_only_an_active_mission_still_flown_resumes():
    assert resume_status(MissionStatus.ACTIVE, FLYING).resumed
    assert resume_status(MissionStatus.ACTIVE, VehicleCheck(True, Landed.TAKEOFF, Mode.AUTO, FailsafeAction.WARN)).resumed
    for saved in (MissionStatus.COMPLETED, MissionStatus.ABORTED, MissionStatus.PAUSED, MissionStatus.READY):
        verdict = resume_status(saved, FLYING)
        assert verdict.status == saved and not verdict.resumed  # terminal and stopped states stay as they were
    cases = {
        VehicleCheck(False, Landed.ON_GROUND, Mode.AUTO, FailsafeAction.NONE): MissionStatus.ABORTED,
        VehicleCheck(True, Landed.ON_GROUND, Mode.AUTO, FailsafeAction.NONE): MissionStatus.ABORTED,
        VehicleCheck(True, Landed.LANDING, Mode.AUTO, FailsafeAction.LAND): MissionStatus.ABORTED,
        VehicleCheck(True, Landed.IN_AIR, Mode.AUTO, FailsafeAction.HOLD): MissionStatus.PAUSED,
        VehicleCheck(True, Landed.IN_AIR, Mode.POSITION, FailsafeAction.NONE): MissionStatus.PAUSED,
    }
    for vehicle, status in cases.items():
        assert resume_status(MissionStatus.ACTIVE, vehicle).status == status, vehicle


def test_a_restarted_executor_continues_where_the_killed_one_was(tmp_path):
    """Fly the survey's first items in a kinematic loop, "kill" the arbiter mid-leg, restore a new one
    from the journal: same item, same speed, no take-off asked again, the next leg flown to the end."""
    plan = Plan((Item("takeoff", z=10.0), Item("change_speed", speed=3.0), Item("waypoint", x=20.0, y=0.0, z=10.0),
                 Item("waypoint", x=20.0, y=20.0, z=10.0)), name="square")
    journal = MissionJournal(tmp_path / "state.json")
    arbiter = CommandArbiter()
    assert arbiter.accept(plan, HOME, 3600.0).plan is not None
    arbiter.control(MissionAction.START)
    position, nav, t = (0.0, 0.0, 0.0), Nav.NONE, 0.0
    saved = None

    def step(arbiter):
        nonlocal position, nav, t, saved
        t += 0.02
        for _, out in arbiter.step(t, 0.02, Vehicle(position, True, position[2] > 0.3, nav)):
            for command, value in out.requests:
                if command == Command.TAKEOFF:
                    position, nav = (position[0], position[1], value), Nav.HOLD  # an instant climb
                elif command == Command.GOTO:
                    nav = Nav.GOTO
            if out.setpoint is not None:
                position = out.setpoint[0]  # perfect tracking
        checkpoint = arbiter.mission.checkpoint()
        if checkpoint != saved:
            journal.save(JournalEntry(arbiter.mission.plan, checkpoint))
            saved = checkpoint

    while arbiter.mission.current < 2 or position[0] < 8.0:
        step(arbiter)
    killed_at = arbiter.mission.current
    restored = journal.load()
    verdict = resume_status(restored.checkpoint.status, FLYING)
    fresh = CommandArbiter()
    fresh.restore(restored.plan, HOME, restored.checkpoint, verdict.status)
    assert verdict.resumed and fresh.mission.current == killed_at == 2 and fresh.mission.speed == 3.0
    requests = fresh.step(t + 0.02, 0.02, Vehicle(position, True, True, Nav.GOTO))[0][1].requests
    assert requests == [(Command.GOTO, 0.0)]  # a fresh leg from where the vehicle is; no take-off
    while fresh.mission.status == MissionStatus.ACTIVE and t < 60:
        step(fresh)
    assert fresh.mission.status == MissionStatus.COMPLETED and math.dist(position, (20.0, 20.0, 10.0)) < 1.0
    assert journal.load().checkpoint.status == MissionStatus.COMPLETED
    new_plan = fresh.accept(plan, HOME, 3600.0).plan
    assert new_plan.plan_id == 2  # ids continue after the restored plan's


def test_a_take_off_in_progress_is_waited_for_not_asked_again():
    mission = MissionExecutor()
    mission.load(Plan((Item("takeoff", z=10.0), Item("waypoint", x=5.0, y=0.0, z=10.0))).with_id(1), HOME)
    mission.start()
    out = mission.step(0.0, 0.02, Vehicle((0.0, 0.0, 0.0), True, False, Nav.NONE))
    assert out.requests == [(Command.TAKEOFF, 10.0)]
    checkpoint = mission.checkpoint()
    assert checkpoint.phase == "wait"
    again = MissionExecutor()
    again.restore(mission.plan, HOME, checkpoint, MissionStatus.ACTIVE)
    assert again.step(0.1, 0.02, Vehicle((0.0, 0.0, 4.0), True, False, Nav.TAKEOFF)).requests == []
    out = again.step(0.2, 0.02, Vehicle((0.0, 0.0, 10.0), True, True, Nav.HOLD))
    assert out.reached == [0] and again.current == 1

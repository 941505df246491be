"""The navigation node's live EKF parameters (ROS-free): the table mirrors EkfConfig, a change lands
in the right field and only there, bad values are refused with the reason, a tighter GNSS gate
changes what the filter accepts, and the journal carries a retune so resim replays it."""

from __future__ import annotations

import dataclasses
import math
import pickle

import numpy as np

from c4d_gnc import journal as jr
from c4d_gnc.ekf import EkfConfig, NavigationEkf
from c4d_gnc.live_navigation import FIELDS, PREFIX, ekf_with, navigation_table

NOT_LIVE = {"mag_declination", "home_fixes"}  # site / start-up values: read-only parameters


def test_table_mirrors_ekf_config_and_round_trips():
    cfg = EkfConfig()
    table = navigation_table(cfg)
    floats = {f.name for f in dataclasses.fields(cfg)} - NOT_LIVE
    assert {t.name for t in table} == {PREFIX + f for f in floats}
    for t in table:
        assert t.default == getattr(cfg, t.name[len(PREFIX):]) and t.low <= t.default <= t.high, t.name
    assert ekf_with(cfg, table.defaults()) == cfg
    tuned = ekf_with(cfg, {"ekf.gps_gate": 3.0, "ekf.baro_noise": 0.5})
    assert (tuned.gps_gate, tuned.baro_noise) == (3.0, 0.5)
    assert dataclasses.replace(tuned, gps_gate=cfg.gps_gate, baro_noise=cfg.baro_noise) == cfg


def test_bad_values_are_refused_with_the_reason():
    table = navigation_table()
    values = table.defaults()
    assert "not finite" in table.check({"ekf.gps_gate": math.nan}, values)
    assert "not finite" in table.check({"ekf.baro_noise": math.inf}, values)
    assert "outside [1, 100]" in table.check({"ekf.gps_gate": 0.5}, values)
    assert "expected a number" in table.check({"ekf.gyro_noise": "0.01"}, values)
    assert "no such parameter" in table.check({"ekf.mag_declination": 0.1}, values)
    assert table.check({"ekf.unaided_velocity_sigma": 0.0}, values) == ""  # 0 = off is a value
    assert set(FIELDS) <= {f.name for f in dataclasses.fields(EkfConfig)}


def _hovering_ekf(cfg: EkfConfig) -> NavigationEkf:
    """An aligned filter at home, position known to ~0.3 m."""
    ekf = NavigationEkf(cfg)
    for _ in range(60):
        ekf.align((0.0, 0.0, 9.80665), None)
    for _ in range(20):
        ekf.update_gps(43.0, 1.0, 100.0, 1.0, 1.0)
    assert ekf.origin is not None
    ekf.update_gps(43.0, 1.0, 100.0, 1.0, 1.0)  # the first fix after home: GNSS in use
    ekf.P[0:3, 0:3] = np.eye(3) * 0.3**2
    return ekf


def test_a_tighter_gps_gate_rejects_a_fix_the_default_accepts():
    """The change acts where the filter reads it (ekf.cfg swapped whole, as the node does)."""
    offset = 3.0 / 111_320.0  # 3 m north
    ekf = _hovering_ekf(EkfConfig())
    before = ekf.rejected["gps"]
    ekf.update_gps(43.0 + offset, 1.0, 100.0, 1.0, 1.0)
    assert ekf.rejected["gps"] == before  # within 5 sigma
    ekf = _hovering_ekf(EkfConfig())
    ekf.cfg = ekf_with(ekf.cfg, {"ekf.gps_gate": 1.0})
    ekf.update_gps(43.0 + offset, 1.0, 100.0, 1.0, 1.0)
    assert ekf.rejected["gps"] == before + 1


def test_retune_record_round_trips_through_the_journal():
    writer = jr.JournalWriter()
    changes = {"ekf.gps_gate": 3.0}
    writer.blob(jr.N_RETUNE, pickle.dumps(changes))
    writer.stamp(jr.N_IMU, 1_000_000_000)
    payload = writer.take()
    assert payload is not None
    recs = list(jr.records(payload))
    assert recs[0][0] == jr.N_RETUNE and jr.safe_loads(recs[0][1]) == changes
    assert recs[1] == (jr.N_IMU, 1_000_000_000)

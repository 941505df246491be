"""Unit tests of the controller stages (ROS-free, deterministic)."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from c4d_common import quat
from c4d_common.airframe import AirframeError, airframe_from_dict, default_airframe_path, load_airframe
from c4d_gnc.control.mixer import Mixer
from c4d_gnc.control.pid import VectorPid
from c4d_gnc.control.translation import TranslationController

QUAD = load_airframe(default_airframe_path("quad_x"))
HEXA = load_airframe(default_airframe_path("hexa_x"))


def to_scipy(q):
    return Rotation.from_quat([q[1], q[2], q[3], q[0]])


def test_quaternion_helpers_match_scipy():
    rng = np.random.default_rng(3)
    for _ in range(50):
        r, p, y = rng.uniform(-1.2, 1.2, 3)
        q = quat.from_euler(r, p, y)
        ref = Rotation.from_euler("ZYX", [y, p, r])
        v = tuple(rng.normal(size=3))
        assert np.allclose(quat.rotate(q, v), ref.apply(v))
        assert np.allclose(quat.rotate_inverse(q, v), ref.inv().apply(v))
        assert np.allclose(quat.body_z(q), ref.as_matrix()[:, 2])
        assert np.allclose(quat.to_euler(q), (r, p, y))
        m = ref.as_matrix()
        back = quat.from_axes(tuple(m[:, 0]), tuple(m[:, 1]), tuple(m[:, 2]))
        assert quat.angle_between(back, q) < 1e-6
        w = tuple(rng.normal(size=3))
        integrated = quat.integrate(q, w, 0.01)
        step = tuple(np.roll(Rotation.from_rotvec(np.array(w) * 0.01).as_quat(), 1))
        assert quat.angle_between(integrated, quat.mul(q, step)) < 1e-6


@pytest.mark.parametrize("airframe", [QUAD, HEXA])
def test_mixer_reproduces_requested_thrust_and_torques(airframe):
    mixer = Mixer(airframe)
    thrust, torque = airframe.mass * 9.81, (0.2, -0.15, 0.05)
    result = mixer.mix(thrust, torque)
    f = np.array(result.commands) * airframe.max_thrust
    achieved = mixer.allocation @ f
    assert np.allclose(achieved, [thrust, *torque], atol=1e-9) and not result.saturated


def test_mixer_protects_roll_pitch_over_yaw():
    mixer = Mixer(QUAD)
    result = mixer.mix(QUAD.mass * 9.81, (0.6, 0.0, 0.8))  # large roll + huge yaw
    f = np.array(result.commands) * QUAD.max_thrust
    achieved = mixer.allocation @ f
    assert achieved[1] == pytest.approx(0.6)  # roll fully delivered
    assert result.yaw_scale < 1.0 and 0.0 <= achieved[3] < 0.8
    assert all(0.0 <= c <= 1.0 for c in result.commands)
    extreme = mixer.mix(QUAD.mass * 9.81, (5.0, 0.0, 0.0))  # beyond the motors: scaled, still in range
    assert extreme.roll_pitch_scale < 1.0 and all(0.0 <= c <= 1.0 for c in extreme.commands)


def test_tilt_limit_keeps_vertical_priority():
    tc = TranslationController(QUAD)
    thrust, target = tc.thrust_and_attitude((30.0, 0.0, 0.0), 0.0, quat.IDENTITY)  # absurd sideways demand
    tilt = math.acos(quat.body_z(target)[2])
    assert tilt == pytest.approx(QUAD.max_tilt, abs=1e-6) and tc.saturated_xy
    # the vertical component is kept whole: collective (projected on the level body z) = weight
    assert thrust == pytest.approx(QUAD.mass * 9.80665)


def test_pid_anti_windup_and_derivative_on_measurement():
    pid = VectorPid(QUAD.rate, d_cutoff_hz=40)
    for _ in range(5000):
        pid.update((1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 0.002)
    assert pid.integral[0] == pytest.approx(QUAD.rate.i_limit[0])  # clamped
    frozen = VectorPid(QUAD.rate)
    for _ in range(100):
        frozen.update((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.002, saturated=(True, False, False))
    assert frozen.integral[0] == 0.0
    kick = VectorPid(QUAD.rate)
    kick.update((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.002)
    out = kick.update((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.002)  # setpoint step: no derivative kick
    assert out[0] == pytest.approx(QUAD.rate.p[0] * 1.0 + QUAD.rate.i[0] * 1.0 * 0.002)


def test_airframe_errors_name_the_field():
    import yaml

    doc = yaml.safe_load(default_airframe_path("quad_x").read_text())
    del doc["motor"]["max_thrust_n"]
    with pytest.raises(AirframeError, match="missing field 'motor.max_thrust_n'"):
        airframe_from_dict(doc)
    doc = yaml.safe_load(default_airframe_path("quad_x").read_text())
    doc["frame"] = "tricopter"
    with pytest.raises(AirframeError, match="field 'frame'"):
        airframe_from_dict(doc)
    doc = yaml.safe_load(default_airframe_path("quad_x").read_text())
    doc["mass_kg"] = 5.0
    with pytest.raises(AirframeError, match="cannot hover"):
        airframe_from_dict(doc)

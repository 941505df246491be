"""The GNC nodes refuse an out-of-range start parameter: one line naming it, exit 2 (no graph needed)."""

import os
import subprocess
import sys

import pytest

CASES = [
    ("core_node", "rt_priority:=100", "core: error: parameter 'rt_priority': 100 is outside [0, 99]"),
    ("core_node", "avoid_detection_range:=0.4",
     "core: error: detection range 0.4 m must exceed the protection radius 0.5 m"),
    ("navigation_node", "odometry_rate_hz:=0.0", "navigation: error: parameter 'odometry_rate_hz': 0.0 is outside [0.01, 1000]"),
    ("perception_node", "gyro_offset:=[1.0]", "perception: error: parameter 'gyro_offset' needs 3 values"),
]


@pytest.mark.parametrize(("module", "assignment", "error"), CASES)
def test_bad_start_parameter_one_line_exit_2(module, assignment, error):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="OFF")  # the process never meets a graph
    result = subprocess.run([sys.executable, "-m", f"c4d_gnc.{module}", "--ros-args", "-p", assignment], env=env,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert [line for line in result.stderr.splitlines() if line.strip()] == [error]

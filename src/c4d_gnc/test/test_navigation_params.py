"""The navigation node refuses bad issue-19 parameters at start: one line naming the parameter, exit 2
(no graph needed); the parameters map onto the filter's configuration."""

import math
import os
import subprocess
import sys

import pytest

from c4d_gnc.navigation_node import PARAMS, navigation_config
from c4d_gnc.source_selection import BARO, EXTERNAL, GNSS, NONE, RANGE

CASES = [
    ("horizontal_primary:=baro", "navigation: error: parameter 'horizontal_primary': 'baro' is not one of gnss, external"),
    ("gnss_input:=usb", "navigation: error: parameter 'gnss_input': 'usb' is not one of perception, external"),
    ("external_alignment:=guess",
     "navigation: error: parameter 'external_alignment': 'guess' is not one of estimate, configured"),
    ("origin_latitude_deg:=43.5", "navigation: error: parameters 'origin_latitude_deg', 'origin_longitude_deg', "
                                  "'origin_altitude_m': all three or none (NaN)"),
    ("external_max_rate_hz:=5000.0",
     "navigation: error: parameter 'external_max_rate_hz': 5000.0 is outside [1, 1000]"),
    ("airframe:=octo_q", "navigation: error: parameter 'airframe': no bundled airframe named 'octo_q'"),
    ("airframe:=/nope/frame.yaml",
     "navigation: error: parameter 'airframe': cannot read airframe /nope/frame.yaml: No such file or directory"),
]


@pytest.mark.parametrize(("assignment", "error"), CASES)
def test_bad_navigation_parameter_one_line_exit_2(assignment, error):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="OFF")
    result = subprocess.run([sys.executable, "-m", "c4d_gnc.navigation_node", "--ros-args", "-p", assignment], env=env,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert [line for line in result.stderr.splitlines() if line.strip()] == [error]


def test_defaults_are_gnss_and_baro_and_parameters_map_to_the_config():
    params = {name: spec.default for name, spec in PARAMS.items()}
    config = navigation_config(params)
    assert (config.horizontal_primary, config.horizontal_secondary, config.height_primary, config.height_secondary) \
        == (GNSS, EXTERNAL, BARO, NONE)
    assert config.origin is None and config.external.frame_ids == ("odom",)
    params.update(horizontal_primary="external", horizontal_secondary="gnss", height_primary="range",
                  height_secondary="baro", origin_latitude_deg=43.0, origin_longitude_deg=1.0, origin_altitude_m=140.0,
                  external_alignment="configured", external_yaw_offset_deg=90.0, external_origin_m=[1.0, 2.0, 0.0])
    config = navigation_config(params)
    assert (config.horizontal_primary, config.horizontal_secondary, config.height_primary, config.height_secondary) \
        == (EXTERNAL, GNSS, RANGE, BARO)
    assert config.origin == (43.0, 1.0, 140.0) and math.isclose(config.external_yaw_offset, math.pi / 2)

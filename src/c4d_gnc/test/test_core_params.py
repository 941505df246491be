"""The core's file-backed parameters (config, airframe, phase_method) report the values in force:
the loaded core.yaml's, unless overridden (issue 14 item 4: `ros2 param get /core phase_method` was '')."""

from __future__ import annotations

import yaml

from c4d_gnc.core_config import default_config_path, load_core_config


def test_core_parameters_in_force_come_from_the_file():
    doc = yaml.safe_load(default_config_path().read_text())
    cfg = load_core_config()
    assert cfg.parameters() == {"config": str(default_config_path()), "airframe": doc["airframe"],
                                "phase_method": doc["executive"]["phase_method"]}
    overridden = load_core_config(None, None, "zero").parameters()
    assert overridden["phase_method"] == "zero" and overridden["airframe"] == doc["airframe"]

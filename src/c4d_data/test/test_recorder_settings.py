"""The recorder's settings without DDS: parameter values -> typed settings, topic selection,
one-line refusals."""

from __future__ import annotations

import pytest

from c4d_data.recorder_node import PARAMETERS
from c4d_data.recorder_settings import RecorderSettings


def values(**changes):
    return {**{name: spec.default for name, spec in PARAMETERS.items()}, **changes}


def test_defaults_make_the_documented_recorder(tmp_path):
    s = RecorderSettings.from_parameters(values(output_dir=str(tmp_path / "rec")))
    assert s.recording.compression == "zstd" and s.recording.chunk_size == 1 << 20 and s.queue_depth == 5000
    assert s.status_topic == "vehicle/status" and s.auto_arm and s.niceness == 5
    assert s.make_output_dir() == tmp_path / "rec" and (tmp_path / "rec").is_dir()
    assert s.wants("/anything")  # no include pattern: every topic


def test_include_and_exclude_select_topics(tmp_path):
    s = RecorderSettings.from_parameters(values(output_dir=str(tmp_path), include=["^/sensors/", "^/vehicle/"],
                                                exclude=["imu$"]))
    assert s.wants("/sensors/gps") and s.wants("/vehicle/status")
    assert not s.wants("/sensors/imu") and not s.wants("/navigation/state")


@pytest.mark.parametrize("changes, text", [
    ({"compression": "rar"}, "compression must be zstd, lz4 or none, not 'rar'"),
    ({"include": ["("]}, "missing ), unterminated subpattern at position 0"),
])
def test_unusable_settings_are_refused_in_one_line(tmp_path, changes, text):
    with pytest.raises(ValueError) as err:
        RecorderSettings.from_parameters(values(output_dir=str(tmp_path), **changes))
    assert str(err.value) == text


def test_every_parameter_states_its_unit_and_numbers_have_a_range():
    for name, spec in PARAMETERS.items():
        assert spec.description.endswith("]") and spec.read_only, name
        if isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool):
            assert spec.low is not None and spec.low <= spec.default <= spec.high, name

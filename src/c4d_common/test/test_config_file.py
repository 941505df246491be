"""YAML errors name the line a person must fix (issue 14 item 6: it used to be one line late)."""

import pytest
import yaml

from c4d_common.config_file import ConfigError, read_yaml_mapping, yaml_error_text


def error_text(text: str) -> str:
    with pytest.raises(yaml.YAMLError) as err:
        yaml.safe_load(text)
    return yaml_error_text(err.value)


@pytest.mark.parametrize("text,line", [
    ("name: x\nitems:\n  - {type: takeoff, altitude: 5\n  - {type: rtl}\n", 3),  # unclosed flow mapping
    ("a: 1\nb: [1, 2\nc: 3\n", 2),  # unclosed flow sequence
    ("a: 1\nb 2\nc: 3\n", 2),  # key without ':'
    ("a: 'x\nb: 2\n", 1),  # unclosed quote
    ("a: 1\nb: 2\n c: 3\n", 3),  # bad indentation: the problem's own line, not the enclosing block's
    ("a:\n  b: 1\n c: 2\n", 3),
    ("a: b: c\n", 1),
])
def test_yaml_error_names_the_line_to_fix(text, line):
    message = error_text(text)
    assert message.startswith(f"malformed YAML at line {line} (") and "\n" not in message, message


def test_config_reader_reports_the_same_line(tmp_path):
    path = tmp_path / "core.yaml"
    path.write_text("rates:\n  imu_hz: [500\n  control_hz: 250\n")
    with pytest.raises(ConfigError, match=r"^core config .*core.yaml: malformed YAML at line 2 \(while parsing a flow"):
        read_yaml_mapping(path, "core config")

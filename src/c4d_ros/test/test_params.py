"""c4d_ros.params: every parameter reports the value in force (issue 14 item 4).

A parameter whose empty start value means "the bundled file" is declared with that file's path, a
Declaration settles file-backed values after the node has read its file, and read-only parameters
are read-only after either (a real rclpy node in a private context, no parameter services, no
other process). The core's file-backed parameters come from the loaded core.yaml.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from c4d_ros.params import Declaration, ParameterError, Spec, declare, effective_value


@pytest.fixture
def make_node():
    import rclpy
    from rclpy.context import Context

    contexts = []

    def make(*overrides: str):
        ctx = Context()
        args = ["test"] + (["--ros-args"] + [a for o in overrides for a in ("-p", o)] if overrides else [])
        rclpy.init(args=args, context=ctx)
        contexts.append(ctx)
        return rclpy.create_node("params_test", context=ctx, start_parameter_services=False)

    yield make
    for ctx in contexts:
        rclpy.try_shutdown(context=ctx)


def test_effective_value_replaces_only_an_empty_start_value():
    spec = Spec("", "file [path]", empty=lambda: Path("/share/x.yaml"))
    assert effective_value(spec, "") == "/share/x.yaml"  # typed like the default: a string
    assert effective_value(spec, "mine.yaml") == "mine.yaml"
    assert effective_value(Spec("", "none [path]"), "") == ""  # no fallback: empty is the value in force
    assert effective_value(Spec([""], "list", empty=lambda: ["a"]), [""]) == ["a"]


def test_empty_start_value_is_declared_as_the_fallback_and_read_only(make_node):
    node = make_node("given:=/etc/c4d/mine.yaml")
    spec = Spec("", "file [path]", read_only=True, empty=lambda: "/share/bundled.yaml")
    assert declare(node, "bundled", spec) == "/share/bundled.yaml"
    assert declare(node, "given", spec) == "/etc/c4d/mine.yaml"
    assert node.get_parameter("bundled").value == "/share/bundled.yaml"
    assert node.describe_parameter("bundled").read_only and node.describe_parameter("given").read_only
    from rclpy.parameter import Parameter

    assert not node.set_parameters([Parameter("bundled", value="other.yaml")])[0].successful


def test_declaration_settles_file_values_then_locks_read_only(make_node):
    node = make_node("count:=5", "method:=zero")
    declared = Declaration(node, {"method": Spec("", "from the file [name]", read_only=True),
                                  "count": Spec(1, "n [-]", 0, 10, read_only=True),
                                  "gain": Spec(1.0, "run-time tunable [-]", 0.0, 2.0),
                                  "other": Spec("", "from the file too [name]", read_only=True)})
    assert declared.values == {"method": "zero", "count": 5, "gain": 1.0, "other": ""}
    settled = declared.settle({"method": "zero", "other": "from_file"})
    assert settled == {"method": "zero", "count": 5, "gain": 1.0, "other": "from_file"}
    assert node.get_parameter("other").value == "from_file"
    assert [node.describe_parameter(n).read_only for n in ("method", "count", "gain", "other")] == [True, True, False, True]
    assert node.describe_parameter("count").integer_range[0].to_value == 10  # the range survives


def test_declaration_refuses_a_value_in_force_outside_the_range(make_node):
    declared = Declaration(make_node(), {"n": Spec(1, "n [-]", 0, 10, read_only=True)})
    with pytest.raises(ParameterError, match="parameter 'n'"):
        declared.settle({"n": 50})
    with pytest.raises(ParameterError, match="parameter 'x': not declared"):
        declared.settle({"x": 1})


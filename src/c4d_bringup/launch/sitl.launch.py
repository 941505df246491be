"""`ros2 launch c4d_bringup sitl.launch.py [config:=SYSTEM.yaml] [run_dir:=DIR]`

Starts the graph of the system YAML (default: the installed config/sitl.yaml) on a standard
ROS 2 Jazzy install — the same nodes, parameters and order as `c4d up`
(c4d_bringup.launch_plan). Node output goes to the screen and ~/.ros/log; a critical node's
exit shuts the launch down; the others respawn by their restart policy.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, SetEnvironmentVariable
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from c4d_bringup.launch_plan import launch_plan


def _graph(context, *args, **kwargs):
    plan = launch_plan(LaunchConfiguration("config").perform(context) or None,
                       LaunchConfiguration("run_dir").perform(context) or None)
    (plan.run_dir / "captures").mkdir(parents=True, exist_ok=True)
    actions = [SetEnvironmentVariable("ROS_AUTOMATIC_DISCOVERY_RANGE", plan.discovery_range)]
    for e in plan.entries:
        on_exit = [EmitEvent(event=Shutdown(reason=f"critical node {e.name} exited"))] if e.critical else None
        actions.append(Node(package=e.package, executable=e.executable, output="screen",
                            parameters=[e.parameters] if e.parameters else [],
                            respawn=e.respawn, respawn_delay=e.respawn_delay, respawn_max_retries=e.respawn_max_retries,
                            on_exit=on_exit))
    return actions


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("config", default_value="", description="system YAML (default: c4d_bringup/config/sitl.yaml)"),
        DeclareLaunchArgument("run_dir", default_value="", description="run directory (default: <run_root>/<UTC stamp>)"),
        OpaqueFunction(function=_graph),
    ])

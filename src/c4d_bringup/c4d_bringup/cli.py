"""`c4d` — bring up, fly and inspect the c4d graph (`ros2 run c4d_bringup c4d ...`).

    c4d up     [--config SYSTEM.yaml] [--run-dir DIR]
    c4d fly    --mission FILE [--config SYSTEM.yaml] [--run-dir DIR] [--timeout S] [--no-report]
    c4d status [--config SYSTEM.yaml] [--wait S]
    c4d param  list | set NAME VALUE | reset  [--config SYSTEM.yaml] [--vehicle NAME] [--node core|navigation|health]

The system config defaults to the installed config/sitl.yaml of c4d_bringup. ROS_DOMAIN_ID
comes from the environment. Bad input (unknown node names, missing files, bad YAML, an
executable that does not resolve, a mission that does not parse or validate, bad arguments)
is reported as one line `c4d: error: ...` on stderr with exit code 2, before anything starts.
Exit codes otherwise: 0 success, 1 failure (critical node died, flight not completed, nodes
down), 130 interrupted during `fly`.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from .system_config import ConfigError, SystemConfig, default_config_path, load_system_config
from .system_modes import PHASES


class UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line instead of usage + error
        raise UsageError(f"{message} (try: c4d {self.prog.split()[-1] + ' ' if ' ' in self.prog else ''}--help)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="c4d", description="Bring up, fly and inspect the c4d ROS 2 graph.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser, metavar="{up,fly,status,param,resim}")
    config_help = "system YAML (nodes, parameters, platform); default: the installed c4d_bringup/config/sitl.yaml"
    up = sub.add_parser("up", help="start the whole graph and supervise it until Ctrl-C/SIGTERM")
    up.add_argument("--config", type=Path, help=config_help)
    up.add_argument("--run-dir", type=Path, help="directory for this run's logs and files (default: <run_root>/<UTC stamp>)")
    up.add_argument("--phase", choices=PHASES, help="pin the system mode's phase (e.g. maintenance) instead of following "
                                                     "vehicle/status (docs/lifecycle.md)")
    fly = sub.add_parser("fly", help="end-to-end SITL flight of a mission: start, upload, fly, land, stop, report")
    fly.add_argument("--mission", type=Path, required=True, help="plan file (project YAML or QGroundControl .plan)")
    fly.add_argument("--config", type=Path, help=config_help)
    fly.add_argument("--run-dir", type=Path, help="directory for this run's logs, recording and report")
    fly.add_argument("--timeout", type=float, help="seconds of flight before a land command (default: 3 x the plan "
                                                    "estimate + 60)")
    fly.add_argument("--no-report", action="store_true", help="skip the analysis report")
    param = sub.add_parser("param", help="a vehicle's stored gains and limits: list, set NAME VALUE, reset to the airframe's")
    param.add_argument("action", choices=("list", "set", "reset"))
    param.add_argument("name", nargs="?", help="set: parameter name (c4d param list)")
    param.add_argument("value", nargs="?", help="set: value")
    param.add_argument("--config", type=Path, help=config_help)
    param.add_argument("--vehicle", help="vehicle name (default: the node's parameter 'vehicle' in the system config)")
    param.add_argument("--node", choices=("core", "navigation", "health"), default="core",
                       help="whose live parameters: the core's gains (default), the EKF's noises, the failsafe thresholds")
    sub.add_parser("resim", help="re-simulate a recorded flight: c4d resim FLIGHT.mcap [-p node.param:=value ...] "
                                 "(docs/data.md)", add_help=False)
    status = sub.add_parser("status", help="one screen of the live graph")
    status.add_argument("--config", type=Path, help=config_help)
    status.add_argument("--wait", type=float, default=5.0,
                        help="listen at most this many seconds for every node to show up (default 5)")
    return parser


def fail(message: str) -> int:
    print(f"c4d: error: {message}", file=sys.stderr, flush=True)
    return 2


def load_mission(path: Path, config: SystemConfig):
    """Parse the plan and validate it offline, before anything starts, as the mission node will:
    geometry, geofence and speeds against the simulated home, endurance against the simulated
    pack at full charge (its capacity at the mission's `hover_current_a`, else the sim's hover
    current). Returns (plan, estimated duration)."""
    from c4d_common.plan import PlanError
    from c4d_common.plan_files import load_plan
    from c4d_common.plan_validation import IssueKind, flight_time_left, validate

    try:
        plan = load_plan(path)
    except PlanError as exc:
        raise ConfigError(f"mission {path}: {exc}") from None
    sim = config.node("sim")
    if sim is None:
        return plan, None
    from c4d_sim.sim_config import SimConfigError, default_sim_config, load_sim_config

    sim_file = sim.parameters.get("config") or ""
    try:
        sim_config = load_sim_config(Path(str(sim_file).replace("${config_dir}", str(config.path.parent)))
                                     if sim_file else default_sim_config())
    except SimConfigError as exc:
        raise ConfigError(f"node 'sim': {exc}") from None
    mission = config.node("mission")
    hover = mission.parameters.get("hover_current_a", sim_config.hover_current_a) if mission else sim_config.hover_current_a
    if isinstance(hover, bool) or not isinstance(hover, (int, float)) or not hover > 0:
        raise ConfigError(f"node 'mission': parameter 'hover_current_a' must be a positive number of amperes, got {hover!r}")
    endurance = flight_time_left(sim_config.sensors.battery_capacity_ah, float(hover))
    result = validate(plan, sim_config.origin, endurance_s=endurance)
    if not result.ok:
        battery = f" (full charge {sim_config.sensors.battery_capacity_ah:g} Ah at {float(hover):.1f} A hover, 20 % reserve)" \
            if any(i.kind == IssueKind.ENDURANCE for i in result.issues) else ""
        raise ConfigError(f"mission {path}: " + "; ".join(result.errors) + battery)
    return plan, result.duration


def resim(argv: list[str]) -> int:
    """`c4d resim ...`: the re-simulation tool (package c4d_resim), its arguments passed through unchanged."""
    import os

    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        exe = Path(get_package_prefix("c4d_resim")) / "lib" / "c4d_resim" / "resim"
    except PackageNotFoundError:
        return fail("c4d_resim is not installed (colcon build --packages-select c4d_resim)")
    os.execv(exe, [str(exe), *argv])
    return 0  # not reached


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["resim"]:
        return resim(argv[1:])
    try:
        args = build_parser().parse_args(argv)
    except UsageError as exc:
        return fail(str(exc))
    try:
        config = load_system_config(args.config or default_config_path())
        if args.command == "param":
            from .param_cli import run as param

            if (args.action == "set") != (args.name is not None and args.value is not None):
                raise ConfigError("usage: c4d param set NAME VALUE (list and reset take no name)")
            return param(config, args.action, args.vehicle, args.name, args.value, args.node)
        if args.command == "status":
            if not math.isfinite(args.wait) or args.wait < 0:
                raise ConfigError("--wait must be >= 0")
            from .status import status

            return status(config, args.wait)
        from .graph import new_run_dir, prepare_run, resolve_all
        from .system_config import check_variables

        executables = resolve_all(config)
        check_variables(config)
        if args.command == "fly":
            plan, estimate = load_mission(args.mission, config)
            if args.timeout is not None and not (math.isfinite(args.timeout) and args.timeout > 0):
                raise ConfigError("--timeout must be a positive number of seconds")
            if config.platform != "sitl":
                raise ConfigError("c4d fly flies the simulated vehicle: the system config must have platform: sitl")
            run_dir = args.run_dir.resolve() if args.run_dir else new_run_dir(config)
            specs = prepare_run(config, run_dir, executables)  # checks the run directory is writable
            del specs
        else:
            run_dir = args.run_dir.resolve() if args.run_dir else new_run_dir(config)
            specs = prepare_run(config, run_dir, executables)
    except ConfigError as exc:
        return fail(str(exc))
    if args.command == "fly":
        from .fly import FlyOptions, fly

        timeout = args.timeout or (3.0 * estimate + 60.0 if estimate else 600.0)
        return fly(config, FlyOptions(args.mission, timeout, not args.no_report), plan, run_dir)
    from .graph import run_graph, stamped_logger
    from .system_config import child_environment

    return run_graph(config, specs, child_environment(config, os.environ), run_dir, stamped_logger(), args.phase)


if __name__ == "__main__":
    sys.exit(main())

"""`c4d param list | set NAME VALUE | reset [--node core|navigation|health]` — a vehicle's stored tuning, offline.

What: the core's live gains and limits (c4d_gnc.live_gains) of the vehicle the system config
names (core parameter `vehicle`, or --vehicle): `list` prints each with the value the core will
start with (the airframe's, or the stored change), unit and range; `set` checks a value as the
core would (range, cross-field rules with the other stored values) and stores it; `reset`
removes the vehicle's stored changes, so the next start uses the airframe's defaults.
The store is the one the running core writes (c4d_common.tunable.VehicleStore: one YAML file per
node and vehicle, written atomically under a lock), so the CLI and a running core never tear it.
A running core does not re-read it: change a flying vehicle with `ros2 param set core NAME VALUE`
or a GCS (MAVLink PARAM_SET); both persist the same way.
`--node navigation` / `--node health`: the same for the EKF noises and gates (c4d_gnc.live_navigation)
and the failsafe thresholds (c4d_health.live_policy, on the policy file the system config names, else
the bundled one); the vehicle is that node's `vehicle` parameter.
"""

from __future__ import annotations

import math

from c4d_common.airframe import AirframeError, airframe_by_ref
from c4d_common.share import share_file
from c4d_common.tunable import TunableError, TunableTable, VehicleStore
from c4d_gnc.core_config import CoreConfigError, load_core_config
from c4d_gnc.live_gains import core_table
from c4d_gnc.live_navigation import navigation_table
from c4d_health.live_policy import policy_table
from c4d_health.policy import FailsafePolicy, PolicyError

from .system_config import ConfigError, SystemConfig

NODES = ("core", "navigation", "health")


def _table_and_store(config: SystemConfig, vehicle: str | None, node: str = "core") -> tuple[TunableTable, VehicleStore]:
    entry = config.node(node)
    params = entry.parameters if entry is not None else {}
    name = vehicle or str(params.get("vehicle") or "")
    if not name:
        raise ConfigError(f"no vehicle name: give --vehicle NAME or set the {node}'s parameter 'vehicle' in the system config")

    def path(key: str) -> str:
        return str(params.get(key) or "").replace("${config_dir}", str(config.path.parent))
    try:
        if node == "navigation":
            table = navigation_table(airframe=airframe_by_ref(path("airframe") or "quad_x"))
        elif node == "health":
            table = policy_table(FailsafePolicy.from_yaml(path("policy_file") or share_file("c4d_health", "config",
                                                                                           "failsafe.yaml")))
        else:
            table = core_table(load_core_config(path("config") or None, path("airframe") or None).airframe)
        return table, VehicleStore.of(name, node)
    except (CoreConfigError, PolicyError, TunableError, AirframeError) as exc:
        raise ConfigError(str(exc)) from None


def run(config: SystemConfig, action: str, vehicle: str | None, name: str | None, value: str | None,
        node: str = "core") -> int:
    """The `c4d param` subcommand; ConfigError (one line, exit 2) for anything unusable."""
    table, store = _table_and_store(config, vehicle, node)
    try:
        stored = store.read()
    except TunableError as exc:
        raise ConfigError(str(exc)) from None
    if action == "list":
        print(f"# {store.path}{'' if store.path.exists() else ' (no stored changes)'}")
        for t in table:
            mark = "*" if t.name in stored else " "
            shown = stored.get(t.name, t.default)
            print(f"{mark} {t.name:34s} {shown:<10g} [{t.unit}] {t.low:g}..{t.high:g}  {t.description}")
        return 0
    if action == "reset":
        removed = store.reset()
        defaults = {"core": "the airframe's", "navigation": "the EKF's default", "health": "the policy file's"}[node]
        print(f"{store.path}: {'removed' if removed else 'nothing stored'}; the next start uses {defaults} values")
        return 0
    assert name is not None and value is not None
    try:
        number = float(value)
    except ValueError:
        raise ConfigError(f"{name}: {value!r} is not a number") from None
    if not math.isfinite(number):
        raise ConfigError(f"{name}: {value} is not finite")
    current = {**table.defaults(), **{k: float(v) for k, v in stored.items() if k in table}}
    reason = table.check({name: number}, current)
    if reason:
        raise ConfigError(reason)
    store.update({name: number}, table.defaults())
    print(f"{name} = {number:g} stored in {store.path} (applies at the next start; a running {node}: "
          f"ros2 param set {node} {name} {number:g})")
    return 0

"""The interface manifest: every topic and service of the c4d graph in one place.

This module is the truth for names, types, QoS profiles, nominal rates, producers and
consumers. Nodes take their topic names and QoS from here (`IMU.name`, `IMU.qos`), the
tables of docs/ARCHITECTURE.md are generated from it (`python tools/interface_docs.py`), and
`test/test_interface_manifest.py` starts the whole graph and fails on any difference between
the live graph and this file.

Names are relative (the graph runs in the root namespace by default). The recorder subscribes
to every topic (its include/exclude parameters), so it is a consumer of every topic here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rclpy.qos import QoSProfile

from .qos import Profile

RECORDER = "recorder"


@dataclass(frozen=True)
class Topic:
    name: str
    type: str  # ROS type name, e.g. "sensor_msgs/msg/Imu"
    profile: Profile
    rate: str  # nominal rate in words ("500 Hz", "on change + 2 Hz")
    producers: tuple[str, ...]
    consumers: tuple[str, ...]
    about: str = ""
    recorded: bool = True  # the recorder subscribes (default configuration)
    lockstep_only: bool = False  # exists only in lockstep mode (system YAML `lockstep: true`)

    @property
    def qos(self) -> QoSProfile:
        return self.profile.qos

    @property
    def all_consumers(self) -> tuple[str, ...]:
        return self.consumers + ((RECORDER,) if self.recorded and RECORDER not in self.consumers else ())


@dataclass(frozen=True)
class Service:
    name: str
    type: str  # e.g. "c4d_interfaces/srv/VehicleCommand"
    server: str
    clients: tuple[str, ...]
    about: str = ""
    rate: str = "on demand"


@dataclass(frozen=True)
class Manifest:
    topics: tuple[Topic, ...]
    services: tuple[Service, ...]
    nodes: tuple[str, ...] = field(default=())
    actions: tuple[Action, ...] = field(default=())

    def topic(self, name: str) -> Topic:
        for t in self.topics:
            if t.name == name:
                return t
        raise KeyError(f"no topic '{name}' in the interface manifest")


S, ST, CMD, L, STATS = Profile.SENSOR, Profile.STATE, Profile.COMMAND, Profile.LATCHED, Profile.STATS

# --- sensors (the simulated hardware) ------------------------------------------------------
IMU = Topic("sensors/imu", "sensor_msgs/msg/Imu", Profile.IMU, "500 Hz, every sample (late ones after a stall)", ("sim",),
            ("perception",))
GPS = Topic("sensors/gps", "sensor_msgs/msg/NavSatFix", S, "10 Hz, 50 ms latency", ("sim",), ("perception",))
BARO = Topic("sensors/baro", "sensor_msgs/msg/FluidPressure", S, "50 Hz", ("sim",), ("perception",))
MAG = Topic("sensors/mag", "sensor_msgs/msg/MagneticField", S, "50 Hz", ("sim",), ("perception",))
RANGE_DOWN = Topic("sensors/range_down", "sensor_msgs/msg/Range", S, "50 Hz", ("sim",), ("perception",))
BATTERY = Topic("sensors/battery", "sensor_msgs/msg/BatteryState", S, "10 Hz", ("sim",), ("mission", "health", "bridge"),
                "also read by the c4d CLI")
GROUND_TRUTH = Topic("sim/ground_truth", "nav_msgs/msg/Odometry", S, "100 Hz", ("sim",), (),
                     "true state in `map` (tests, analysis)")
ACTUATOR_LINK = Topic("sim/actuator_link", "diagnostic_msgs/msg/DiagnosticStatus", STATS, "1 Hz", ("sim",), (),
                      "the sim's diagnostics: gaps in control/actuators as the vehicle received them (worst, p99.9, "
                      "> 20 ms) and IMU samples published late / dropped after stalls (tests, bench)")
SCAN = Topic("sensors/scan", "sensor_msgs/msg/LaserScan", S, "10-20 Hz (sim parameter)", ("sim",), ("perception",),
             "horizontal 360° lidar rendered from the world file (frame base_link, FLU; levelled at the vehicle's height)")
SIM_OBSTACLES = Topic("sim/obstacles", "c4d_interfaces/msg/Surroundings", S, "10 Hz", ("sim",), (),
                      "the world's true obstacles and wind in `map` (tests, analysis); what perception estimates")
CLOCK = Topic("clock", "rosgraph_msgs/msg/Clock", ST, "lockstep only: per step (500 Hz simulated)", ("sim",),
              ("core", "perception", "navigation", "mission", "payload", "health", "bridge"),
              "simulated time in lockstep mode (the core's tick; `use_sim_time` of the other nodes); absent in real time",
              recorded=False, lockstep_only=True)
# --- perception ---------------------------------------------------------------------------
P_IMU = Topic("perception/imu", "sensor_msgs/msg/Imu", Profile.IMU, "500 Hz", ("perception",), ("navigation", "core"),
              "validated, calibrated; the core takes the gyro")
P_GPS = Topic("perception/gps", "sensor_msgs/msg/NavSatFix", S, "10 Hz", ("perception",), ("navigation", "bridge"))
P_BARO = Topic("perception/baro", "sensor_msgs/msg/FluidPressure", S, "50 Hz", ("perception",), ("navigation",))
P_MAG = Topic("perception/mag", "sensor_msgs/msg/MagneticField", S, "50 Hz", ("perception",), ("navigation",))
P_RANGE_DOWN = Topic("perception/range_down", "sensor_msgs/msg/Range", S, "50 Hz", ("perception",), ("navigation",))
P_HEALTH = Topic("perception/health", "diagnostic_msgs/msg/DiagnosticArray", STATS, "5 Hz", ("perception",),
                 ("health", "mission", "bridge"), "sensor health (bridge: SYS_STATUS sensor bits)")
SURROUNDINGS = Topic("perception/surroundings", "c4d_interfaces/msg/Surroundings", ST, "per scan (10-20 Hz)",
                     ("perception",), ("core", "health", "bridge"),
                     "tracked obstacles (map) and the wind estimate: the core's avoidance barrier, health's proximity "
                     "events, the bridge's OBSTACLE_DISTANCE")
MARKERS = Topic("perception/markers", "visualization_msgs/msg/MarkerArray", S, "per scan", ("perception",), (),
                "obstacles as markers for RViz / Foxglove")
# --- navigation ---------------------------------------------------------------------------
NAV_STATE = Topic("navigation/state", "c4d_interfaces/msg/VehicleState", ST, "500 Hz (per IMU sample)", ("navigation",),
                  ("core", "perception", "mission", "payload", "health", "bridge", "offboard"), "full estimated state")
NAV_ODOMETRY = Topic("navigation/odometry", "nav_msgs/msg/Odometry", ST, "50 Hz (parameter)", ("navigation",), ("health",),
                     "the estimate as standard odometry in `map` (tools, the c4d CLI); health: navigation's liveness")
# --- GNC core -----------------------------------------------------------------------------
SETPOINT = Topic("guidance/setpoint", "c4d_interfaces/msg/GuidanceSetpoint", ST,
                 "50 Hz while flying a plan / RTL / go-to (AUTO only)", ("mission",), ("core",),
                 "the mission's stream: the core follows it in AUTO (MISSION / GOTO / RTL) only")
PILOT_SETPOINT = Topic("guidance/pilot", "c4d_interfaces/msg/GuidanceSetpoint", ST,
                       "per MANUAL_CONTROL frame in STABILIZED / ACRO", ("bridge",), ("core",),
                       "pilot attitude / rate level; the core follows it in ATTITUDE / RATE only")
OFFBOARD_SETPOINT = Topic("guidance/offboard", "c4d_interfaces/msg/GuidanceSetpoint", ST,
                          "as the external stream, at most 100 Hz", ("offboard",), ("core", "health", "bridge"),
                          "validated external setpoints (the offboard gateway is the only publisher); the core follows "
                          "it in OFFBOARD only; health: offboard_loss; bridge: POSITION_TARGET_LOCAL_NED")
ACTUATORS = Topic("control/actuators", "c4d_interfaces/msg/ActuatorCommand", ST, "every tick (500 Hz)", ("core",), ("sim",),
                  "the core is the only publisher")
STATUS = Topic("vehicle/status", "c4d_interfaces/msg/VehicleStatus", L, "on change + 5 Hz (health's heartbeat)",
               ("core",),
               ("navigation", "mission", "payload", "health", "bridge", "offboard", "lifecycle_manager"),
               "armed, mode, landed state, failsafe; the lifecycle manager of `c4d up` picks the system mode's phase")
EXECUTOR_STATS = Topic("gnc/executor_stats", "c4d_interfaces/msg/ExecutorStats", STATS, "1 Hz", ("core",),
                       ("health", "bridge"), "cyclic-executive profiler")
SCHEDULE = Topic("gnc/schedule", "c4d_interfaces/msg/ScheduleTable", L, "once", ("core",), (), "static schedule (GCD+)")
# --- mission and payload ------------------------------------------------------------------
MISSION_STATE = Topic("mission/state", "c4d_interfaces/msg/MissionState", L, "on change + 5 Hz", ("mission",),
                      ("payload", "health", "bridge"), "health: mission's liveness")
MISSION_PLAN = Topic("mission/plan", "c4d_interfaces/msg/MissionPlan", L, "on change", ("mission",),
                     ("payload", "bridge", "offboard"), "the accepted plan (its fence is in geofence/active)")
CAPTURES = Topic("payload/captures", "c4d_interfaces/msg/CaptureEvent", CMD, "per capture", ("payload",), ("bridge",))
GIMBAL = Topic("payload/gimbal", "geometry_msgs/msg/Vector3Stamped", S, "50 Hz while a mission runs", ("payload",), (),
               "roll, pitch, yaw [rad], body frame")
GEOFENCE = Topic("geofence/active", "c4d_interfaces/msg/Geofence", L, "on change", ("mission",),
                 ("core", "health", "offboard", "bridge"),
                 "the fence in force: the accepted plan's, or one set in flight (geofence/set, MAVLink fence upload); "
                 "the core's barrier, health's breach check, the gateway's clamp, the bridge's FENCE_STATUS")
# --- health -------------------------------------------------------------------------------
DIAGNOSTICS = Topic("diagnostics", "diagnostic_msgs/msg/DiagnosticArray", STATS, "1 Hz", ("health",), ())
HEALTH_SUMMARY = Topic("health/summary", "diagnostic_msgs/msg/DiagnosticStatus", L, "10 Hz", ("health",), ("bridge",),
                       "failsafe, reason, active events, dead nodes")
# --- bridge -------------------------------------------------------------------------------
GCS_HEARTBEAT = Topic("bridge/gcs_heartbeat", "std_msgs/msg/Header", ST, "per GCS HEARTBEAT (~1 Hz per GCS)", ("bridge",),
                      (), "frame_id 'gcs'; health subscribes when its `link_topic` names it (not in the bundled YAML)")
LINK_STATS = Topic("bridge/link_stats", "diagnostic_msgs/msg/DiagnosticArray", STATS, "1 Hz", ("bridge",), (),
                   "link up/losses, per endpoint rx/tx, rejections, utilisation")
# --- offboard (the public API for external nodes, docs/offboard.md) -----------------------
OFFBOARD_TRAJECTORY = Topic("offboard/trajectory_setpoint", "c4d_interfaces/msg/GuidanceSetpoint", ST,
                            "external: >= 2 Hz to enter and keep OFFBOARD", ("bridge",), ("offboard",),
                            "public input: any level, NaN = unset, frame map (ENU); also external nodes "
                            "(bridge: MAVLink SET_POSITION_TARGET_* / SET_ATTITUDE_TARGET)")
OFFBOARD_POSE = Topic("offboard/pose", "geometry_msgs/msg/PoseStamped", ST, "external", (), ("offboard",),
                      "public input: position + yaw target, frame map (ENU); external nodes")
OFFBOARD_TWIST = Topic("offboard/twist", "geometry_msgs/msg/TwistStamped", ST, "external", (), ("offboard",),
                       "public input: velocity + yaw rate, frame map (ENU) or base_link (FLU); external nodes")
OFFBOARD_STATUS = Topic("offboard/status", "diagnostic_msgs/msg/DiagnosticStatus", L, "1 Hz + on change",
                        ("offboard",), ("health",), "stream live, accepted / rejected per reason / rate-limited counts, "
                        "active action; health: the gateway's liveness")
NAV_POSE = Topic("navigation/pose", "geometry_msgs/msg/PoseStamped", ST, "50 Hz (odometry_rate_hz)", ("navigation",), (),
                 "the estimate's pose in `map` for external nodes")
# --- navigation sources (issue 19, docs/navigation.md) ----------------------------------------
NAV_STATUS = Topic("navigation/status", "c4d_interfaces/msg/EstimatorStatus", L, "5 Hz + on change", ("navigation",),
                   ("health", "bridge", "mission"), "fused sources, switches, external input health and rejections, GNSS "
                   "integrity; mission: pre-arm refuses an untrusted GNSS the estimate depends on")
EXTERNAL_ODOMETRY = Topic("navigation/external/odometry", "nav_msgs/msg/Odometry", S, "external: up to 200 Hz",
                          ("sim", "bridge"), ("navigation",),
                          "public input: VIO / mocap odometry (frame_id one of `external_frame_ids`, child base_link); "
                          "sim: external-pose emulator; bridge: MAVLink ODOMETRY")
EXTERNAL_POSE = Topic("navigation/external/pose", "geometry_msgs/msg/PoseWithCovarianceStamped", S,
                      "external: up to 200 Hz", ("bridge",), ("navigation",),
                      "public input: pose of base_link (frame_id one of `external_frame_ids`); "
                      "bridge: MAVLink VISION_POSITION_ESTIMATE, ATT_POS_MOCAP")
EXTERNAL_GNSS = Topic("navigation/external/gnss", "sensor_msgs/msg/NavSatFix", S, "external: 1-20 Hz", ("bridge",),
                      ("navigation",), "public input: fixes from another receiver; bridge: MAVLink GPS_INPUT")
# --- re-simulation journals (c4d_gnc.journal, docs/data.md § Re-simulation) ----------------
NAV_JOURNAL = Topic("navigation/journal", "std_msgs/msg/UInt8MultiArray", CMD, "10 Hz batches + a snapshot at arm",
                    ("navigation",), (), "which input sample each callback consumed, in order (resim)")
CORE_JOURNAL = Topic("gnc/journal", "std_msgs/msg/UInt8MultiArray", CMD, "10 Hz batches + a snapshot at arm", ("core",),
                     (), "per tick: index, clock, gyro and state stamps; setpoints, commands, fences, retunes (resim)")
# --- recorder -----------------------------------------------------------------------------
RECORDER_STATUS = Topic("recorder/status", "diagnostic_msgs/msg/DiagnosticStatus", L, "1 Hz + on change", ("recorder",),
                        (), "state, file, written, dropped; the c4d CLI and tests")

TOPICS: tuple[Topic, ...] = (
    IMU, GPS, BARO, MAG, RANGE_DOWN, BATTERY, GROUND_TRUTH, ACTUATOR_LINK, CLOCK,
    P_IMU, P_GPS, P_BARO, P_MAG, P_RANGE_DOWN, P_HEALTH,
    SCAN, SIM_OBSTACLES, SURROUNDINGS, MARKERS,
    NAV_STATE, NAV_ODOMETRY, NAV_POSE, NAV_STATUS, EXTERNAL_ODOMETRY, EXTERNAL_POSE, EXTERNAL_GNSS,
    SETPOINT, PILOT_SETPOINT, OFFBOARD_SETPOINT, ACTUATORS, STATUS, EXECUTOR_STATS, SCHEDULE,
    MISSION_STATE, MISSION_PLAN, GEOFENCE, CAPTURES, GIMBAL,
    DIAGNOSTICS, HEALTH_SUMMARY,
    GCS_HEARTBEAT, LINK_STATS,
    OFFBOARD_TRAJECTORY, OFFBOARD_POSE, OFFBOARD_TWIST, OFFBOARD_STATUS,
    NAV_JOURNAL, CORE_JOURNAL,
    RECORDER_STATUS,
)

# --- services -----------------------------------------------------------------------------
CORE_COMMAND = Service("gnc/command", "c4d_interfaces/srv/VehicleCommand", "core", ("mission", "health"),
                       "ARM, DISARM, TAKEOFF, LAND, RETURN_TO_LAUNCH, HOLD, SET_MODE, GOTO; applied at the next tick")
VEHICLE_COMMAND = Service("vehicle/command", "c4d_interfaces/srv/VehicleCommand", "mission", ("bridge", "health", "offboard"),
                          "every vehicle command incl. RTL; also the c4d CLI")
MISSION_UPLOAD = Service("mission/upload", "c4d_interfaces/srv/UploadMission", "mission", ("bridge",),
                         "validate and accept a plan; also the c4d CLI")
MISSION_DOWNLOAD = Service("mission/download", "c4d_interfaces/srv/DownloadMission", "mission", (),
                           "tools (the bridge answers MAVLink downloads from mission/plan)")
SET_GEOFENCE = Service("geofence/set", "c4d_interfaces/srv/SetGeofence", "mission", ("bridge",),
                       "replace the fence in force, in flight too (validated; outside it only with force); also tools")
MISSION_CONTROL = Service("mission/control", "c4d_interfaces/srv/MissionControl", "mission", ("bridge",),
                          "start / pause / resume / clear / set current; also the c4d CLI")
RECORDER_START = Service("recorder/start", "std_srvs/srv/Trigger", "recorder", (), "c4d CLI, tests")
RECORDER_STOP = Service("recorder/stop", "std_srvs/srv/Trigger", "recorder", (), "c4d CLI, tests")

SERVICES: tuple[Service, ...] = (
    CORE_COMMAND, VEHICLE_COMMAND, MISSION_UPLOAD, MISSION_DOWNLOAD, MISSION_CONTROL, SET_GEOFENCE, RECORDER_START, RECORDER_STOP,
)

# --- actions (rclpy action servers; clients are external nodes and c4d_client) ---------------
@dataclass(frozen=True)
class Action:
    name: str
    type: str  # e.g. "c4d_interfaces/action/GoTo"
    server: str
    about: str = ""


ACTION_TAKEOFF = Action("offboard/takeoff", "c4d_interfaces/action/TakeOff", "offboard",
                        "arm if needed, climb to an altitude above home, hold")
ACTION_LAND = Action("offboard/land", "c4d_interfaces/action/Land", "offboard", "land here and disarm; cancel: hold")
ACTION_GOTO = Action("offboard/goto", "c4d_interfaces/action/GoTo", "offboard",
                     "fly to a map (ENU) position in OFFBOARD, feedback distance to go; cancel: hold")
ACTION_FOLLOW_PATH = Action("offboard/follow_path", "c4d_interfaces/action/FollowPath", "offboard",
                            "fly a nav_msgs/Path at a speed in OFFBOARD; cancel: hold")
ACTIONS: tuple[Action, ...] = (ACTION_TAKEOFF, ACTION_LAND, ACTION_GOTO, ACTION_FOLLOW_PATH)

NODES: tuple[str, ...] = ("sim", "perception", "navigation", "core", "mission", "payload", "health", "bridge", "offboard",
                          "recorder")

MANIFEST = Manifest(TOPICS, SERVICES, NODES, ACTIONS)


# Every node is a managed node (c4d_ros.lifecycle): the ROS-standard lifecycle endpoints of each node are implicit,
# like the parameter services, and not listed above: services /<node>/<one of LIFECYCLE_SERVICES>
# (lifecycle_msgs/srv/*; clients: c4d up's lifecycle_manager, `ros2 lifecycle`) and the topic
# /<node>/transition_event (lifecycle_msgs/msg/TransitionEvent; consumer: health). docs/lifecycle.md
LIFECYCLE_SERVICES = frozenset({"change_state", "get_state", "get_available_states", "get_available_transitions",
                                "get_transition_graph"})
LIFECYCLE_TOPIC = "transition_event"


def is_lifecycle_endpoint(name: str) -> bool:
    """Whether a service or topic name is one of a managed node's standard lifecycle endpoints."""
    base = name.rsplit("/", 1)[-1]
    return base in LIFECYCLE_SERVICES or base == LIFECYCLE_TOPIC


def side_node_name(owner: str) -> str:
    """Name of the hidden helper node on which `owner` keeps LatestSampler subscriptions; the
    live-graph check attributes its subscriptions to `owner`."""
    return f"_{owner}_samples"

"""World model and lidar without DDS: exact ray-cast ranges against each shape (and against an
independent sphere-tracing reference built on the shapes' distance functions), REP-117 range
conventions, movers over time, the wind field acting on the plant, strict world-file errors."""

from __future__ import annotations

import math
import random
import re
import time
from pathlib import Path

import numpy as np
import pytest

from c4d_common.airframe import GRAVITY
from c4d_sim.lidar import Lidar, LidarConfig
from c4d_sim.plant import MultirotorPlant
from c4d_sim.sim_config import default_sim_config, load_sim_config
from c4d_sim.simulation import Simulation, task_specs
from c4d_sim.world import Box, Cylinder, Mover, WindField, World, WorldError, load_world, truth

WORLDS = Path(__file__).resolve().parents[3] / "worlds"


def ranges(world: World, beams: int = 8, x: float = 0.0, y: float = 0.0, z: float = 1.0, yaw: float = 0.0,
           t: float = 0.0, **cfg) -> np.ndarray:
    """Noise-free scan: beam i at angle -π + i·2π/beams from the heading (8 beams: i = 4 forward, 6 left)."""
    return Lidar(LidarConfig(beams=beams, noise=0.0, **cfg), world).scan(x, y, z, yaw, t)


def test_cylinder_exact_ranges_and_heading():
    w = World(cylinders=(Cylinder(5.0, 0.0, 1.0, 3.0), Cylinder(3.0, 3.0, 1.0, 3.0)))
    r = ranges(w)
    assert r[4] == pytest.approx(4.0, abs=1e-5)  # forward (east)
    assert r[5] == pytest.approx(math.sqrt(18.0) - 1.0, abs=1e-5)  # 45° left
    assert np.isinf(r[[0, 1, 2, 3, 6, 7]]).all() and (r[[0, 1, 2, 3, 6, 7]] > 0).all()
    # heading north: the east cylinder is now on the right (-90°, beam 2)
    assert ranges(w, yaw=math.pi / 2)[2] == pytest.approx(4.0, abs=1e-5)


def test_box_yawed_box_and_wall_exact_ranges():
    w = World(boxes=(Box(0.0, 5.0, 2.0, 4.0, 0.0, 3.0),))  # north face at y = 3
    assert ranges(w)[6] == pytest.approx(3.0, abs=1e-5)
    diamond = World(boxes=(Box(5.0, 0.0, 2.0, 2.0, math.radians(45.0), 3.0),))  # corner towards the sensor
    assert ranges(diamond)[4] == pytest.approx(5.0 - math.sqrt(2.0), abs=1e-5)
    wall = load_world_text("walls:\n  - {from: [-10, -3], to: [10, -3], thickness: 0.2, height: 5}\n")
    r = ranges(wall)
    assert r[2] == pytest.approx(2.9, abs=1e-5)  # south
    assert r[1] == pytest.approx(2.9 * math.sqrt(2.0), abs=1e-5)  # south-west, 45° to the wall
    # a 200 m wall whose centre lies far beyond range_max is still seen where it passes near
    far = load_world_text("walls:\n  - {from: [-5, 3], to: [195, 3], thickness: 0.2, height: 5}\n")
    assert ranges(far, range_max=10.0)[6] == pytest.approx(2.9, abs=1e-5)


def test_nearest_surface_wins_and_height_and_limits():
    w = World(cylinders=(Cylinder(10.0, 0.0, 1.0, 3.0), Cylinder(5.0, 0.0, 0.5, 3.0)))
    assert ranges(w)[4] == pytest.approx(4.5, abs=1e-5)
    assert math.isinf(ranges(w, z=3.5)[4])  # above both tops: the scan plane misses them
    assert ranges(w, z=0.0)[4] == pytest.approx(4.5, abs=1e-5)  # on the ground
    assert ranges(w, range_max=4.0)[4] == math.inf  # beyond range_max: +inf (REP-117)
    inside = ranges(w, x=5.2)  # sensor inside a cylinder: every beam reads -inf (too close)
    assert (inside == -math.inf).all()
    assert ranges(World(cylinders=(Cylinder(0.15, 0.0, 0.1, 3.0),)))[4] == -math.inf  # 0.05 m < range_min


def test_random_worlds_match_sphere_tracing_reference():
    """Independent check: march each beam by the world's exact clearance (distance functions, not ray
    algebra) until it touches a surface; the vectorised ranges must agree to millimetres."""
    rnd = random.Random(7)
    for _ in range(15):
        w = World(cylinders=tuple(Cylinder(rnd.uniform(-15, 15), rnd.uniform(-15, 15), rnd.uniform(0.2, 2), 5.0)
                                  for _ in range(rnd.randint(0, 6))),
                  boxes=tuple(Box(rnd.uniform(-15, 15), rnd.uniform(-15, 15), rnd.uniform(0.2, 5), rnd.uniform(0.2, 5),
                                  rnd.uniform(-math.pi, math.pi), 5.0) for _ in range(rnd.randint(0, 6))))
        x, y, yaw = rnd.uniform(-2, 2), rnd.uniform(-2, 2), rnd.uniform(-math.pi, math.pi)
        if w.clearance(x, y, 1.0, 0.0) < 0.2:
            continue
        lidar = Lidar(LidarConfig(beams=72, noise=0.0, range_max=40.0), w)
        got = lidar.scan(x, y, 1.0, yaw, 0.0)
        for i, angle in enumerate(lidar.angles + yaw):
            assert got[i] == pytest.approx(sphere_trace(w, x, y, angle, 40.0), abs=2e-3), (i, w)


def sphere_trace(w: World, x: float, y: float, angle: float, limit: float) -> float:
    s = 0.0
    while s < limit:
        d = w.clearance(x + s * math.cos(angle), y + s * math.sin(angle), 1.0, 0.0)
        if d < 1e-4:
            return s
        s += d
    return math.inf


def test_noise_has_the_configured_sigma():
    lidar = Lidar(LidarConfig(beams=360, noise=0.05), World(cylinders=(Cylinder(6.0, 0.0, 1.0, 3.0),)), seed=3)
    samples = np.concatenate([lidar.scan(0.0, 0.0, 1.0, 0.0, 0.0)[180:181] for _ in range(2000)])
    assert samples.mean() == pytest.approx(5.0, abs=0.01) and samples.std() == pytest.approx(0.05, rel=0.1)


def test_movers_position_and_velocity_over_time():
    loop = Mover(((0.0, 0.0), (10.0, 0.0), (10.0, 10.0)), 2.0, 0.5, 3.0, back_and_forth=False)
    assert loop.state(0.0) == ((0.0, 0.0), (2.0, 0.0))
    p, v = loop.state(7.5)  # 15 m: second leg, 5 m north
    assert p == pytest.approx((10.0, 5.0)) and v == pytest.approx((0.0, 2.0))
    p, v = loop.state(12.0)  # 24 m: closing leg (10, 10) → (0, 0), 4 m along it
    assert p == pytest.approx((10.0 - 4 / math.sqrt(2), 10.0 - 4 / math.sqrt(2))) and v == pytest.approx((-math.sqrt(2),) * 2)
    period = (20.0 + 10.0 * math.sqrt(2.0)) / 2.0
    assert loop.state(period + 1.0)[0] == pytest.approx((2.0, 0.0))
    shuttle = Mover(((0.0, 0.0), (10.0, 0.0)), 2.0, 0.5, 3.0, back_and_forth=True)
    assert shuttle.state(7.0) == (pytest.approx((6.0, 0.0)), pytest.approx((-2.0, 0.0)))  # 14 m: on the way back
    assert shuttle.state(11.0)[0] == pytest.approx((2.0, 0.0))
    # the lidar sees the mover where it is at t
    w = World(movers=(Mover(((5.0, -10.0), (5.0, 10.0)), 2.0, 0.5, 3.0, back_and_forth=True),))
    assert math.isinf(ranges(w, t=0.0)[4]) and ranges(w, t=5.0)[4] == pytest.approx(4.5, abs=1e-5)


def test_truth_lists_every_obstacle_with_bounding_circle():
    w = World(cylinders=(Cylinder(1.0, 2.0, 0.5, 3.0),), boxes=(Box(0.0, 5.0, 6.0, 8.0, 0.3, 4.0),),
              movers=(Mover(((0.0, 0.0), (4.0, 0.0)), 1.0, 0.7, 2.0, back_and_forth=True),))
    obs = truth(w, 1.0)
    assert [o.id for o in obs] == [1, 2, 3]
    assert obs[1].radius == pytest.approx(5.0) and (obs[2].x, obs[2].vx) == pytest.approx((1.0, 1.0))
    pillar = World(cylinders=w.cylinders)
    assert pillar.clearance(1.0, 3.0, 1.0, 0.0) == pytest.approx(0.5)  # 1 m from the cylinder's centre
    assert pillar.clearance(1.0, 2.0, 7.0, 0.0) == pytest.approx(4.0)  # above its top
    assert w.clearance(0.0, 5.0, 1.0, 0.0) == pytest.approx(-3.0)  # inside the box: negative


def test_wind_field_and_drag_push_the_vehicle_downwind():
    field = WindField((3.0, 4.0, 0.0), gust=2.0, gust_period=4.0)
    assert field.at(0.0) == pytest.approx((3.0, 4.0, 0.0))
    assert field.at(2.0) == pytest.approx((3.0 + 1.2, 4.0 + 1.6, 0.0))  # the gust peaks along the mean
    assert WindField(gust=1.0, gust_period=2.0).at(1.0) == pytest.approx((1.0, 0.0, 0.0))  # no mean: from the west
    config = load_sim_config(default_sim_config())
    plant = MultirotorPlant(config.airframe, (0.0, 0.0, 10.0))
    plant.wind = (5.0, 0.0, 0.0)
    hover = config.airframe.mass * GRAVITY / (config.airframe.max_thrust * len(config.airframe.motors))
    plant.state.thrusts = [hover * config.airframe.max_thrust] * len(config.airframe.motors)
    for _ in range(200):
        plant.step(0.001, [hover] * len(config.airframe.motors))
    assert plant.state.velocity[0] > 0.05 and abs(plant.state.velocity[1]) < 1e-6  # pushed towards +x (downwind)
    # the world's wind replaces the sim config's in the simulation
    sim = Simulation(config, time.monotonic_ns, World(wind=WindField((0.0, -5.0, 0.0))))
    sim.physics(0)
    assert sim.plant.wind == pytest.approx((0.0, -5.0, 0.0))


def test_world_tasks_join_the_schedule():
    config = load_sim_config(default_sim_config())
    specs = {s.name: s for s in task_specs(config, {"scan": 20.0, "obstacles": 10.0})}
    assert specs["scan"].divider == 50 and specs["obstacles"].divider == 100
    with pytest.raises(ValueError, match="15.0 Hz rate does not divide"):
        task_specs(config, {"scan": 15.0})


def load_world_text(text: str, tmp: Path | None = None) -> World:
    import tempfile

    with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
        f.write(text)
    try:
        return load_world(f.name)
    finally:
        Path(f.name).unlink()


@pytest.mark.parametrize("text, message", [
    ("trees: []\n", "world: unknown field(s) trees"),
    ("cylinders:\n  - {center: [1, 2], radius: 0, height: 3}\n", "'cylinders[0].radius' must be a positive number"),
    ("cylinders:\n  - {center: [1], radius: 1, height: 3}\n", "'cylinders[0].center' must be a list of 2 numbers"),
    ("cylinders:\n  - {center: [1, 2], radius: 1, hieght: 3}\n", "world: cylinders[0]: unknown field(s) hieght"),
    ("boxes:\n  - {center: [0, 0], size: [1, -2], height: 3}\n", "'boxes[0].size' must be two positive numbers"),
    ("walls:\n  - {from: [1, 1], to: [1, 1], height: 3}\n", "'walls[0].to' must differ from 'walls[0].from'"),
    ("movers:\n  - {path: [[0, 0]], speed: 1, radius: 1, height: 2}\n", "'movers[0].path' must be a list of at least 2"),
    ("movers:\n  - {path: [[0, 0], [1, 0]], speed: 1, radius: 1, height: 2, mode: pingpong}\n",
     "'movers[0].mode' must be 'loop' or 'back_and_forth'"),
    ("movers:\n  - {path: [[0, 0], [1, 0]], speed: .nan, radius: 1, height: 2}\n", "'movers[0].speed' must be a positive"),
    ("wind: {mean_enu_m_s: [1, 2]}\n", "'wind.mean_enu_m_s' must be a list of 3 numbers"),
    ("wind: {gust_m_s: -1}\n", "'wind.gust_m_s' must be a number >= 0"),
    ("cylinders: {center: [0, 0]}\n", "field 'cylinders' must be a list of mappings"),
    ("cylinders: [\n", "malformed YAML"),
])
def test_world_file_errors_are_one_line_naming_the_field(text, message):
    with pytest.raises(WorldError, match=re.escape(message)) as err:
        load_world_text(text)
    assert "\n" not in str(err.value)


def test_example_worlds_load():
    names = {p.stem: load_world(p) for p in sorted(WORLDS.glob("*.yaml"))}
    assert {"pillars", "moving", "windy"} <= set(names)
    assert names["moving"].movers and names["pillars"].boxes and names["windy"].wind is not None

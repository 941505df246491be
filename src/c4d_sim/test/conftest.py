import pytest
import yaml

from c4d_gnc.airframe import default_airframe_path, load_airframe
from c4d_sim.closed_loop import DEFAULT_NOISE, ClosedLoop


@pytest.fixture(scope="module")
def core_config():
    with open(default_airframe_path("quad_x").parent.parent / "core.yaml") as f:
        return yaml.safe_load(f)["executive"]


@pytest.fixture
def make_loop(core_config):
    def make(airframe="quad_x", noise=DEFAULT_NOISE, seed=1, **kwargs):
        return ClosedLoop(load_airframe(default_airframe_path(airframe)), kwargs.pop("config", core_config),
                          noise, seed=seed, **kwargs)
    return make

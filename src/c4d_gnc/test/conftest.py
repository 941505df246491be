import pytest
import yaml
from closed_loop import DEFAULT_NOISE, ClosedLoop

from c4d_common.airframe import default_airframe_path, load_airframe
from c4d_gnc.core_config import default_config_path


@pytest.fixture(scope="module")
def core_config():
    with open(default_config_path()) as f:
        return yaml.safe_load(f)["executive"]


@pytest.fixture
def make_loop(core_config):
    def make(airframe="quad_x", noise=DEFAULT_NOISE, seed=1, **kwargs):
        return ClosedLoop(load_airframe(default_airframe_path(airframe)), kwargs.pop("config", core_config),
                          noise, seed=seed, **kwargs)
    return make

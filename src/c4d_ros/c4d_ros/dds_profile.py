"""c4d's Fast DDS participant profile and the environment variable that loads it.

What: `config/fastdds_profile.xml` (installed to share/c4d_ros/config) makes every participant
announce only a loopback UDP locator for user data, so no writer ever delivers into another
process's shared-memory port. Why: with shared memory, publish() in the GNC core, the sim and
the navigation filter blocked for up to hundreds of milliseconds whenever a reader's process died
or a new one joined (docs/dds.md, bench/interference.py).

env.sh exports the variable for every shell; `with_profile()` does the same for processes started
without env.sh (the supervisor's children under `c4d up` / `ros2 launch`). An explicit
FASTRTPS_DEFAULT_PROFILES_FILE is respected; C4D_FASTDDS_PROFILE="" (empty) opts out.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from c4d_common.share import share_file

PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
OPT_OUT_ENV = "C4D_FASTDDS_PROFILE"


def profile_path() -> Path:
    """The installed (or source-tree) c4d Fast DDS profile."""
    return share_file("c4d_ros", "config", "fastdds_profile.xml")


def with_profile(base: Mapping[str, str]) -> dict[str, str]:
    """`base` plus the profile variable, unless it is already set or C4D_FASTDDS_PROFILE opts out."""
    env = dict(base)
    choice = base.get(OPT_OUT_ENV)
    if PROFILE_ENV in env or choice == "":
        return env
    env[PROFILE_ENV] = choice or str(profile_path())
    return env

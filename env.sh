# c4d environment — source it, do not run it:   . ./env.sh
#
# Activates the project venv, the ROS 2 Jazzy underlay (PyPI wheels inside the venv, or the
# system install in /opt/ros/jazzy when setup.sh chose it) and the colcon overlay
# (install/setup.bash), with safe defaults: DDS discovery on this machine only
# (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) and Fast DDS as the RMW. Every script, test and CI
# run uses it. Returns non-zero with a one-line reason when the workspace is not set up.
#
# C4D_ENV_UNDERLAY_ONLY=1 skips the overlay (setup.sh uses this before the first build).

# shellcheck shell=bash
_c4d_env() {
    local root venv mode
    root=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
    venv=${C4D_VENV:-$root/.venv}
    if [ ! -x "$venv/bin/python" ] || [ ! -f "$venv/c4d-mode" ]; then
        echo "env.sh: error: no c4d venv at $venv — run ./setup.sh first" >&2
        return 1
    fi
    mode=$(cat "$venv/c4d-mode")
    # Remember the caller's PATH once, so tools can start clean sub-environments.
    export C4D_ORIG_PATH=${C4D_ORIG_PATH:-$PATH}
    export C4D_ROOT=$root
    export C4D_VENV=$venv
    export C4D_ROS_MODE=$mode

    # ROS setup scripts read unset variables; relax nounset while sourcing them.
    local had_u=0
    case $- in *u*) had_u=1; set +u ;; esac

    if [ "$mode" = system ]; then
        # shellcheck disable=SC1091
        . /opt/ros/jazzy/setup.bash
    fi
    # shellcheck disable=SC1091
    VIRTUAL_ENV_DISABLE_PROMPT=1 . "$venv/bin/activate"
    if [ "$mode" = wheels ]; then
        # The wheels install their ament index and CMake configs under the venv prefix.
        case ":${AMENT_PREFIX_PATH:-}:" in *":$venv:"*) ;; *) export AMENT_PREFIX_PATH=$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH} ;; esac
        case ":${CMAKE_PREFIX_PATH:-}:" in *":$venv:"*) ;; *) export CMAKE_PREFIX_PATH=$venv${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH} ;; esac
    fi
    local status=0
    if [ "${C4D_ENV_UNDERLAY_ONLY:-0}" != 1 ]; then
        if [ ! -f "$root/install/.c4d-ready" ] || [ ! -f "$root/install/setup.bash" ]; then
            echo "env.sh: error: workspace not built (or last build failed) — run ./setup.sh" >&2
            status=1
        else
            # shellcheck disable=SC1091
            . "$root/install/setup.bash"
        fi
    fi
    [ "$had_u" = 1 ] && set -u

    export ROS_DISTRO=${ROS_DISTRO:-jazzy}
    # DDS discovery stays on this machine unless C4D_DISCOVERY_RANGE says otherwise (deployment).
    export ROS_AUTOMATIC_DISCOVERY_RANGE=${C4D_DISCOVERY_RANGE:-LOCALHOST}
    export RMW_IMPLEMENTATION=${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}
    # Fast DDS profile: user data over loopback UDP, never shared memory (docs/dds.md: a dead or new
    # participant made publish() block in the flight-critical nodes). C4D_FASTDDS_PROFILE= disables it.
    local profile=${C4D_FASTDDS_PROFILE-$root/src/c4d_ros/config/fastdds_profile.xml}
    if [ -n "$profile" ]; then
        export FASTRTPS_DEFAULT_PROFILES_FILE=$profile
    else
        unset FASTRTPS_DEFAULT_PROFILES_FILE
    fi
    return $status
}
_c4d_env
_c4d_env_status=$?
unset -f _c4d_env
# shellcheck disable=SC2317
return $_c4d_env_status 2>/dev/null || exit $_c4d_env_status

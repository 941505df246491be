#!/usr/bin/env bash
# c4d image entrypoint: the workspace environment (env.sh), then the command.
#   docker run c4d                                  -> c4d up (the SITL graph)
#   docker run c4d c4d fly --mission missions/hop.yaml
#   docker run -it c4d bash                         -> a shell with the workspace sourced
set -e
cd /c4d
# shellcheck disable=SC1091
. /c4d/env.sh
if [ "${1:-}" = c4d ]; then
    shift
    exec /c4d/install/c4d_bringup/lib/c4d_bringup/c4d "$@"
fi
exec "$@"

"""One line instead of a traceback when an installed c4d executable runs without its environment.

The executables colcon installs under `install/<pkg>/lib/<pkg>/` start with this venv's Python but
find their packages only through the paths `env.sh` sets. Started from a plain shell they die in
`importlib.metadata` (`PackageNotFoundError: c4d-gnc`) or on `import rclpy`, with a 20-line
traceback. setup.sh copies this module into the venv's site-packages with a `.pth` line that
imports it, so any Python of this venv replaces exactly those tracebacks — and only while the c4d
environment is not set (`C4D_ROOT` unset) — by the hint `./c4d` prints, and exits 2.
"""

from __future__ import annotations

import os
import sys
from types import TracebackType

_NEEDS_ENVIRONMENT = ("c4d", "rclpy", "rcl_interfaces", "ament_index_python", "rosidl", "builtin_interfaces")


def _names_missing_environment(error: BaseException) -> bool:
    """The error is a c4d/ROS package that the environment would have put on the path."""
    if type(error).__name__ == "PackageNotFoundError":  # importlib.metadata, for a console-script wrapper
        return str(error.args[0] if error.args else "").replace("-", "_").startswith("c4d_")
    if isinstance(error, ImportError):
        name = error.name or ""
        return name.startswith(_NEEDS_ENVIRONMENT) or "librcl" in str(error)
    return False


def _hook(kind: type[BaseException], error: BaseException, tb: TracebackType | None) -> None:
    if "C4D_ROOT" not in os.environ and _names_missing_environment(error):
        program = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else "python"
        env_sh = os.path.join(os.path.dirname(sys.prefix), "env.sh")
        where = env_sh if os.path.isfile(env_sh) else "env.sh of the c4d checkout"
        sys.stderr.write(f"{program}: error: the c4d environment is not set — run `. {where}` first "
                         f"(or start it through ./c4d); missing: {error}\n")
        sys.stderr.flush()
        os._exit(2)
    _previous(kind, error, tb)


_previous = sys.excepthook
sys.excepthook = _hook

"""`ros2 run c4d_bringup container [--group NAME] PACKAGE/EXECUTABLE... [--ros-args ...]` — several
c4d nodes in one process on one executor (process composition, docs/bringup.md).

Each PACKAGE/EXECUTABLE names a component: the `c4d.components` entry point of that package
(declared in its setup.py next to the console script of the same name). Components are loaded
by name, like plugins of a ROS 2 component container, so this module imports no block package.
Every node keeps its own name, parameters, topics and services; parameters come from a
parameters file keyed by node name (`c4d up` writes one per group: params/<group>.yaml).
A component that does not exist or cannot load, or a bad parameter, is one line
`container: error: ...` (or `<node>: error: ...`) and exit 2; otherwise the exit code is the
highest of the nodes' (the recorder's is 1 after a failed write).
"""

from __future__ import annotations

import argparse
import sys

from c4d_ros.component import ComponentError, Factory, load_factory, run_components


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line instead of usage + error
        raise ComponentError(f"{message} (try: container --help)")


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv if argv is None else argv)
    try:
        from rclpy.utilities import remove_ros_args

        parser = _Parser(prog="container", description="Run c4d components (nodes) in one process on one executor.")
        parser.add_argument("--group", default="container", help="name of this process in logs (the compose group)")
        parser.add_argument("components", nargs="+", metavar="PACKAGE/EXECUTABLE",
                            help="components to run, in this order (c4d.components entry points)")
        args = parser.parse_args(remove_ros_args(argv)[1:])
        factories: list[tuple[str, Factory]] = []
        for spec in args.components:
            package, _, executable = spec.partition("/")
            if not package or not executable:
                raise ComponentError(f"'{spec}' is not PACKAGE/EXECUTABLE")
            factories.append((executable, load_factory(package, executable)))
        if len({name for name, _ in factories}) != len(factories):
            raise ComponentError(f"a component is named twice in {' '.join(args.components)}")
    except ComponentError as exc:
        print(f"container: error: {exc}", file=sys.stderr, flush=True)
        return 2
    return run_components(factories, argv, args.group, composed=True)


if __name__ == "__main__":
    sys.exit(main())

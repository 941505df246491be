#!/usr/bin/env python3
"""Rewrite the wheel builder's interpreter paths in the ROS 2 wheels' exported CMake files.

Why: the `ros-jazzy-*` wheels on PyPI were built under `/opt/python/cp311-cp311`; their
exported CMake files (e.g. `<pkg>__rosidl_generator_pyExport.cmake`) still name that
interpreter's include dir and site-packages, so building any interface package against them
fails in CMake's generate step. This script points those paths at the running interpreter's
own include dir and purelib (site-packages). It only rewrites files whose content changes,
so running it again is a no-op (idempotent).

Usage: python fix_wheel_cmake_paths.py <venv prefix>   (prints how many files it rewrote)
"""

from __future__ import annotations

import sys
import sysconfig
from pathlib import Path

BUILDER_PREFIX = "/opt/python/cp311-cp311"
BUILDER_INCLUDE = f"{BUILDER_PREFIX}/include/python3.11"
BUILDER_SITE_PACKAGES = f"{BUILDER_PREFIX}/lib/python3.11/site-packages"


def rewrite(text: str, include_dir: str, site_packages: str) -> str:
    """Return `text` with the builder's include and site-packages paths replaced."""
    return text.replace(BUILDER_INCLUDE, include_dir).replace(BUILDER_SITE_PACKAGES, site_packages)


def fix_tree(prefix: Path, include_dir: str, site_packages: str) -> list[Path]:
    """Rewrite every CMake file under `<prefix>/share/*/cmake/`; return the files changed."""
    changed: list[Path] = []
    for path in sorted(prefix.glob("share/*/cmake/**/*")):
        if not path.is_file() or path.suffix not in {".cmake", ".in"}:
            continue
        text = path.read_text(encoding="utf-8", errors="surrogateescape")
        if BUILDER_PREFIX not in text:
            continue
        new = rewrite(text, include_dir, site_packages)
        if new != text:
            path.write_text(new, encoding="utf-8", errors="surrogateescape")
            changed.append(path)
    return changed


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: fix_wheel_cmake_paths.py <venv prefix>", file=sys.stderr)
        return 2
    prefix = Path(argv[1])
    if not (prefix / "share").is_dir():
        print(f"fix_wheel_cmake_paths: error: {prefix}/share does not exist", file=sys.stderr)
        return 1
    paths = sysconfig.get_paths()
    include_dir, site_packages = paths["include"], paths["purelib"]
    if not Path(include_dir, "Python.h").is_file():
        print(
            f"fix_wheel_cmake_paths: error: Python headers missing ({include_dir}/Python.h);"
            " install the python3-dev package",
            file=sys.stderr,
        )
        return 1
    changed = fix_tree(prefix, include_dir, site_packages)
    leftovers = [
        p
        for p in prefix.glob("share/*/cmake/**/*.cmake")
        if BUILDER_INCLUDE in p.read_text(errors="ignore")
        or BUILDER_SITE_PACKAGES in p.read_text(errors="ignore")
    ]
    if leftovers:
        print(f"fix_wheel_cmake_paths: error: still unfixed: {leftovers[0]}", file=sys.stderr)
        return 1
    print(f"{len(changed)} file(s) rewritten")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

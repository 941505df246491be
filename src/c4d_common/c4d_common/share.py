"""Where a package's bundled data files are: its installed `share/` or, in a source tree, beside it.

Why: every block ships YAML defaults (airframes, core.yaml, sim.yaml, failsafe.yaml, …) and must
find them both after `colcon build` (ament index) and when run from a checkout (tests, tools).
"""

from __future__ import annotations

from pathlib import Path


def share_file(package: str, *parts: str, source_root: Path | None = None) -> Path:
    """`share/<package>/<parts…>` of the installed package when it exists, else the same path
    under the package's source folder (`src/<package>/<parts…>`, or `source_root`)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

        installed = Path(get_package_share_directory(package)).joinpath(*parts)
        if installed.exists():
            return installed
    except (ImportError, LookupError, PackageNotFoundError):
        pass
    root = source_root if source_root is not None else Path(__file__).resolve().parents[2] / package
    return root.joinpath(*parts)

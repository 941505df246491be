"""Root pytest configuration: loads the shared c4d test plugin for src/*/test and test/."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "test" / "support"))

pytest_plugins = ["c4d_testing"]

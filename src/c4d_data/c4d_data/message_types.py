"""Python classes of installed ROS message types, looked up by name."""

from __future__ import annotations

import importlib
from typing import Any


def message_class(type_name: str) -> Any:
    """Python class of 'pkg/msg/Type', or None if that package is not installed."""
    try:
        package, namespace, name = type_name.split("/")
        return getattr(importlib.import_module(f"{package}.{namespace}"), name)
    except (ValueError, ImportError, AttributeError):
        return None

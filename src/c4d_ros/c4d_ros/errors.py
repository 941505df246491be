"""Typed errors shared by c4d_ros's runner (component.py) and life cycle (lifecycle.py).

Why a module of its own: both import it, and neither may import the other at module level and
back (test_architecture forbids import cycles between files)."""

from __future__ import annotations


class ComponentError(Exception):
    """A component that cannot be created or found (one line)."""

"""Cascaded controller stages, each a small ROS-free module (see docs/gnc.md)."""

"""c4d_resim: deterministic re-simulation of recorded flights (docs/data.md § Re-simulation)."""

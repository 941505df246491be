"""c4d bring-up: system configuration, process supervisor, flight summary, the `c4d` CLI."""

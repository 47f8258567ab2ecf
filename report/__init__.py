"""Self-contained HTML report comparing the engines phase by phase (SPEC §1)."""

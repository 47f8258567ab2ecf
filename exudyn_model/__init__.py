"""The dual-arm flexible space robot built from Exudyn's own elements (SPEC §1)."""

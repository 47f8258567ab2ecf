"""The dual-arm flexible space robot built from Exudyn's own elements (docs/exudyn.md)."""

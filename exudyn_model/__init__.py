"""The dual-arm flexible space robot built from Exudyn's own elements (docs/exudyn.md)."""

from rsmcheck.core.jit import use_source_keyed_cache

use_source_keyed_cache()

"""The Kane–Newton reference model of the paper (docs/physics.md), compiled with numba."""

from rsmcheck.core.jit import use_source_keyed_cache

use_source_keyed_cache()

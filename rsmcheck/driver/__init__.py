"""The sampled-data driver every engine shares: the initial state, the controllers and the
runner.  It reads the foundation (rsmcheck.core) and no engine."""

from rsmcheck.core.jit import use_source_keyed_cache

use_source_keyed_cache()

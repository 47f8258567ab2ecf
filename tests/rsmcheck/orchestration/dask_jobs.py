"""Cheap, picklable job functions for tests/rsmcheck/orchestration/test_executor.py (a
module of their own: Dask's workers import them by name, the repository root on their
path)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np


def noise(seed: int, n: int = 2000) -> np.ndarray:
    """A deterministic array whose every bit depends on the arithmetic (sums, sin, a
    matrix product): equal to the bit in any process of the same machine."""
    x = np.random.default_rng(seed).standard_normal((n // 40, 40))
    return np.sin(x @ x.T).cumsum(axis=0)


def started_at(delay: float) -> float:
    """When the job started (time.time()); then `delay` seconds of sleep."""
    t = time.time()
    time.sleep(delay)
    return t


def marked(folder: str, delay: float, fn, *args):
    """Leave FOLDER/PID (written whole: a temporary name, then renamed) to say which
    process runs the job, wait `delay` seconds (the time to be killed in), then `fn(*args)`."""
    tmp = Path(folder) / f".{os.getpid()}.tmp"
    tmp.write_text(str(time.time()))
    tmp.rename(Path(folder) / str(os.getpid()))
    time.sleep(delay)
    return fn(*args)


def environment(names: tuple[str, ...]) -> dict[str, str | None]:
    """The values of the environment variables `names` in the process running the job."""
    return {n: os.environ.get(n) for n in names}

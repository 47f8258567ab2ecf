"""The engine packages' functions beyond the Engine object (rsmcheck/core/engine.py): each
package offers the same functions with the same signatures, so shared code asks both the
same way and never reads an engine's internals."""

from __future__ import annotations

import importlib
import inspect
import math

import pytest

from rsmcheck.core.cases import load_case

PACKAGES = ("reference_model", "exudyn_model")
FUNCTIONS = (("modes", "linear_plant"), ("modes", "coupled_frequencies"), ("stepping", "rhs_timing"))


@pytest.mark.parametrize("module, name", FUNCTIONS)
def test_same_function_same_signature_in_both_engines(module, name):
    signatures = {pkg: inspect.signature(getattr(importlib.import_module(f"{pkg}.{module}"), name))
                  for pkg in PACKAGES}
    assert len(set(map(str, signatures.values()))) == 1, signatures


@pytest.mark.parametrize("package", PACKAGES)
def test_rhs_timing_reports_the_documented_keys(package):
    rhs_timing = importlib.import_module(f"{package}.stepping").rhs_timing
    timing = rhs_timing(load_case("closed_squeeze"), 5)
    assert set(timing) == {"call_us", "compiled_us", "states"}
    assert timing["call_us"] > 0.0 and timing["states"] > 0
    assert timing["compiled_us"] > 0.0 or (package == "exudyn_model" and math.isnan(timing["compiled_us"]))

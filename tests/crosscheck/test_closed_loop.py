"""The sampled closed loop of p1_rigid_gains (Fig. 6a), linearised in both engines: the same
unstable 92 Hz rotor modes (docs/exudyn.md §10).  Each engine linearises its own model
(rsmcheck.modes.reference_linear_plant, exudyn_model.modes.linear_plant); the controller's
laws and the zero-order hold are the shared part (rsmcheck.closed_loop)."""

from __future__ import annotations

import numpy as np
import pytest

from cases.loader import load_case
from rsmcheck.closed_loop import analyse


@pytest.fixture(scope="module")
def exponents():
    return analyse(load_case("p1_rigid_gains"))


@pytest.mark.crosscheck
def test_the_rigid_model_gains_destabilise_the_rotor_modes(exponents):
    """Fig. 6a: with the gains chosen on the rigid model the loop is unstable; the two arm-2
    rotor modes grow at ≈ 0.5/s in the reference (the growth rate the case measures)."""
    s = exponents["reference"]
    assert len(s) == 6
    assert np.sort(s.real)[-2:] == pytest.approx([0.50, 0.50], abs=0.02)


@pytest.mark.crosscheck
def test_engines_agree_on_the_closed_loop(exponents):
    """Same six modes; σ within 0.01/s (measured 7.4e-3 with 2 reference modes and 8
    elements: modal truncation), frequencies within 0.01 Hz."""
    ref, exu = exponents["reference"], exponents["exudyn"]
    assert len(ref) == len(exu) == 6
    assert np.max(np.abs(ref.real - exu.real)) < 0.01
    assert np.max(np.abs(ref.imag - exu.imag)) / (2 * np.pi) < 0.01

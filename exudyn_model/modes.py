"""Eigenfrequencies from Exudyn: one link (`links.link_frequencies`) and the coupled,
linearised robot in a case's configuration (for `rsmcheck modes`).

`coupled_frequencies` builds the engine's full model (base, target, six ANCF links with their
frame bodies, rotors, active grasps) in the case's initial configuration *at rest*, without
damping (ζ = 0, C_m = 0: the undamped frequencies both engines can be compared on), and asks
Exudyn for the eigenvalues of M, K projected on the null space of the constraint Jacobian
(`ComputeODE2Eigenvalues(ignoreAlgebraicEquations=False)`).  The zero frequencies of the
free-floating rigid motions (3 for the floating base, 6 joint rotations, and the wrist while a
grasp is on) are dropped.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from exudyn_model import links
from exudyn_model.links import analytic_frequencies, link_frequencies  # noqa: F401  (re-exported)


def at_rest_undamped(case, params=None):
    """The case in its initial configuration with zero rates and no damping."""
    params = params or case.params
    params = dataclasses.replace(params, link=dataclasses.replace(params.link, damping_ratio=0.0),
                                 motor=dataclasses.replace(params.motor, damping=0.0))
    ini = dataclasses.replace(case.initial, base_rate=(0.0, 0.0, 0.0), joint_rates=(0.0,) * 6)
    return dataclasses.replace(case, initial=ini, params=params)


def coupled_frequencies(case, n: int = 6, n_elements: int = links.N_ELEMENTS_DEFAULT,
                        params=None, f_min: float = 1.0) -> np.ndarray:
    """The first `n` non-zero eigenfrequencies [Hz] of the linearised robot of `case`."""
    from exudyn_model.engine import ExudynEngine

    engine = ExudynEngine(at_rest_undamped(case, params), n_elements=n_elements)
    freqs, _ = engine.mbs.ComputeODE2Eigenvalues(convert2Frequencies=True, ignoreAlgebraicEquations=False)
    freqs = np.asarray(freqs)
    return freqs[freqs > f_min][:n]

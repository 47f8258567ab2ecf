"""The MuJoCo model's links against Euler–Bernoulli (rsmcheck.core.beams), and eq. (2)'s rotor
against its analytic clamped frequency: analytic references, not self-comparisons."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

from mujoco_model import links  # noqa: E402
from rsmcheck.core.beams import analytic_frequencies  # noqa: E402
from rsmcheck.core.cases import load_case  # noqa: E402
from rsmcheck.core.params import Params  # noqa: E402


@pytest.mark.parametrize("basis", ["PP", "PF"])
def test_link_frequencies_against_euler_bernoulli(basis):
    p = Params()
    exact = analytic_frequencies(p.link, basis, 2)
    err8 = links.link_frequencies(p, basis, 8, 2) / exact - 1.0
    err16 = links.link_frequencies(p, basis, 16, 2) / exact - 1.0
    assert np.all(np.abs(err8) < [5e-5, 5e-4]), err8
    # fourth order in 1/N: halving the segments divides the error by ≈ 16
    assert np.all(np.abs(err8 / err16) > 13.0), err8 / err16
    assert np.all(err8 < 0.0)  # converging from below


def test_frame_tendon_leaves_the_link_modes_alone():
    """J_extra sits on the link frame's rotation, which the PP and PF modes leave at rest
    (docs/physics.md §2.3): the frequencies do not depend on it."""
    from dataclasses import replace

    p = Params()
    heavy = replace(p, link=replace(p.link, inertia_z=p.link.inertia_z + 5.0))
    for basis in ("PP", "PF"):
        a = links.link_frequencies(p, basis, 8, 2)
        b = links.link_frequencies(heavy, basis, 8, 2)
        assert np.allclose(a, b, rtol=1e-6), (basis, a, b)


def test_clamped_rotor_is_eq2():
    """Eq. (2) with the link held (ψ_J fixed): the rotor swings alone at √(K_m/B_m), in
    MuJoCo's own M and K of the whole robot along θ_m with s = ψ_J − θ_m."""
    from mujoco_model.engine import MujocoEngine

    e = MujocoEngine(load_case("flex_arm_step"))
    m, d = e.mm.model, e.d
    M = e.mass_matrix()
    ix = e.mm.index
    v = np.zeros(m.nv)
    v[ix.rotor[1, 0]], v[ix.spring[1, 0]] = 1.0, -1.0
    import mujoco

    q0 = d.qpos.copy()
    forces = []
    for sign in (1.0, -1.0):
        d.qpos[:] = q0 + sign * 1e-6 * v
        mujoco.mj_forward(m, d)
        forces.append(d.qfrc_passive.copy())
    k = -v @ (forces[0] - forces[1]) / 2e-6
    f = math.sqrt(k / (v @ M @ v)) / (2 * math.pi)
    mo = e.params.motor
    assert f == pytest.approx(math.sqrt(mo.stiffness / mo.inertia) / (2 * math.pi), rel=1e-7)


def test_coupled_frequencies_in_the_rotor_band():
    """The free_drift robot at rest: the rotor band of docs/physics.md §3.4 (75–89 Hz with
    the links' end compliance in series, below √(K_m/B_m)/2π = 91.9 Hz)."""
    from mujoco_model.modes import coupled_frequencies

    f = coupled_frequencies(load_case("free_drift"), n=40, f_min=60.0)
    band = f[(f > 70.0) & (f < 92.0)]
    assert len(band) >= 4, f

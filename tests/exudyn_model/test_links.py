"""One link of ANCF cable elements against Table 2 and against its own interpolation."""

from __future__ import annotations

import numpy as np
import pytest

from exudyn_model import links
from rsmcheck.core.beams import analytic_frequencies
from rsmcheck.core.params import TABLE2_HZ, Params


@pytest.mark.parametrize("basis", ["PP", "PF"])
def test_frequencies_within_0p1_percent_of_table2(basis):
    f = links.link_frequencies(Params(), basis, links.N_ELEMENTS_DEFAULT)
    table = np.array(TABLE2_HZ[basis])
    assert np.all(np.abs(f / table - 1.0) < 1e-3), (basis, f, table)
    fa = analytic_frequencies(Params().link, basis)
    assert np.all(np.abs(f / fa - 1.0) < 5e-4), (basis, f, fa)


def test_convergence_is_monotone_and_fourth_order():
    rows = links.convergence_table(counts=(4, 8, 16))
    for basis in ("PP", "PF"):
        for mode in (1, 2):
            e = [r["error_analytic"] for r in rows if r["basis"] == basis and r["mode"] == mode]
            assert e[0] > e[1] > e[2] > 0.0  # stiff from above, converging
            assert 8.0 < e[0] / e[1] < 24.0  # h^4 (cubic Hermite): ratio 16 per halving


def test_mass_matrix_and_integrals_match_exudyn():
    import exudyn as exu

    p = Params().link
    mesh = links.LinkMesh(6, p.length, p.rho_a)
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    nodes, elements = links.add_link(mbs, p, 6, (0.3, -0.2), 0.7)
    mbs.Assemble()
    solver = exu.MainSolverStatic()
    settings = exu.SimulationSettings()
    settings.solution.file.write = False
    solver.InitializeSolver(mbs, settings)
    solver.ComputeMassMatrix(mbs)
    M = solver.GetSystemMassMatrix()
    assert np.allclose(M, mesh.mass_matrix(), rtol=1e-12, atol=1e-12)
    q = np.concatenate([mbs.GetNodeOutput(n, exu.OutputVariableType.Coordinates) +
                        np.array(mbs.GetNodeParameter(n, "referenceCoordinates")) for n in nodes])
    # total mass, COM and second moment of the straight link
    F = mesh.first_matrix() @ q
    C = mesh.moment_matrix() @ q
    e = np.array([np.cos(0.7), np.sin(0.7)])
    assert np.allclose(F, p.mass * (np.array([0.3, -0.2]) + 0.5 * p.length * e), rtol=1e-13)
    assert np.allclose(C, p.rho_a * (p.length**2 / 2 * np.array([0.3, -0.2]) + p.length**3 / 3 * e),
                       rtol=1e-13)
    # position interpolation agrees with Exudyn's element output
    for xi in (0.1, 0.75, 1.37):
        el, s = mesh.element_of(xi)
        r = mbs.GetObjectOutputBody(elements[el], exu.OutputVariableType.Position, [s, 0, 0])[:2]
        assert np.allclose(r, mesh.pos_matrix(xi) @ q, atol=1e-14)
    assert mesh.strain_energy(q, p.ei, p.axial_to_bending * p.ei) < 1e-20

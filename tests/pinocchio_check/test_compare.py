"""Reference model vs Pinocchio: every rigid quantity, open and closed chain (crosscheck).

One test per (n_modes, chain/holding arm, quantity), each over `N_STATES` seeded random
consistent states (pinocchio_check.states).  A failure names the quantity, the worst
seed and the entry.  The last tests show that the comparison has teeth: building the
Pinocchio side from parameters that differ by 1 mm in one mount point, or by 1e-3 in
the link mass, makes exactly the quantities that depend on them fail.
"""

from __future__ import annotations

import pytest

from pinocchio_check import compare
from rsmcheck.core.params import Params

pytest.importorskip("reference_model.build")

N_STATES = compare.N_STATES
CASES = [("open", 1), ("open", 2), ("closed", 0)]


def _key(chain, arm):
    return f"{chain}-arm{arm}" if arm else chain


@pytest.fixture(scope="module")
def rows_by_key():
    """All comparison rows, computed once: {(n_modes, case, quantity): row}."""
    out = {}
    for n_modes in (0, 2):
        for row in compare.run_checks(n_states=N_STATES, n_modes=n_modes, open_arms=(1, 2)):
            arm = {"arm1": 1, "arm2": 2, "both": 0}[row["holding"]]
            out[(n_modes, _key(row["chain"], arm), row["quantity"])] = row
    return out


def _params():
    for n_modes in (0, 2):
        for chain, arm in CASES:
            for q in compare.QUANTITIES:
                if n_modes and q in compare.DYNAMIC:
                    continue
                yield pytest.param(n_modes, _key(chain, arm), q, id=f"modes{n_modes}-{_key(chain, arm)}-{q}")


@pytest.mark.crosscheck
@pytest.mark.parametrize("n_modes,case,quantity", list(_params()))
def test_reference_matches_pinocchio(rows_by_key, n_modes, case, quantity):
    row = rows_by_key[(n_modes, case, quantity)]
    assert row["states"] == N_STATES
    assert row["pass"], (
        f"{quantity} ({case}, n_modes={n_modes}): max relative error "
        f"{row['max_rel_error']} > {row['tolerance']:g} at seed {row['seed']}, entry {row['entry']}"
        + (f"; reference raised {row['error']}" if "error" in row else "")
    )


def _perturbed_rows(pin_params: Params, wanted):
    rows = compare.run_checks(params=Params(), pin_params=pin_params, n_states=20,
                              chains=("open", "closed"), wanted=wanted)
    return rows


@pytest.mark.crosscheck
def test_moved_mount_of_arm2_is_detected():
    """Pinocchio side with arm 2's root 1 mm off: every quantity that sees arm 2's
    geometry fails; those that do not (arm 1, the target's grasp points) still pass."""
    moved = Params.from_overrides({"geometry": {"mount_arm2_B": [1.0, -0.599]}}, where="test")
    depends = ["mass_matrix", "nonlinear_terms", "ee2_position", "ee2_jacobian", "ee2_jdot_qd",
               "com_position", "com_jacobian", "momentum", "accelerations", "reaction_forces"]
    independent = ["ee1_position", "ee1_jacobian", "ee1_jdot_qd", "grasp1_position", "grasp2_position"]
    for row in _perturbed_rows(moved, depends + independent):
        expect_pass = row["quantity"] in independent
        assert row["pass"] == expect_pass, (
            f"{row['quantity']} ({row['chain']}): pass={row['pass']} with arm 2 moved 1 mm, "
            f"error {row['max_rel_error']}"
        )


@pytest.mark.crosscheck
def test_heavier_link_is_detected():
    """Pinocchio side with link mass × (1 + 1e-3): inertial quantities fail, pure
    kinematics pass."""
    p = Params()
    heavier = Params.from_overrides({"link": {"mass": p.link.mass * (1 + 1e-3)}}, where="test")
    inertial = ["mass_matrix", "nonlinear_terms", "com_position", "com_jacobian", "momentum",
                "accelerations", "reaction_forces"]
    kinematic = ["ee1_position", "ee2_position", "ee1_jacobian", "ee2_jacobian", "ee1_jdot_qd",
                 "ee2_jdot_qd", "grasp1_position", "grasp2_position"]
    for row in _perturbed_rows(heavier, inertial + kinematic):
        expect_pass = row["quantity"] in kinematic
        assert row["pass"] == expect_pass, (
            f"{row['quantity']} ({row['chain']}): pass={row['pass']} with link mass +0.1 %, "
            f"error {row['max_rel_error']}"
        )


def test_main_json_and_exit_code(capsys):
    import json

    rc = compare.main(["--json", "--states", "3", "--modes", "0"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    keys = {"quantity", "chain", "states", "max_rel_error", "tolerance", "pass"}
    assert out["checks"] and all(keys <= set(r) for r in out["checks"])
    assert {r["chain"] for r in out["checks"]} == {"open", "closed"}


def test_main_exits_1_when_the_reference_disagrees(monkeypatch, capsys):
    """A reference whose mass matrix is off by 1e-9 (relative) fails exactly the
    mass_matrix rows, and `main` returns 1."""
    real = compare.default_reference

    def wrong_reference(params, n_modes):
        ref = real(params, n_modes)
        mm = ref.mass_matrix
        ref.mass_matrix = lambda q: mm(q) * (1 + 1e-9)
        return ref

    monkeypatch.setattr(compare, "default_reference", wrong_reference)
    rc = compare.main(["--states", "3", "--modes", "0"])
    table = capsys.readouterr().out
    assert rc == 1
    failing = [line.split()[:2] for line in table.splitlines() if " FAIL " in line]
    assert sorted(failing) == [["mass_matrix", "closed"], ["mass_matrix", "open"], ["mass_matrix", "open"]]

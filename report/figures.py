"""Figures of the report: observables against time, one line per engine, as inline PNG."""

from __future__ import annotations

import base64
import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rsmcheck.observables import BY_NAME  # noqa: E402
from rsmcheck.store import EngineRun  # noqa: E402

#: what a reader looks at first, per case (paper figure in the title where there is one)
PANELS = (
    ("base_pose_I", "base pose (x, y [m], θ_B [rad])"),
    ("joint_angles", "joint angles θ_J [rad]"),
    ("motor_torques", "motor torques τ_m [N·m] (Fig. 14)"),
    ("link_deflection", "mid-span deflection [m] (Fig. 15)"),
    ("ee2_speed", "end-effector 2 speed [m/s] (Fig. 6)"),
    ("target_attitude", "target attitude θ_T [rad] (Fig. 9)"),
    ("capture_gap_B", "capture gap [m] (Fig. 10)"),
    ("com_pos_B", "system COM in base frame [m] (Fig. 12)"),
    ("reaction_forces_I", "grasp reaction forces R_cl [N] (Fig. 4)"),
    ("constraint_residual", "constraint residual φ_T [m]"),
    ("energy", "energy: kinetic, elastic, gravitational [J]"),
    ("momentum_I", "momentum p_x, p_y [N·s], L_z [N·m·s]"),
)
_STYLES = {"reference": "-", "exudyn": "--"}


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def case_figure(runs: dict[str, EngineRun]) -> str:
    """A grid of the PANELS for one case, every engine overlaid; base64 PNG."""
    fig, axes = plt.subplots(4, 3, figsize=(15, 13))
    for ax, (name, title) in zip(axes.flat, PANELS):
        for engine, run in runs.items():
            t = run.observables["time"]
            y = np.asarray(run.observables[name]).reshape(len(t), -1)
            for c in range(y.shape[1]):
                ax.plot(t, y[:, c], _STYLES.get(engine, ":"), color=f"C{c}", lw=1.0,
                        label=f"{engine} [{c}]" if y.shape[1] > 1 else engine)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("t [s]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        if BY_NAME[name].size <= 3 or len(runs) > 1:
            ax.legend(fontsize=6, loc="best")
    fig.tight_layout()
    return _png(fig)


def conservation_figure(runs: dict[str, EngineRun]) -> str:
    """Drift of total energy and of momentum from t = 0 (absolute, SI), log scale."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 3.2))
    for engine, run in runs.items():
        t = run.observables["time"]
        e = run.observables["energy"].sum(axis=1)
        axes[0].semilogy(t[1:], np.abs(e[1:] - e[0]) + 1e-300, _STYLES.get(engine, ":"), label=engine)
        p = run.observables["momentum_I"]
        axes[1].semilogy(t[1:], np.max(np.abs(p[1:] - p[0]), axis=1) + 1e-300,
                         _STYLES.get(engine, ":"), label=engine)
    axes[0].set_title("|E(t) − E(0)| [J] (damping, control and orbit make it move)", fontsize=9)
    axes[1].set_title("max |p(t) − p(0)| [N·s, N·m·s] (external loads make it move)", fontsize=9)
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
        ax.set_xlabel("t [s]", fontsize=8)
    fig.tight_layout()
    return _png(fig)

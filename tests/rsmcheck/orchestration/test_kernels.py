"""Compiling the kernels once (rsmcheck.orchestration.kernels, `rsmcheck compile`): the
groups each engine declares, one job per group, the marker that makes a second call free,
and the one-line errors for a malformed declaration.  The session's own warm-up
(tests/conftest.py) runs the real groups on every fresh tree."""

from __future__ import annotations

import subprocess
import sys

import pytest

from rsmcheck.core import plugins as reg
from rsmcheck.core.errors import InputError
from rsmcheck.orchestration import kernels
from rsmcheck.orchestration.runs import Outcome


def test_each_compiling_engine_declares_groups_of_its_own_options():
    for name in ("reference", "exudyn"):
        groups = reg.kernel_runs(name)
        assert groups, name
        for group in groups:
            for case, options in group:
                assert set(options) <= set(reg.plugin(name).engine_options), (name, case, options)
    assert reg.kernel_runs("pinocchio") == ()
    # the reference's implicit integrators compile beside the explicit pair, not after it
    assert {o.get("integrator", "dopri5") for g in reg.kernel_runs("reference")[1:] for _, o in g} >= {"trbdf2",
                                                                                                       "imex"}


def test_a_group_with_an_option_the_engine_does_not_take_is_one_line(monkeypatch):
    ref = reg.plugin("reference")
    monkeypatch.setattr(type(ref), "kernel_runs", ((("free_drift", {"tolerance": 1.0}),),), raising=False)
    with pytest.raises(InputError, match=r"plug-in reference: kernel_runs\[0\]: free_drift: options tolerance"):
        reg.kernel_runs("reference")
    monkeypatch.setattr(type(ref), "kernel_runs", (("free_drift",),), raising=False)
    with pytest.raises(InputError, match=r"kernel_runs\[0\]: must be a sequence of \(case, options\)"):
        reg.kernel_runs("reference")


@pytest.fixture
def cache(monkeypatch, tmp_path):
    """An empty kernel-cache folder, and run_jobs recorded instead of run: (jobs ran, folder)."""
    ran: list = []
    monkeypatch.setattr(kernels.jit, "cache_dir", lambda: tmp_path / "kernels")

    def fake_run_jobs(jobs, progress=None, workers=2):
        ran.extend(jobs)
        return {job: Outcome(len(job.args[1]), None, 0.5) for job in jobs}

    monkeypatch.setattr(kernels, "run_jobs", fake_run_jobs)
    return ran, tmp_path / "kernels"


def test_one_job_per_group_then_a_marker_that_makes_the_next_call_free(cache):
    ran, folder = cache
    walls = kernels.compile_kernels(["reference", "exudyn"], again=False)
    n_groups = len(reg.kernel_runs("reference")) + len(reg.kernel_runs("exudyn"))
    assert len(ran) == len(walls) == n_groups
    assert all(job.fn is kernels._compile_group for job in ran)
    assert kernels.compiled("reference") and kernels.compiled("exudyn")
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        f".compiled-{job.key[0]}-{job.key[1]}" for job in ran)
    ran.clear()
    assert kernels.compile_kernels(["reference", "exudyn"], again=False) == {} and ran == []
    assert len(kernels.compile_kernels(["exudyn"])) == len(reg.kernel_runs("exudyn"))  # again=True: runs


def test_the_first_group_alone_then_the_rest_on_request(cache):
    """groups=1 (the test session's choice): what the cases' default settings reach; the
    implicit integrators' group is compiled by a later call, the first is not redone."""
    ran, folder = cache
    kernels.compile_kernels(["reference"], groups=1, again=False)
    assert [job.key for job in ran] == [("reference", 1)]
    assert kernels.compiled("reference", groups=1) and not kernels.compiled("reference")
    ran.clear()
    kernels.compile_kernels(["reference"], again=False)
    assert [job.key[1] for job in ran] == list(range(2, len(reg.kernel_runs("reference")) + 1))
    assert kernels.compiled("reference")


def test_the_first_group_flies_every_case_on_its_default_integrator():
    """The first group is what every case runs on: no non-default integrator in it."""
    for name in ("reference", "exudyn"):
        first = reg.kernel_runs(name)[0]
        assert all("integrator" not in options for _, options in first), (name, first)


def test_a_group_that_fails_raises_its_error_and_marks_nothing(cache, monkeypatch):
    ran, folder = cache
    boom = RuntimeError("kernel did not compile")
    monkeypatch.setattr(kernels, "run_jobs", lambda jobs, progress=None, workers=2: {
        job: Outcome(None, boom, 0.1) for job in jobs})
    with pytest.raises(RuntimeError, match="kernel did not compile"):
        kernels.compile_kernels(["exudyn"])
    assert not kernels.compiled("exudyn") and not any(folder.glob(".compiled-*"))


def test_a_group_runs_its_cases_in_this_process_for_a_few_samples(monkeypatch):
    flown = []
    monkeypatch.setattr(kernels, "run_engine", lambda engine, case, options: flown.append(
        (engine, case.name, case.duration, options)))
    assert kernels._compile_group("exudyn", (("free_drift", {}), ("capture", {"n_elements": 2}))) == 2
    assert flown == [("exudyn", "free_drift", kernels.RUN_S, {}), ("exudyn", "capture", kernels.RUN_S,
                                                                     {"n_elements": 2})]


def test_the_command_names_an_unknown_engine_in_one_line():
    proc = subprocess.run([sys.executable, "-m", "rsmcheck.cli", "compile", "--engines", "nosuch"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()] and "nosuch" in proc.stderr

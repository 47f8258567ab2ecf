"""HDF5 run files: round trip, atomic writes, and what the reader rejects."""

from __future__ import annotations

import datetime as dt
import os
import platform
import shutil
import subprocess

import h5py
import numpy as np
import pytest

from rsmcheck.core import store
from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import NAMES, OBSERVABLES
from rsmcheck.core.store import EngineRun, Event, Phase, read_run, write_run


def make_run(engine: str, n: int = 20, seed: int = 0) -> EngineRun:
    rng = np.random.default_rng(seed)
    obs = {spec.name: rng.normal(size=(n, *spec.shape)) for spec in OBSERVABLES}
    obs["time"] = np.linspace(0.0, 2.0, n)
    obs["grasp_state"] = rng.integers(0, 2, size=(n, 2)).astype(float)
    return EngineRun(
        engine=engine,
        observables=obs,
        events=[Event(0.5, "capture", "arm 1, gap 1.2 mm"),
                Event(1.5, "bistop", "wrist 2 contact θ = 0.5 rad")],
        phases=[Phase("approach", 0.0, 0.5), Phase("grasped", 0.5, 2.0)],
        solver={"method": "RK45", "rtol": 1e-9, "max_step": 0.001, "steps": 1234},
        versions={"numpy": np.__version__, engine: "1.2.3"},
    )


def write(path, runs, **kw):
    args = dict(case_name="free_drift", case_hash="c" * 64, param_hash="p" * 64)
    args.update(kw)
    return write_run(path, runs, **args)


def test_round_trip(tmp_path):
    path = tmp_path / "free_drift.h5"
    runs = {"reference": make_run("reference", seed=1), "exudyn": make_run("exudyn", seed=2)}
    before = dt.datetime.now(dt.timezone.utc).replace(microsecond=0)
    out = write(path, runs, extra_attrs={"short": True, "duration": 2.0})
    assert out == path and path.exists()
    assert not (tmp_path / "free_drift.h5.tmp").exists()

    back, attrs = read_run(path)
    assert set(back) == {"reference", "exudyn"}
    for name, run in runs.items():
        got = back[name]
        assert got.engine == name
        assert set(got.observables) == set(NAMES)
        for obs in NAMES:
            np.testing.assert_array_equal(got.observables[obs], run.observables[obs], err_msg=obs)
            assert got.observables[obs].dtype == np.float64
        assert got.events == run.events
        assert got.phases == run.phases
        assert got.solver == run.solver
        assert type(got.solver["steps"]) is int and type(got.solver["method"]) is str
        assert got.versions == run.versions

    assert attrs["case_name"] == "free_drift"
    assert attrs["case_hash"] == "c" * 64
    assert attrs["param_hash"] == "p" * 64
    assert attrs["format"] == store.FORMAT
    assert attrs["short"] is True and attrs["duration"] == 2.0
    assert attrs["engines"] == "reference,exudyn"
    assert isinstance(attrs["git_commit"], str) and attrs["git_commit"]
    assert attrs["version.h5py"] == h5py.__version__
    created = dt.datetime.fromisoformat(attrs["created_utc"])
    assert created.utcoffset() == dt.timedelta(0)
    assert before <= created <= dt.datetime.now(dt.timezone.utc)


def test_layout_groups_datasets_and_attrs(tmp_path):
    path = write(tmp_path / "x.h5", {"reference": make_run("reference")})
    with h5py.File(path, "r") as f:
        g = f["reference"]
        assert g.attrs["engine"] == "reference"
        assert g.attrs["solver.rtol"] == 1e-9
        assert g.attrs["version.reference"] == "1.2.3"
        assert g["joint_angles"].shape == (20, 6)
        assert g["time"].shape == (20,)
        assert list(g["events/time"][()]) == [0.5, 1.5]
        assert list(g["events/kind"].asstr()[()]) == ["capture", "bistop"]
        assert list(g["phases/name"].asstr()[()]) == ["approach", "grasped"]


def test_empty_events_and_phases_round_trip(tmp_path):
    run = make_run("reference")
    run.events, run.phases, run.solver, run.versions = [], [], {}, {}
    back, _ = read_run(write(tmp_path / "x.h5", {"reference": run}))
    assert back["reference"].events == [] and back["reference"].phases == []
    assert back["reference"].solver == {} and back["reference"].versions == {}


def test_long_datasets_are_compressed(tmp_path):
    path = write(tmp_path / "x.h5", {"reference": make_run("reference", n=store.COMPRESS_ABOVE + 1),
                                     "exudyn": make_run("exudyn", n=50)})
    with h5py.File(path, "r") as f:
        assert f["reference/motor_angles"].compression == "gzip"
        assert f["exudyn/motor_angles"].compression is None


def test_missing_observable_is_named_and_nothing_written(tmp_path):
    run = make_run("reference")
    del run.observables["capture_gap_B"]
    path = tmp_path / "x.h5"
    with pytest.raises(ValueError, match=r"x\.h5:/reference: observable 'capture_gap_B': missing"):
        write(path, {"reference": run})
    assert list(tmp_path.iterdir()) == []


def test_invalid_observable_leaves_existing_file_untouched(tmp_path):
    path = write(tmp_path / "x.h5", {"reference": make_run("reference")})
    old = path.read_bytes()
    bad = make_run("reference")
    bad.observables["energy"][3, 0] = np.nan
    with pytest.raises(ValueError, match=r"'energy': non-finite"):
        write(path, {"reference": bad})
    assert path.read_bytes() == old
    assert not (tmp_path / "x.h5.tmp").exists()


@pytest.mark.parametrize("exc", [RuntimeError("disk full"), KeyboardInterrupt()])
def test_failure_mid_write_leaves_no_file(tmp_path, monkeypatch, exc):
    calls = []
    real = store._write_group

    def failing(f, name, run, compress=False):
        real(f, name, run, compress)  # the first group really lands in the temporary file
        calls.append(name)
        assert (tmp_path / "x.h5.tmp").exists()
        if len(calls) == 2:
            raise exc

    monkeypatch.setattr(store, "_write_group", failing)
    runs = {"reference": make_run("reference"), "exudyn": make_run("exudyn")}
    with pytest.raises(type(exc)):
        write(tmp_path / "x.h5", runs)
    assert calls == ["reference", "exudyn"]
    assert list(tmp_path.iterdir()) == []


def test_failure_mid_write_keeps_previous_file(tmp_path, monkeypatch):
    path = write(tmp_path / "x.h5", {"reference": make_run("reference", seed=5)})
    old = path.read_bytes()

    def failing(f, name, run, compress=False):
        raise OSError("simulated write error")

    monkeypatch.setattr(store, "_write_group", failing)
    with pytest.raises(OSError, match="simulated"):
        write(path, {"reference": make_run("reference", seed=6)})
    assert path.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5"]


def test_stale_temp_file_is_overwritten(tmp_path):
    (tmp_path / "x.h5.tmp").write_bytes(b"garbage from a killed run")
    path = write(tmp_path / "x.h5", {"reference": make_run("reference")})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5"]
    read_run(path)


def test_creates_output_directory(tmp_path):
    path = write(tmp_path / "out" / "sub" / "x.h5", {"reference": make_run("reference")})
    assert path.exists()


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda r: setattr(r, "engine", "exudyn"), r"differs from the run's engine"),
        (lambda r: r.events.append(Event(float("nan"), "capture", "")), r"events\[2\]"),
        (lambda r: r.events.append(Event(1.0, "", "")), r"non-empty kind"),
        (lambda r: r.phases.append(Phase("back", 2.0, 1.0)), r"phase 'back' has bad bounds"),
        (lambda r: r.solver.update(tol=[1, 2]), r"solver setting 'tol'"),
        (lambda r: r.versions.update(numpy=2), r"version of 'numpy'"),
    ],
)
def test_bad_run_metadata_rejected(tmp_path, mutate, message):
    run = make_run("reference")
    mutate(run)
    with pytest.raises(ValueError, match=message):
        write(tmp_path / "x.h5", {"reference": run})
    assert list(tmp_path.iterdir()) == []


def test_bad_root_attributes_rejected(tmp_path):
    runs = {"reference": make_run("reference")}
    with pytest.raises(ValueError, match="case_hash"):
        write(tmp_path / "x.h5", runs, case_hash="")
    with pytest.raises(ValueError, match="no engine runs"):
        write(tmp_path / "x.h5", {})
    with pytest.raises(ValueError, match="'git_commit' is reserved"):
        write(tmp_path / "x.h5", runs, extra_attrs={"git_commit": "x"})
    assert list(tmp_path.iterdir()) == []


def test_read_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_run(tmp_path / "nope.h5")


def test_read_rejects_non_hdf5_and_foreign_hdf5(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    with pytest.raises(InputError, match="not an HDF5 file"):
        read_run(junk)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = np.zeros(3)
    with pytest.raises(InputError, match="not an rsmcheck run file"):
        read_run(foreign)


def test_read_names_a_missing_dataset(tmp_path):
    path = write(tmp_path / "x.h5", {"reference": make_run("reference")})
    with h5py.File(path, "a") as f:
        del f["reference/com_pos_B"]
    with pytest.raises(InputError, match=r"reference: observables: observable 'com_pos_B': missing"):
        read_run(path)


def test_git_commit_unknown_outside_a_repository(tmp_path, monkeypatch):
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))
    assert store.git_commit(tmp_path) == ("unknown", "unknown")


@pytest.mark.skipif(shutil.which("git") is None, reason="git not installed")
def test_git_commit_of_a_repository(tmp_path):
    def git(*args):
        return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
                              cwd=tmp_path, check=True, capture_output=True, text=True).stdout

    git("init", "-q")
    assert store.git_commit(tmp_path) == ("unknown", "unknown")  # no commit yet
    (tmp_path / "a.txt").write_text("1")
    git("add", "a.txt")
    git("commit", "-q", "-m", "one")
    sha = git("rev-parse", "HEAD").strip()
    assert store.git_commit(tmp_path) == (sha, "no")
    (tmp_path / "goldens").mkdir()
    (tmp_path / "goldens" / "g.h5").write_text("1")
    git("add", "goldens/g.h5")
    git("commit", "-q", "-m", "golden")
    sha = git("rev-parse", "HEAD").strip()
    (tmp_path / "goldens" / "g.h5").write_text("2")  # a bless in progress: not the code
    assert store.git_commit(tmp_path) == (sha, "no")
    (tmp_path / "a.txt").write_text("2")
    assert store.git_commit(tmp_path) == (sha, "yes")
    # a folder inside the work tree (a package installed there) is not the work tree
    (tmp_path / "site").mkdir()
    assert store.git_commit(tmp_path / "site") == ("unknown", "unknown")


def test_package_versions():
    versions = store.package_versions("numpy", "surely-not-a-package-xyz")
    assert versions == {"numpy": np.__version__, "surely-not-a-package-xyz": "not installed"}


def test_machine_names_the_processor_its_cores_and_packages(tmp_path, monkeypatch):
    """The CPU is the first processor's block of /proc/cpuinfo with what tells a bare virtual
    model name apart; without the file, `platform.processor()`; the one-line text names the
    CPU, the cores and the packages, or says that a document has no record."""
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 25\nmodel\t\t: 17\n"
                    "model name\t: AMD EPYC\nstepping\t: 1\ncpu MHz\t\t: 2596.126\ncache size\t: 1024 KB\n\n"
                    "processor\t: 1\nmodel name\t: Other CPU\n")
    assert store._cpu(info) == ("AMD EPYC (family 25, model 17, stepping 1, cache 1024 KB)", 2596.126)
    monkeypatch.setattr(store.platform, "processor", lambda: "x86_64")
    assert store._cpu(tmp_path / "none") == ("x86_64", None)
    m = store.machine()
    assert m["logical_cpus"] == os.cpu_count() and m["python"] == platform.python_version()
    assert m["packages"]["numpy"] == np.__version__ and set(m["packages"]) >= {"numba", "exudyn", "pin"}
    text = store.machine_text(m)
    assert text.startswith(m["cpu"]) and f", {os.cpu_count()} logical CPUs, " in text
    assert f"numpy {np.__version__}" in text
    assert "not recorded" in store.machine_text(None) and "not recorded" in store.machine_text({})


def test_same_machine_is_the_same_processor_and_cores():
    a = {"cpu": "AMD EPYC (family 25, model 17)", "logical_cpus": 2, "memory_gib": 23.5}
    assert store.same_machine(a, dict(a, memory_gib=31.0, system="other kernel", cpu_mhz=3100.0))
    assert not store.same_machine(a, dict(a, cpu="Intel Xeon (family 6, model 85)"))
    assert not store.same_machine(a, dict(a, logical_cpus=4))
    assert not store.same_machine(a, None) and not store.same_machine(None, None)


def test_event_identity_keeps_words_and_integers_and_drops_measured_values():
    def ident(detail):
        return Event(0.0, "capture", detail).identity
    assert ident("arm=2 delta_rad=-5.95e-08 gap_m=0.0014") == "arm=2 delta_rad gap_m"
    assert ident("iteration=3 com_y=-4.1e-3 step=1e+00") == "iteration=3 com_y step"
    assert ident("approach") == "approach"
    assert ident("arm=1 segment=hold") == "arm=1 segment=hold"

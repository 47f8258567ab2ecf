"""HDF5 run files (docs/observables.md, "Run files").

A run file holds one group per engine (`/reference`, `/exudyn`).  Each group has one
dataset per observable of docs/observables.md (first axis = time sample, `time` included), the
events (`events/time`, `events/kind`, `events/detail`), the phase boundaries
(`phases/name`, `phases/t_start`, `phases/t_end`) and, as attributes, the engine name,
its package versions (`version.<package>`) and its solver settings (`solver.<key>`).
The root attributes carry the case name and case-file hash, the parameter hash, the git
commit of rsmcheck, the versions of Python/numpy/h5py and the UTC creation time.

Writing is atomic: the file is written as `<path>.tmp` in the same directory and renamed
over `<path>` only once complete; on any failure the temporary file is removed and an
existing `<path>` is left as it was.  `write_text` and `write_json` do the same for the
project's other result files (end states, studies, benchmarks, fault matrix, changelog).
`dumps_json` is the one JSON writer: strict JSON, NaN as null and ±inf as "inf"/"-inf".
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import platform
import subprocess
import tempfile
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any, Mapping

import h5py
import numpy as np

from rsmcheck.core.errors import InputError
from rsmcheck.core.observables import NAMES, check_observables
from rsmcheck.core.plugins import plugin_distributions

def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write `text` to `path` atomically (`<path>.tmp`, then renamed; removed on failure)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(str(path) + ".tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _writable_folder(path: Path, target: Path, field: str) -> None:
    """InputError unless the nearest existing folder at or above `path` is a directory this
    process can create entries in (`target`, the path the user gave, is named)."""
    at = path
    while not at.exists():
        if at.parent == at:
            break
        at = at.parent
    if not at.is_dir():
        raise InputError(str(target), field, f"{at} is not a directory")
    if not os.access(at, os.W_OK | os.X_OK):
        raise InputError(str(target), field, f"cannot write in {at} (permission denied)")
    # access() says yes to root everywhere and knows nothing of read-only or virtual file
    # systems (/proc): create and remove an empty folder there
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".rsmcheck-probe-", dir=at))
    except OSError as exc:
        raise InputError(str(target), field, f"cannot create anything in {at} ({exc.strerror or exc})") from None


def output_dir(value: str | os.PathLike[str], field: str = "--out") -> Path:
    """`value` as a folder a command may write its files into, checked before anything is
    run: InputError naming the path and `field` if it is an existing file, lies below a
    file, or cannot be written in.  Nothing is created."""
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise InputError(str(path), field, "exists and is not a directory (the files are written into a directory)")
    _writable_folder(path, path, field)
    return path


def output_file(value: str | os.PathLike[str], field: str = "--out") -> Path:
    """`value` as a file a command may write (atomically, `write_text`), checked before
    anything is run: InputError naming the path and `field` if it is an existing directory
    or its folder cannot be created or written in.  Nothing is created."""
    path = Path(value)
    if path.is_dir():
        raise InputError(str(path), field, "is a directory (a file name is expected)")
    _writable_folder(path.parent, path, field)
    return path


def json_number(x: float) -> float | str | None:
    """A float as strict JSON can hold it: NaN (nothing measured) → null, ±inf (e.g. an
    infinite margin: a zero error) → the strings "inf" / "-inf", any other value as is."""
    if math.isnan(x):
        return None
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return x


def json_safe(doc: Any) -> Any:
    """`doc` with every value strict JSON can hold: floats through `json_number`, numpy
    scalars and arrays as Python numbers and lists, tuples as lists, paths as strings;
    mappings and sequences walked."""
    if isinstance(doc, bool) or doc is None or isinstance(doc, (str, int)):
        return doc
    if isinstance(doc, float):
        return json_number(doc)
    if isinstance(doc, np.generic):
        return json_safe(doc.item())
    if isinstance(doc, np.ndarray):
        return json_safe(doc.tolist())
    if isinstance(doc, Mapping):
        return {k: json_safe(v) for k, v in doc.items()}
    if isinstance(doc, (list, tuple)):
        return [json_safe(v) for v in doc]
    if isinstance(doc, os.PathLike):
        return os.fspath(doc)
    return doc


def dumps_json(doc: Any, indent: int | None = 1) -> str:
    """`doc` as strict JSON (RFC 8259: no NaN or Infinity, which most parsers other than
    Python's refuse) — the one writer of every JSON document rsmcheck prints or stores."""
    return json.dumps(json_safe(doc), indent=indent, allow_nan=False, default=_json_default)


def _json_default(value: Any) -> Any:
    """Anything else that is a number (a Decimal, a 0-d array-like) as a float."""
    return json_number(float(value))


def write_json(path: str | os.PathLike[str], doc: Any) -> Path:
    """`doc` as indented strict JSON (`dumps_json`), atomically: a measurement that failed
    (NaN) is written as null, an infinite value as "inf"."""
    return write_text(path, dumps_json(doc))


FORMAT = "rsmcheck-run"
FORMAT_VERSION = 1
COMPRESS_ABOVE = 1000
"""Datasets with more samples than this are stored gzip-compressed."""

_SOLVER = "solver."
_VERSION = "version."
_RESERVED_ROOT = (
    "format", "format_version", "case_name", "case_hash", "param_hash",
    "git_commit", "git_dirty", "created_utc", "engines",
)
_STR = h5py.string_dtype("utf-8")


@dataclass(frozen=True)
class Event:
    """Something that happened at one instant (capture, release, bistop contact, ...)."""

    time: float
    kind: str
    detail: str = ""

    @property
    def identity(self) -> str:
        """The detail without its measured values: 'arm=2 gap_m=0.00139951' → 'arm=2
        gap_m'.  Which arm, which segment, which iteration (words and integers) identify an
        event; the real numbers it reports (gaps, speeds, residuals, energy lost) are
        results, printed to 6 digits, and round-off would flip their last digit: the
        observables carry the same physics with tolerances.  A measured value is written
        with a decimal point even when it is exactly zero ('residual_m=0.00000'), or it
        would read as an integer that identifies the event."""
        words = []
        for token in self.detail.split():
            key, sep, value = token.partition("=")
            if sep and not value.lstrip("+-").isdigit():
                try:
                    float(value)
                except ValueError:
                    pass
                else:
                    token = key
            words.append(token)
        return " ".join(words)


@dataclass(frozen=True)
class Phase:
    """A named interval of a case (mission phase, burn, coast, ...)."""

    name: str
    t_start: float
    t_end: float


@dataclass
class EngineRun:
    """Everything one engine produced for one case."""

    engine: str
    observables: dict[str, np.ndarray]
    events: list[Event] = field(default_factory=list)
    phases: list[Phase] = field(default_factory=list)
    solver: dict[str, float | int | str] = field(default_factory=dict)
    versions: dict[str, str] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------
# helpers shared by the engines
# ---------------------------------------------------------------------------------------
def package_versions(*names: str) -> dict[str, str]:
    """Installed versions of the distributions `names` ("not installed" if absent)."""
    out: dict[str, str] = {}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _cpu(cpuinfo: str | os.PathLike[str] = "/proc/cpuinfo") -> tuple[str, float | None]:
    """(processor, clock [MHz]).  The processor: on Linux the first processor's `model name`
    of /proc/cpuinfo with its family, model, stepping and cache (a virtual machine's model
    name can be as bare as "AMD EPYC": family 25 model 17 tells its generation), else what
    `platform.processor()` says, else "unknown".  The clock is apart: where the frequency
    scales it changes from one reading to the next on the same processor."""
    fields: dict[str, str] = {}
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as f:
            for line in f:
                if not line.strip():
                    break  # the end of the first processor's block
                key, sep, value = line.partition(":")
                if sep:
                    fields[key.strip()] = value.strip()
    except OSError:
        pass
    name = fields.get("model name") or platform.processor() or "unknown"
    details = [f"{label} {fields[key]}" for key, label in (("cpu family", "family"), ("model", "model"),
                                                             ("stepping", "stepping"), ("cache size", "cache"))
               if fields.get(key)]
    try:
        mhz = float(fields["cpu MHz"])
    except (KeyError, ValueError):
        mhz = None
    return (f"{name} ({', '.join(details)})" if details else name), mhz


def _memory_gib() -> float | None:
    """Physical memory [GiB] (POSIX sysconf), None where the system does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (AttributeError, OSError, ValueError):
        return None


def machine() -> dict[str, Any]:
    """The machine a speed measurement ran on (`rsmcheck bench`): wall times of the same
    code differ between two machines of one kind by tens of per cent (docs/benchmarks.md),
    so a stored figure names its CPU model, logical CPUs, memory [GiB], operating system,
    Python and the numerical packages the engines run on."""
    cpu, mhz = _cpu()
    return {"cpu": cpu, "cpu_mhz": mhz, "logical_cpus": os.cpu_count(), "memory_gib": _memory_gib(),
            "system": platform.platform(), "python": platform.python_version(),
            "packages": package_versions("numpy", "scipy", "numba", *plugin_distributions())}


def machine_text(m: Mapping[str, Any] | None) -> str:
    """One line for people: "AMD EPYC (family 25, model 17, stepping 1, cache 1024 KB) at
    2596 MHz, 2 logical CPUs, 23.5 GiB, Linux-…, Python 3.11.7 (numpy 2.4.6, …)"; for a
    document without the record, says so."""
    if not m:
        return "machine not recorded (a document older than the record)"
    mem = m.get("memory_gib")
    packages = ", ".join(f"{k} {v}" for k, v in (m.get("packages") or {}).items())
    mhz = m.get("cpu_mhz")
    return (f"{m.get('cpu', 'unknown')}" + (f" at {mhz:.0f} MHz" if isinstance(mhz, (int, float)) else "")
            + f", {m.get('logical_cpus', '?')} logical CPUs, "
            + (f"{mem:.1f} GiB" if isinstance(mem, (int, float)) else "memory unknown")
            + f", {m.get('system', '?')}, Python {m.get('python', '?')}" + (f" ({packages})" if packages else ""))


def same_machine(a: Mapping[str, Any] | None, b: Mapping[str, Any] | None) -> bool:
    """Whether two `machine()` records name the same kind of processor (CPU model with its
    family, model, stepping and cache, and logical CPUs; not the clock, which may scale):
    only then can two documents' wall times compare.  An unrecorded machine is the same as
    none."""
    return bool(a) and bool(b) and all(a.get(k) == b.get(k) for k in ("cpu", "logical_cpus"))


def git_commit(repo: str | os.PathLike[str] | None = None) -> tuple[str, str]:
    """(commit, dirty) of the git work tree holding rsmcheck's sources.

    `commit` is `git rev-parse HEAD` or "unknown" (no git, no repository, no commit
    yet); `dirty` is "yes"/"no" for tracked files modified relative to HEAD, or
    "unknown".  The goldens (`goldens/`) do not count: they are what `bless` writes, no
    run reads them, and a bless of several cases would otherwise record its own first
    goldens as uncommitted changes of the code.

    Only a work tree's top folder counts (`.git` in it): a package installed into a
    folder that lies inside some other repository (a virtual environment in a project)
    is "unknown", not that repository's commit.
    """
    cwd = Path(repo) if repo is not None else Path(__file__).resolve().parents[2]
    if not (cwd / ".git").exists():
        return "unknown", "unknown"
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--verify", "--quiet", "HEAD"],
            cwd=cwd, capture_output=True, text=True, timeout=10, check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown", "unknown"
    commit = head.stdout.strip()
    if head.returncode != 0 or not commit:
        return "unknown", "unknown"
    try:
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)goldens"],
            cwd=cwd, capture_output=True, text=True, timeout=30, check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return commit, "unknown"
    if status.returncode != 0:
        return commit, "unknown"
    return commit, "yes" if status.stdout.strip() else "no"


# ---------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------
def write_run(
    path: str | os.PathLike[str],
    runs: Mapping[str, EngineRun],
    case_name: str,
    case_hash: str,
    param_hash: str,
    extra_attrs: Mapping[str, Any] | None = None,
    compress: bool = False,
) -> Path:
    """Write `runs` (group name -> run, the name being the run's engine) to `path`.

    Datasets longer than COMPRESS_ABOVE samples are gzip-compressed, all of them with
    `compress` (small files kept in the repository, rsmcheck.orchestration.gate).

    Everything is validated before anything is written: observables with
    `check_observables`, events and phases (finite times, t_end >= t_start), scalar
    attributes.  Raises ValueError on bad data; the file system is then untouched.
    Returns the final path.
    """
    path = Path(path)
    where = str(path)
    if not runs:
        raise ValueError(f"{where}: no engine runs to write")
    for key, value in (("case_name", case_name), ("case_hash", case_hash),
                       ("param_hash", param_hash)):
        if not isinstance(value, str) or not value:
            raise ValueError(f"{where}: {key} must be a non-empty string, got {value!r}")
    extra = dict(extra_attrs or {})
    for key, value in extra.items():
        if key in _RESERVED_ROOT or key.startswith(_VERSION):
            raise ValueError(f"{where}: extra attribute '{key}' is reserved")
        _check_scalar(value, f"{where}: extra attribute '{key}'")
    for name, run in runs.items():
        _validate_run(name, run, f"{where}:/{name}")

    commit, dirty = git_commit()
    root_attrs: dict[str, Any] = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "case_name": case_name,
        "case_hash": case_hash,
        "param_hash": param_hash,
        "git_commit": commit,
        "git_dirty": dirty,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "engines": ",".join(runs),
        _VERSION + "python": platform.python_version(),
        **{_VERSION + k: v for k, v in package_versions("rsmcheck", "numpy", "h5py").items()},
        **extra,
    }

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(str(path) + ".tmp")
    try:
        # the newest file format has far more compact metadata (a 100-sample run: 49 kB
        # instead of 117 kB), worth it for the small files kept in the repository
        with h5py.File(tmp, "w", libver="latest" if compress else "earliest") as f:
            for key, value in root_attrs.items():
                f.attrs[key] = value
            for name, run in runs.items():
                _write_group(f, name, run, compress)
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        raise
    return path


def _check_scalar(value: Any, what: str) -> None:
    if isinstance(value, (bool, np.bool_)):
        return
    if isinstance(value, str):
        return
    if isinstance(value, (int, float, np.integer, np.floating)):
        return
    raise ValueError(f"{what}: must be a number, bool or string, got {type(value).__name__}")


def _validate_run(name: str, run: EngineRun, where: str) -> None:
    if not isinstance(run, EngineRun):
        raise ValueError(f"{where}: expected an EngineRun, got {type(run).__name__}")
    if not name or "/" in name or name in (".", ".."):
        raise ValueError(f"{where}: '{name}' is not a valid group name")
    if run.engine != name:
        raise ValueError(f"{where}: group name '{name}' differs from the run's engine "
                         f"'{run.engine}'")
    check_observables(run.observables, where)
    for i, ev in enumerate(run.events):
        if not isinstance(ev, Event):
            raise ValueError(f"{where}: events[{i}] is not an Event")
        if not np.isfinite(ev.time):
            raise ValueError(f"{where}: events[{i}] ({ev.kind}) has time {ev.time}")
        if not isinstance(ev.kind, str) or not ev.kind or not isinstance(ev.detail, str):
            raise ValueError(f"{where}: events[{i}] needs a non-empty kind and a string detail")
    for i, ph in enumerate(run.phases):
        if not isinstance(ph, Phase):
            raise ValueError(f"{where}: phases[{i}] is not a Phase")
        if not isinstance(ph.name, str) or not ph.name:
            raise ValueError(f"{where}: phases[{i}] needs a non-empty name")
        if not (np.isfinite(ph.t_start) and np.isfinite(ph.t_end)) or ph.t_end < ph.t_start:
            raise ValueError(f"{where}: phase '{ph.name}' has bad bounds "
                             f"[{ph.t_start}, {ph.t_end}]")
    for key, value in run.solver.items():
        _check_scalar(value, f"{where}: solver setting '{key}'")
    for key, value in run.versions.items():
        if not isinstance(value, str):
            raise ValueError(f"{where}: version of '{key}' must be a string, got {value!r}")


def _write_group(f: h5py.File, name: str, run: EngineRun, compress: bool = False) -> None:
    g = f.create_group(name)
    g.attrs["engine"] = run.engine
    for key, value in run.versions.items():
        g.attrs[_VERSION + key] = value
    for key, value in run.solver.items():
        g.attrs[_SOLVER + key] = value
    n = None
    for obs in NAMES:
        data = np.asarray(run.observables[obs], dtype=np.float64)
        n = data.shape[0]
        kwargs: dict[str, Any] = {}
        if compress or n > COMPRESS_ABOVE:
            kwargs = {"compression": "gzip", "compression_opts": 9 if compress else 4, "shuffle": True}
        g.create_dataset(obs, data=data, **kwargs)
    g.attrs["n_samples"] = n
    ev = g.create_group("events")
    ev.create_dataset("time", data=np.array([e.time for e in run.events], dtype=np.float64))
    ev.create_dataset("kind", data=[e.kind for e in run.events], dtype=_STR)
    ev.create_dataset("detail", data=[e.detail for e in run.events], dtype=_STR)
    ph = g.create_group("phases")
    ph.create_dataset("name", data=[p.name for p in run.phases], dtype=_STR)
    ph.create_dataset("t_start", data=np.array([p.t_start for p in run.phases], dtype=np.float64))
    ph.create_dataset("t_end", data=np.array([p.t_end for p in run.phases], dtype=np.float64))


# ---------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------
def read_run(path: str | os.PathLike[str]) -> tuple[dict[str, EngineRun], dict[str, Any]]:
    """Read a run file: (group name -> EngineRun, root attributes as Python values).

    Raises FileNotFoundError if `path` does not exist and `InputError` (a ValueError)
    if it is not a well-formed rsmcheck run file.
    """
    path = Path(path)
    where = str(path)
    if not path.exists():
        raise FileNotFoundError(f"{where}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(where, "file", f"not an HDF5 file ({exc})") from None
    with f:
        attrs = {key: _py(value) for key, value in f.attrs.items()}
        if attrs.get("format") != FORMAT:
            raise InputError(where, "format", f"not an rsmcheck run file "
                                              f"(format = {attrs.get('format')!r})")
        if attrs.get("format_version") != FORMAT_VERSION:
            raise InputError(where, "format_version",
                             f"{attrs.get('format_version')!r} is not supported "
                             f"(this rsmcheck reads {FORMAT_VERSION})")
        runs: dict[str, EngineRun] = {}
        for name, g in f.items():
            if not isinstance(g, h5py.Group):
                raise InputError(where, name, "expected an engine group")
            runs[name] = _read_group(g, f"{where}:/{name}")
    return runs, attrs


def _read_group(g: h5py.Group, where: str) -> EngineRun:
    observables: dict[str, np.ndarray] = {}
    for key, item in g.items():
        if key in ("events", "phases"):
            continue
        if not isinstance(item, h5py.Dataset):
            raise InputError(where, key, "expected a dataset")
        observables[key] = item[()]
    try:
        check_observables(observables, where)
    except ValueError as exc:
        raise InputError(where, "observables", str(exc).removeprefix(where + ": ")) from None
    try:
        ev, ph = g["events"], g["phases"]
        ev_time = ev["time"][()]
        ev_kind = ev["kind"].asstr()[()]
        ev_detail = ev["detail"].asstr()[()]
        ph_name = ph["name"].asstr()[()]
        ph_start = ph["t_start"][()]
        ph_end = ph["t_end"][()]
    except (KeyError, TypeError) as exc:
        raise InputError(where, "events/phases", f"missing or malformed ({exc})") from None
    if not (len(ev_time) == len(ev_kind) == len(ev_detail)):
        raise InputError(where, "events", "time, kind and detail differ in length")
    if not (len(ph_name) == len(ph_start) == len(ph_end)):
        raise InputError(where, "phases", "name, t_start and t_end differ in length")
    solver: dict[str, Any] = {}
    versions: dict[str, str] = {}
    for key, value in g.attrs.items():
        if key.startswith(_SOLVER):
            solver[key[len(_SOLVER):]] = _py(value)
        elif key.startswith(_VERSION):
            versions[key[len(_VERSION):]] = str(_py(value))
    return EngineRun(
        engine=str(_py(g.attrs.get("engine", g.name.lstrip("/")))),
        observables=observables,
        events=[Event(float(t), str(k), str(d)) for t, k, d in zip(ev_time, ev_kind, ev_detail)],
        phases=[Phase(str(n), float(a), float(b)) for n, a, b in zip(ph_name, ph_start, ph_end)],
        solver=solver,
        versions=versions,
    )


def _py(value: Any) -> Any:
    """An HDF5 attribute value as a plain Python value."""
    if isinstance(value, bytes):
        return value.decode("utf-8")
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value

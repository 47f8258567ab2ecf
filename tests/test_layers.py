"""The layers hold: the import graph of the project's own modules, read with `ast` from the
source tree (nothing is imported), has no cycle (imports inside functions included) and no
import that goes up a layer; the engines stay independent of each other, and nothing
outside them imports or names one.

Layers, lowest first, each a folder (README, Layout):

* floor — rsmcheck/core/: errors, parameters, the observable schema, run files, the engine
  protocol and the plug-in registry, orbit, trajectories, the case model and loader, plane
  geometry, analytic beam frequencies;
* driver — rsmcheck/driver/, shared by every engine: initial conditions, controllers, the
  runner;
* engines — the plug-in packages reference_model, exudyn_model, pinocchio_check, mujoco_model
  (independent of each other: only pinocchio_check's comparison module may read the
  reference model, which it checks);
* orchestration — rsmcheck/orchestration/: chaining, comparison, collection, the gate,
  studies, the benchmark, eigenfrequencies, closed-loop analysis, fault injection; it
  reaches the engines through the registry only;
* report — rsmcheck.report (the folder report/), rendering what orchestration stored;
* entry — the command line, which dispatches to all of the above.

An import inside a function (deferred: it runs when the function is called) counts for
the layers and the cycles.  Outside the engine packages the only deferred imports are the
few of the command line listed in DEFERRED_ALLOWED (measured start-up cost).  Every module
of the tree must be given a layer, so that a new module is placed on purpose.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: package name → folder (rsmcheck.report is installed from report/, pyproject's package-dir)
PACKAGES = {
    "rsmcheck": "rsmcheck",
    "rsmcheck.core": "rsmcheck/core",
    "rsmcheck.driver": "rsmcheck/driver",
    "rsmcheck.orchestration": "rsmcheck/orchestration",
    "rsmcheck.report": "report",
    "reference_model": "reference_model",
    "exudyn_model": "exudyn_model",
    "pinocchio_check": "pinocchio_check",
    "mujoco_model": "mujoco_model",
}

#: (layer, module patterns), lowest first; "pkg.*" is a package and every module of it
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("floor", ("rsmcheck", "rsmcheck.core.*")),
    ("driver", ("rsmcheck.driver.*",)),
    ("engines", ("reference_model.*", "exudyn_model.*", "pinocchio_check.*", "mujoco_model.*")),
    ("orchestration", ("rsmcheck.orchestration.*",)),  # the folder is the layer
    ("report", ("rsmcheck.report.*",)),
    ("entry", ("rsmcheck.cli",)),
]

#: the engines: each is independent of the others ...
ENGINES = ("reference_model", "exudyn_model", "pinocchio_check", "mujoco_model")
#: ... except these (importing module, imported engine)
ENGINE_EDGES_ALLOWED = {("pinocchio_check.compare", "reference_model")}
#: third-party engine libraries and the engine packages that own them; the floor and the
#: driver (shared by every engine) import none of them, an engine only its own
ENGINE_LIBRARIES = {"exudyn": "exudyn_model", "pinocchio": "pinocchio_check", "mujoco": "mujoco_model"}
#: deferred imports allowed outside the engine packages besides those of the engines
#: (importing module, imported module): the command line imports the modules that read
#: scipy, plotly and jinja2 only for the commands that need them — at the top they take
#: `rsmcheck --help` from 0.4 s to 1.0 s; the executor imports Dask only to run jobs
DEFERRED_ALLOWED = {("rsmcheck.cli", "rsmcheck.orchestration.collect"), ("rsmcheck.cli", "rsmcheck.report.build"),
                    ("rsmcheck.cli", "rsmcheck.orchestration.modes"),
                    # Dask: `import distributed` (and its dask.config) at the top adds ≈ 0.7 s
                    # to every command
                    ("rsmcheck.orchestration.executor", "distributed"),
                    ("rsmcheck.orchestration.executor", "dask")}
#: generic top-level names the project must not import (installed as rsmcheck.core.cases and
#: rsmcheck.report; cases/ holds only data)
GENERIC_NAMES = ("cases", "report")


@dataclass(frozen=True)
class Import:
    source: str  # importing module
    target: str  # imported module (a project module) or top-level name (anything else)
    line: int
    deferred: bool  # inside a function: runs when the function is called


# ---------------------------------------------------------------------------------------
# reading the tree
# ---------------------------------------------------------------------------------------
def project_modules(root: Path = ROOT) -> dict[str, Path]:
    """Module name → file, for every .py file of PACKAGES."""
    out = {}
    for pkg, folder in PACKAGES.items():
        for path in sorted((root / folder).glob("*.py")):
            out[pkg if path.stem == "__init__" else f"{pkg}.{path.stem}"] = path
    return out


def _resolve(name: str, modules: set[str]) -> str:
    """The project module `name` names, or the longest project module it lies in (a name
    imported from a module), or its top-level name when it is not the project's."""
    parts = name.split(".")
    for n in range(len(parts), 0, -1):
        candidate = ".".join(parts[:n])
        if candidate in modules:
            return candidate
    return parts[0]


def imports_of(module: str, source: str, modules: set[str]) -> list[Import]:
    """Every import statement of `source` (the text of `module`)."""
    tree = ast.parse(source)
    package = module if module in PACKAGES else module.rpartition(".")[0]
    found: list[Import] = []

    def visit(node: ast.AST, deferred: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = deferred or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                for alias in child.names:
                    found.append(Import(module, _resolve(alias.name, modules), child.lineno, deferred))
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:  # relative: from the importing module's package
                    up = package.split(".")
                    up = up[:len(up) - (child.level - 1)]
                    base = ".".join(up + ([base] if base else []))
                for alias in child.names:
                    target = _resolve(f"{base}.{alias.name}", modules)
                    if target not in modules:
                        target = _resolve(base, modules)
                    found.append(Import(module, target, child.lineno, deferred))
            visit(child, inner)

    visit(tree, False)
    return found


def import_graph(root: Path = ROOT) -> tuple[set[str], list[Import]]:
    """(project modules, every import of theirs)."""
    files = project_modules(root)
    modules = set(files)
    edges = [imp for name, path in files.items()
             for imp in imports_of(name, path.read_text(encoding="utf-8"), modules)]
    return modules, edges


# ---------------------------------------------------------------------------------------
# the rules
# ---------------------------------------------------------------------------------------
def layer_of(module: str, layers=LAYERS) -> int | None:
    """Index of the layer `module` belongs to (None: no layer names it)."""
    for i, (_, patterns) in enumerate(layers):
        for p in patterns:
            if module == p or (p.endswith(".*") and (module == p[:-2] or module.startswith(p[:-1]))):
                return i
    return None


def cycles(modules: set[str], edges: list[Import]) -> list[list[str]]:
    """The strongly connected components with more than one module, or a module importing
    itself, of the graph of `edges` between `modules` (Tarjan), each sorted."""
    succ: dict[str, set[str]] = {m: set() for m in modules}
    for e in edges:
        if e.source in modules and e.target in modules:
            succ[e.source].add(e.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def connect(v: str) -> None:  # recursion depth ≤ number of modules (≈ 50)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(succ[v]):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in succ[v]:
                out.append(sorted(component))

    for v in sorted(modules):
        if v not in index:
            connect(v)
    return sorted(out)


def upward_imports(edges: list[Import], layers=LAYERS) -> list[str]:
    """Imports from a module into a higher layer than its own."""
    bad = []
    for e in edges:
        i, j = layer_of(e.source, layers), layer_of(e.target, layers)
        if i is not None and j is not None and j > i:
            bad.append(f"{e.source}:{e.line} ({layers[i][0]}) imports {e.target} ({layers[j][0]})"
                       + (" inside a function" if e.deferred else ""))
    return bad


def deferred_outside_engines(edges: list[Import], allowed=DEFERRED_ALLOWED) -> list[str]:
    """Imports inside a function, in a module outside the engine packages, of anything but
    an engine package (or a pair of `allowed`): they belong at the top of the module."""
    return [f"{e.source}:{e.line} imports {e.target} inside a function" for e in edges
            if e.deferred and e.source.split(".")[0] not in ENGINES
            and e.target.split(".")[0] not in ENGINES and (e.source, e.target) not in allowed]


def engine_crossings(edges: list[Import]) -> list[str]:
    """Imports of one engine package (or of another engine's library) by another engine,
    and of an engine library by the shared floor or driver."""
    shared = {name for name, _ in LAYERS[:2]}
    bad = []
    for e in edges:
        src_pkg, tgt_pkg = e.source.split(".")[0], e.target.split(".")[0]
        if src_pkg in ENGINES and tgt_pkg in ENGINES and src_pkg != tgt_pkg \
                and (e.source, tgt_pkg) not in ENGINE_EDGES_ALLOWED:
            bad.append(f"{e.source}:{e.line} imports the engine {e.target}")
        owner = ENGINE_LIBRARIES.get(tgt_pkg)
        if owner is not None:
            layer = layer_of(e.source)
            if (src_pkg in ENGINES and src_pkg != owner) or (layer is not None and LAYERS[layer][0] in shared):
                bad.append(f"{e.source}:{e.line} imports {tgt_pkg}, {owner}'s library")
    return bad


# ---------------------------------------------------------------------------------------
# the tests
# ---------------------------------------------------------------------------------------
def test_every_module_has_a_layer():
    modules, _ = import_graph()
    assert len(modules) > 40, f"only {len(modules)} modules found: not run from the repository?"
    missing = sorted(m for m in modules if layer_of(m) is None)
    assert not missing, f"modules with no layer (add them to LAYERS in {Path(__file__).name}): {missing}"


def test_the_orchestration_folder_is_the_orchestration_layer():
    """Every module under rsmcheck/orchestration/ is in the orchestration layer, and every
    module of rsmcheck in that layer lies in the folder: the folder shows the layer."""
    files = project_modules()
    folder = ROOT / PACKAGES["rsmcheck.orchestration"]
    in_folder = {m for m, path in files.items() if path.parent == folder}
    assert "rsmcheck.orchestration.compare" in in_folder, f"{folder} not found or empty"
    orchestration = next(i for i, (name, _) in enumerate(LAYERS) if name == "orchestration")
    in_layer = {m for m in files if m.split(".")[0] == "rsmcheck" and layer_of(m) == orchestration}
    assert in_layer == in_folder, (f"in the folder, not the layer: {sorted(in_folder - in_layer)}; "
                                   f"in the layer, not the folder: {sorted(in_layer - in_folder)}")


def test_no_import_cycle_among_module_level_imports():
    modules, edges = import_graph()
    found = cycles(modules, [e for e in edges if not e.deferred])
    assert not found, "import cycles (module-level imports): " + "; ".join(" ↔ ".join(c) for c in found)


def test_no_import_cycle_through_deferred_imports():
    """A function-level import that closes a cycle is a cycle too: it runs whenever the
    function is called, and it hides which module depends on which."""
    modules, edges = import_graph()
    found = cycles(modules, edges)
    lines = []
    for c in found:
        closing = [f"{e.source}:{e.line} → {e.target}" for e in edges
                   if e.deferred and e.source in c and e.target in c]
        lines.append(f"{' ↔ '.join(c)} (deferred: {', '.join(closing) or 'none'})")
    assert not found, "import cycles:\n" + "\n".join(lines)


def test_no_module_outside_the_engines_imports_or_names_one():
    """The driver, the orchestration, the report and the command line reach the engines only
    through the plug-in registry (rsmcheck.core.plugins): none imports an engine package or
    its library, and no string in their code (docstrings aside) is a registered engine's
    name; the engines a cross-check compares by default are data (rsmcheck/core/defaults.toml)."""
    from rsmcheck.core.plugins import plugins

    names = set(plugins())
    packages = {type(p).__module__.split(".")[0] for p in plugins().values()} | set(ENGINE_LIBRARIES)
    assert {"reference", "exudyn"} <= names, f"the registry lists {sorted(names)}: is the project installed?"
    bad = []
    for module, path in project_modules().items():
        if module.split(".")[0] in packages:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                      if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                      and n.body and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names \
                    and id(node) not in docstrings:
                bad.append(f"{module}:{node.lineno} names the engine {node.value!r}")
            imported = ([a.name for a in node.names] if isinstance(node, ast.Import)
                        else [node.module] if isinstance(node, ast.ImportFrom) and node.module and not node.level else [])
            bad += [f"{module}:{node.lineno} imports {n}" for n in imported if n.split(".")[0] in packages]
    assert not bad, "\n".join(bad)


def test_no_source_file_over_700_lines():
    """Small modules with one job: no file of the package or the engines over 700 lines."""
    long = {m: n for m, path in project_modules().items()
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > 700}
    assert not long, f"files over 700 lines: {long}"


def test_imports_outside_the_engines_are_at_the_top():
    """Outside the engine packages, a function imports only an engine package (lazily:
    heavy and optional) or what DEFERRED_ALLOWED lists."""
    _, edges = import_graph()
    bad = deferred_outside_engines(edges)
    assert not bad, "imports inside functions (move them to the top of the module):\n" + "\n".join(bad)
    # every allowed one is real (else the exception is stale: remove it)
    for source, target in DEFERRED_ALLOWED:
        assert any(e.deferred and (e.source, e.target) == (source, target) for e in edges), (source, target)


def test_no_import_goes_up_a_layer():
    _, edges = import_graph()
    bad = upward_imports(edges)
    assert not bad, "imports into a higher layer:\n" + "\n".join(bad)


def test_the_engines_are_independent():
    _, edges = import_graph()
    bad = engine_crossings(edges)
    assert not bad, "\n".join(bad)
    # the allowed crossing is real (else the exception is stale: remove it)
    for source, engine in ENGINE_EDGES_ALLOWED:
        assert any(e.source == source and e.target.split(".")[0] == engine for e in edges), (source, engine)


def test_no_generic_top_level_names():
    """Neither the source nor the tests import `cases` or `report` as top-level packages,
    and cases/ holds no Python."""
    files = list(project_modules().values()) + sorted((ROOT / "tests").rglob("*.py"))
    bad = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            bad += [f"{path.relative_to(ROOT)}:{node.lineno}: {n}" for n in names if n.split(".")[0] in GENERIC_NAMES]
    assert not bad, "imports of generic top-level names:\n" + "\n".join(bad)
    assert not list((ROOT / "cases").glob("*.py"))


# ---------------------------------------------------------------------------------------
# the checks can fail: a synthetic tree with a cycle, an upward import and an engine crossing
# ---------------------------------------------------------------------------------------
def test_the_checks_catch_a_cycle_an_upward_import_and_an_engine_crossing():
    sources = {
        "rsmcheck.core.params": "from rsmcheck.driver.runner import run\n",  # floor → driver: upward
        "rsmcheck.driver.runner": "import numpy\nfrom rsmcheck.core import params\n",  # closes a cycle
        "rsmcheck.orchestration.compare": "def f():\n    from rsmcheck.orchestration.gate import g\n",  # deferred
        "rsmcheck.orchestration.gate": "from rsmcheck.orchestration.compare import f\n",  # cycle: listed only
        "exudyn_model.engine": "from reference_model.build import M\n",  # engine → engine
        "reference_model.build": "import exudyn\n",  # another engine's library
        "pinocchio_check.compare": "from reference_model.build import M\n",  # allowed
    }
    modules = set(sources)
    edges = [imp for m, text in sources.items() for imp in imports_of(m, text, modules)]
    assert Import("rsmcheck.driver.runner", "numpy", 1, False) in edges
    assert Import("rsmcheck.driver.runner", "rsmcheck.core.params", 2, False) in edges  # `from pkg import module`
    assert Import("rsmcheck.orchestration.compare", "rsmcheck.orchestration.gate", 2, True) in edges

    assert cycles(modules, [e for e in edges if not e.deferred]) == [["rsmcheck.core.params", "rsmcheck.driver.runner"]]
    assert cycles(modules, edges) == [["rsmcheck.core.params", "rsmcheck.driver.runner"],
                                      ["rsmcheck.orchestration.compare", "rsmcheck.orchestration.gate"]]
    assert cycles({"a"}, [Import("a", "a", 1, False)]) == [["a"]]

    up = upward_imports(edges)
    assert len(up) == 1 and up[0].startswith("rsmcheck.core.params:1 (floor) imports rsmcheck.driver.runner (driver)")

    deferred = deferred_outside_engines(edges + imports_of("exudyn_model.engine", "def f():\n    import exudyn\n",
                                                          modules), allowed=set())
    assert deferred == ["rsmcheck.orchestration.compare:2 imports rsmcheck.orchestration.gate inside a function"]

    crossings = engine_crossings(edges)
    assert len(crossings) == 2
    assert crossings[0].startswith("exudyn_model.engine:1 imports the engine reference_model.build")
    assert crossings[1].startswith("reference_model.build:1 imports exudyn")

"""The layering of jaxdrift, checked on the source with ``ast`` (no import of jaxdrift needed).

Layers (a module may import only the layers listed for its own; ``errors`` is open to all):

    solvers   <- ensemble <- analysis <- diagnosis <- studies <- durability <- campaign <- cli
    models    <-------------'            io ---'          report (pages and summaries) <-'
    io (numpy only)

Rules: no import cycle between modules; no module over 650 lines; no function over 150 lines;
models import no engine (solvers, ensemble) and no matplotlib; nothing but ``cli`` imports ``cli``;
the report scorer used by the sweeps is not shipped in the library.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "jaxdrift"

MAX_MODULE_LINES = 650
MAX_FUNCTION_LINES = 150

# layer -> layers it may import (besides itself and ``errors``)
ALLOWED = {
    "errors": set(),
    "solvers": set(),
    "ensemble": {"solvers"},
    "models": set(),
    "io": set(),
    "analysis": {"models", "solvers", "ensemble"},
    "diagnosis": {"models", "analysis", "solvers", "ensemble", "io"},
    "studies": {"models", "analysis", "solvers", "ensemble", "io", "diagnosis"},
    # durability reuses the paper study's simulations (studies): it sits between studies and cli
    "durability": {"models", "analysis", "solvers", "ensemble", "io", "diagnosis", "studies"},
    # campaigns run the diagnosis and the durability of many runs on Dask: between durability and cli
    "campaign": {"models", "analysis", "solvers", "ensemble", "io", "diagnosis", "studies", "durability"},
    # the pages and terminal summaries of reports: read a report's JSON, plot (the vehicle preview
    # re-simulates through the diagnosis); only the command line uses them
    "report": {"models", "analysis", "solvers", "ensemble", "io", "diagnosis"},
    "cli": {"models", "analysis", "solvers", "ensemble", "io", "diagnosis", "studies", "durability", "campaign",
            "report"},
}
# third-party packages a layer must not import
FORBIDDEN_THIRD_PARTY = {
    "solvers": {"matplotlib", "scipy", "tqdm"},
    "models": {"matplotlib", "tqdm"},
    "io": {"jax", "equinox", "matplotlib"},
    "errors": {"jax", "numpy", "matplotlib"},
    "analysis": {"matplotlib"},
    "ensemble": {"matplotlib"},
}


#: layers that use the diagnosis through its public API only (no module whose name starts with _)
PUBLIC_API_ONLY = {"campaign", "durability", "cli", "studies", "report"}


def module_name(path: Path, root: Path = ROOT) -> str:
    rel = path.relative_to(root.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def layer_of(mod: str) -> str:
    parts = mod.split(".")
    if len(parts) == 1:
        return "top"  # jaxdrift/__init__.py: the lazy public surface
    name = parts[1]
    if name == "__main__":
        return "top"
    return name.lstrip("_") if name.lstrip("_") in ALLOWED else name


def _resolve(mod: str, is_pkg: bool, node: ast.ImportFrom) -> list[str]:
    if node.level == 0:
        base = node.module or ""
    else:
        pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
        pkg = pkg[: len(pkg) - (node.level - 1)]
        base = ".".join(pkg + ([node.module] if node.module else []))
    # ``from .pkg import name`` may import a submodule: keep both candidates
    return [base] + [f"{base}.{a.name}" for a in node.names]


def scan(root: Path = ROOT):
    """Return {module: (path, imports: set of dotted names, third-party top names)}."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        mod = module_name(path, root)
        tree = ast.parse(path.read_text(), filename=str(path))
        internal, external = set(), set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    (internal if a.name.split(".")[0] == "jaxdrift" else external).add(
                        a.name if a.name.startswith("jaxdrift") else a.name.split(".")[0])
            elif isinstance(node, ast.ImportFrom):
                names = _resolve(mod, path.name == "__init__.py", node)
                if names[0].split(".")[0] == "jaxdrift":
                    internal.update(names)
                else:
                    external.add(names[0].split(".")[0])
        out[mod] = (path, tree, internal, external)
    return out


def module_graph(mods) -> dict[str, set[str]]:
    known = set(mods)
    graph = {}
    for mod, (_, _, internal, _) in mods.items():
        graph[mod] = {m for m in internal if m in known and m != mod}
    return graph


def find_cycle(graph) -> list[str] | None:
    color, stack = {}, []

    def visit(u):
        color[u] = 1
        stack.append(u)
        for v in sorted(graph[u]):
            # a package __init__ re-exporting its own private modules is not a cycle with them
            if color.get(v) == 1:
                return stack[stack.index(v):] + [v]
            if v not in color:
                c = visit(v)
                if c:
                    return c
        stack.pop()
        color[u] = 2
        return None

    for u in sorted(graph):
        if u not in color:
            c = visit(u)
            if c:
                return c
    return None


def violations(root: Path = ROOT) -> list[str]:
    mods = scan(root)
    problems = []
    graph = module_graph(mods)
    cycle = find_cycle(graph)
    if cycle:
        problems.append("import cycle: " + " -> ".join(cycle))
    for mod, (path, tree, internal, external) in mods.items():
        n_lines = len(path.read_text().splitlines())
        if n_lines > MAX_MODULE_LINES:
            problems.append(f"{mod}: {n_lines} lines (max {MAX_MODULE_LINES})")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    problems.append(f"{mod}:{node.name}: {n} lines (max {MAX_FUNCTION_LINES})")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and node.name == "score_report":
                problems.append(f"{mod}: the test-only report scorer ships in the library")
        layer = layer_of(mod)
        if layer == "top":
            continue
        if layer not in ALLOWED:
            problems.append(f"{mod}: in no layer (a flat private module outside the subpackages)")
            continue
        for dep in sorted(graph[mod]):
            dl = layer_of(dep)
            if dl in (layer, "errors", "top") and dl != "top":
                continue
            if dl == "top" and layer == "cli" and dep == "jaxdrift":
                continue  # the CLI reads jaxdrift.__version__
            if dl == "top":
                problems.append(f"{mod} imports the top-level package {dep} (import the layer itself)")
            elif dl not in ALLOWED.get(layer, set()):
                problems.append(f"{mod} ({layer}) imports {dep} ({dl})")
        if layer in PUBLIC_API_ONLY:
            for dep in sorted(graph[mod]):
                if dep.startswith("jaxdrift.diagnosis.") and any(p.startswith("_") for p in dep.split(".")[2:]):
                    problems.append(f"{mod} ({layer}) imports the diagnosis's private module {dep} "
                                    "(import its public API, jaxdrift.diagnosis[.vehicle|.attitude])")
        for ext in sorted(external & FORBIDDEN_THIRD_PARTY.get(layer, set())):
            problems.append(f"{mod} ({layer}) imports {ext}")
    return problems


def test_layers_and_sizes():
    problems = violations()
    assert not problems, "architecture rules broken:\n" + "\n".join(problems)


def test_checker_catches_a_broken_tree(tmp_path):
    """The checker must be able to fail: a model importing the engine and a cycle are caught."""
    pkg = tmp_path / "jaxdrift"
    for sub in ("models", "solvers", "cli"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "models" / "_m.py").write_text("from ..solvers._s import f\nimport matplotlib\n")
    (pkg / "solvers" / "_s.py").write_text("from ._t import g\ndef f():\n    pass\n")
    (pkg / "solvers" / "_t.py").write_text("from ._s import f\nfrom ..cli import main\n"
                                           "def g():\n" + "    x = 1\n" * 160)
    (pkg / "diagnosis" / "vehicle").mkdir(parents=True)
    (pkg / "diagnosis" / "__init__.py").write_text("")
    (pkg / "diagnosis" / "vehicle" / "__init__.py").write_text("from ._causes import f as apply_causes\n")
    (pkg / "diagnosis" / "vehicle" / "_causes.py").write_text("def f():\n    pass\n")
    (pkg / "cli" / "_a.py").write_text("from ..diagnosis.vehicle._causes import f\nfrom ..diagnosis.vehicle import apply_causes\n")
    found = "\n".join(violations(pkg))
    assert "cli._a (cli) imports the diagnosis's private module jaxdrift.diagnosis.vehicle._causes" in found
    assert "imports the diagnosis's private module jaxdrift.diagnosis.vehicle (" not in found
    assert "models._m (models) imports jaxdrift.solvers._s (solvers)" in found
    assert "models._m (models) imports matplotlib" in found
    assert "import cycle" in found
    assert "solvers._t (solvers) imports jaxdrift.cli (cli)" in found
    assert "solvers._t:g: 161 lines" in found


@pytest.mark.parametrize("name", ["solve_ode", "monte_carlo", "HalfCarParams", "diagnose_vehicle_run",
                                  "run_attitude_diagnosis", "read_vehicle_run", "run_paper_study",
                                  "durability_analysis", "campaign"])
def test_public_names_resolve(name):
    import jaxdrift

    assert getattr(jaxdrift, name) is not None


def test_seed_table_points_at_real_code():
    """Every ``file:function`` in docs/explanation/architecture.md's seed table names a real top-level definition."""
    import re

    doc = (ROOT.parent / "docs" / "explanation" / "architecture.md").read_text()
    refs = re.findall(r"`(jaxdrift/[\w/]+\.py):(\w+)`", doc)
    assert len(refs) >= 30, "the seed table lost its entries"
    missing = []
    for path, name in refs:
        tree = ast.parse((ROOT.parent / path).read_text())
        defined = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
        defined |= {t.id for n in tree.body if isinstance(n, ast.Assign) for t in n.targets if isinstance(t, ast.Name)}
        if name not in defined:
            missing.append(f"{path}:{name}")
    assert not missing, f"docs/explanation/architecture.md names code that does not exist: {missing}"


# ----------------------------------------------------------------------------- no shared mutable state
#: Functions allowed to set attributes of an object they did not make, and why. Everything else in
#: jaxdrift/ that sets ``x.attr`` sets it on ``self`` (or ``cls``) or on an object it created in the
#: same function (``new = copy.copy(self); new.band = ...``).
MUTATION_ALLOWED = {
    # process-wide hooks, set once by the command line or the package itself
    "cli._common": "warnings.showwarning and the interrupt handler: the command line's process hooks",
    "campaign": "the package module's class (a callable package)",
}


def _functions(root: Path):
    """(module, function node) of every function in the package below ``root``."""
    for path in sorted(root.rglob("*.py")):
        mod = ".".join(path.relative_to(root).with_suffix("").parts)
        mod = mod[:-len(".__init__")] if mod.endswith(".__init__") else mod
        for fn in ast.walk(ast.parse(path.read_text())):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield mod, fn


def _fake_package(tmp_path, source: str) -> Path:
    """A package ``jaxdrift.diagnosis._x`` of ``source`` below ``tmp_path``: its root."""
    pkg = tmp_path / "jaxdrift" / "diagnosis"
    pkg.mkdir(parents=True)
    (pkg / "_x.py").write_text(source)
    return tmp_path / "jaxdrift"


def mutations(root: Path = ROOT) -> list[str]:
    """``module:line function: target`` for every assignment to an attribute of an object the
    function did not create (a parameter, an alias of another object, ``self.x.y``), and every
    ``setattr``/``object.__setattr__`` outside ``__post_init__``."""
    out = []
    for mod, fn in _functions(root):
        params = {a.arg for a in fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs}
        made = {t.id for node in ast.walk(fn) if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
                for t in node.targets if isinstance(t, ast.Name)} - params
        for node in ast.walk(fn):
            if isinstance(node, ast.Call) and isinstance(node.func, (ast.Name, ast.Attribute)) \
                    and ast.unparse(node.func) in ("setattr", "object.__setattr__") and fn.name != "__post_init__":
                out.append(f"{mod}:{node.lineno} {fn.name}: {ast.unparse(node)[:60]}")
            targets = node.targets if isinstance(node, ast.Assign) else \
                [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
            for t in targets:
                for tt in (t.elts if isinstance(t, ast.Tuple) else [t]):
                    if not isinstance(tt, ast.Attribute):
                        continue
                    base = tt.value
                    if isinstance(base, ast.Name) and (base.id in ("self", "cls") or base.id in made):
                        continue
                    out.append(f"{mod}:{tt.lineno} {fn.name}: {ast.unparse(tt)}")
    return out


def test_no_step_mutates_another_object():
    found = [m for m in mutations() if m.split(":")[0] not in MUTATION_ALLOWED]
    assert not found, "a function sets attributes of an object it did not create:\n" + "\n".join(found)


#: methods that change a list, dict or set in place
IN_PLACE = {"append", "extend", "insert", "update", "pop", "popitem", "setdefault", "sort", "clear", "remove",
            "add", "discard", "reverse"}

#: Functions allowed to change, item by item, a dict, list or array they were given, and why.
#: What is left is the vehicle side of #32 and the readers' assembly: each is named so that a new one
#: fails the test.
ITEM_MUTATION_ALLOWED = {
    # the vehicle diagnosis's selection log, one list that the selection steps append to
    **{f"diagnosis.vehicle._select:{f}": "the selection log (a list of lines) that the steps add to"
       for f in ("_swap_pass", "_refine", "_forward", "_backward", "_parsimony", "_exact_confounding",
                 "_tie_alternatives")},
    "diagnosis.vehicle._select:_screen": "the candidates' signature columns, cached across the forward steps",
    "diagnosis.vehicle._confirm:confirm_corrections": "the selection log",
    "diagnosis.vehicle._confirm:confirm_by_resimulation": "the selection log",
    "diagnosis.vehicle._confirm:confirm_below_body": "the selection log",
    "diagnosis.vehicle._pipeline:select_with_form": "the selection log",
    "diagnosis.vehicle._mode:find_mode": "the selection log",
    "diagnosis.vehicle._mode:resize_mode": "the selection log",
    "diagnosis.vehicle._mode:lowers_each": "the selection log",
    "campaign._campaign:_diagnose_all": "the campaign's log",
    "diagnosis.vehicle._adequacy:_named": "the extended model's nonlinear correction, filled finding by finding",
    "diagnosis.vehicle._residuals:_band_filter": "the residual channels filtered in their own dict",
    # the readers assemble one run from columns, file by file
    **{f"io._runs:{f}": "the reader's columns and notes, assembled file by file"
       for f in ("_spread_repeated", "_euler_reference", "_logger_faults", "_convert_units", "_time_base")},
    "io._ulog_fast:_walk_range": "the ULog scan's index arrays, filled while walking the file",
}


def _root_name(node):
    while isinstance(node, (ast.Attribute, ast.Subscript)):
        node = node.value
    return node.id if isinstance(node, ast.Name) else None


def item_mutations(root: Path = ROOT) -> list[str]:
    """``module:line function: target`` for every item assignment (``p[k] = v``, ``p[k] += v``,
    ``del p[k]``) and every in-place method call (``p.append(x)``, ``p.update(d)``, ...) on a
    parameter of the function, or on something reached from one (``p.x[k] = v``), where the
    function never rebinds that parameter (``p = dict(p)`` makes it its own)."""
    out = []
    for mod, fn in _functions(root):
        params = {a.arg for a in fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs} - {"self", "cls"}
        if fn.args.vararg is not None:
            params.add(fn.args.vararg.arg)
        rebound = set()
        for node in ast.walk(fn):
            tg = node.targets if isinstance(node, ast.Assign) else \
                [node.target] if isinstance(node, (ast.AnnAssign, ast.For)) else []
            for t in tg:
                for tt in (t.elts if isinstance(t, ast.Tuple) else [t]):
                    if isinstance(tt, ast.Name):
                        rebound.add(tt.id)
        given = params - rebound
        for node in ast.walk(fn):
            targets = node.targets if isinstance(node, (ast.Assign, ast.Delete)) else \
                [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
            for t in targets:
                for tt in (t.elts if isinstance(t, ast.Tuple) else [t]):
                    if isinstance(tt, ast.Subscript) and _root_name(tt) in given:
                        out.append(f"{mod}:{tt.lineno} {fn.name}: {ast.unparse(tt)}")
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                    and node.func.attr in IN_PLACE and _root_name(node.func.value) in given:
                out.append(f"{mod}:{node.lineno} {fn.name}: {ast.unparse(node)[:60]}")
    return out


def test_no_step_changes_what_it_was_given():
    """No function changes, item by item or by an in-place method, a dict, list or array it was
    given (a step returns a new record instead)."""
    found = [m for m in item_mutations() if m.split(" ")[0].rsplit(":", 1)[0] + ":" + m.split(" ")[1].rstrip(":")
             not in ITEM_MUTATION_ALLOWED]
    assert not found, "a function changes what it was given:\n" + "\n".join(found)


def test_item_mutation_checker_can_fail(tmp_path):
    root = _fake_package(tmp_path, "def fill(report):\n    report['x'] = 1\n"
                                   "def grow(findings, f):\n    findings.append(f)\n"
                                   "def deep(s):\n    s.notes[0] += 'x'\n"
                                   "def own(run):\n    run = dict(run)\n    run['x'] = 1\n    return run\n"
                                   "def local():\n    out = []\n    out.append(1)\n    return out\n")
    found = "\n".join(item_mutations(root))
    assert "fill: report['x']" in found and "grow: findings.append" in found and "deep: s.notes[0]" in found
    assert "own" not in found and "local" not in found


def test_mutation_checker_can_fail(tmp_path):
    root = _fake_package(tmp_path, "import copy\n"
                                   "def limit(prob):\n    prob.pipe.band = {}\n"
                                   "def alias(self):\n    pipe = self.pipe\n    pipe.band = {}\n"
                                   "def fine(self):\n    new = copy.copy(self)\n    new.band = {}\n    self.x = 1\n"
                                   "    return new\n"
                                   "def hidden(o):\n    setattr(o, 'band', 1)\n")
    found = "\n".join(mutations(root))
    assert "limit: prob.pipe.band" in found and "alias: pipe.band" in found and "hidden: setattr" in found
    assert "fine" not in found

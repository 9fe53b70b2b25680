"""Codebase rules: import direction, no global random state, no pickle-style loading."""

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = {"pgm": ROOT / "pgm", "pgm.inference": ROOT / "inference", "pgm.models": ROOT / "models"}


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes under ``if TYPE_CHECKING:`` (annotations only: no import at run time)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            out |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return out


def _imports(path: Path, typing_too: bool = True) -> list[str]:
    """Modules ``path`` imports: ``import``/``from`` statements (relative ones with their
    dots), and ``import_module("...")`` calls on a string literal; ``typing_too=False``
    leaves out those under ``if TYPE_CHECKING:``."""
    tree = ast.parse(path.read_text())
    skip = set() if typing_too else _type_checking_nodes(tree)
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0 and node.module:
                out.append(node.module)
            elif node.level > 0:
                out.append("." * node.level + (node.module or ""))
        elif isinstance(node, ast.Call) and node.args and \
                isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
            if name == "import_module":
                out.append(node.args[0].value)
    return out


def _py_files(folder: Path):
    return sorted(p for p in folder.rglob("*.py") if "__pycache__" not in p.parts)


#: what each layer of ``pgm`` may import from the others (DESIGN.md "Layers"): the
#: modelling layer's subpackages form a DAG rooted at ``core``; ``app`` sits on top.
ALLOWED = {
    "pgm.core": {"pgm.core"},
    "pgm.factors": {"pgm.core", "pgm.factors"},
    "pgm.io": {"pgm.core", "pgm.io"},
    "pgm.dynamics": {"pgm.core", "pgm.factors", "pgm.dynamics"},
    "pgm.plotting": {"pgm.core", "pgm.plotting"},
    "pgm.synthetic": {"pgm.core", "pgm.io", "pgm.synthetic"},
    "pgm.evaluation": {"pgm.core", "pgm.io", "pgm.evaluation"},
    "pgm.observation": {"pgm.core", "pgm.factors", "pgm.io", "pgm.observation"},
    "pgm.inference": {"pgm.core", "pgm.factors", "pgm.inference"},
    "pgm.models": {"pgm.core", "pgm.factors", "pgm.observation", "pgm.inference",
                   "pgm.dynamics", "pgm.models"},
    "pgm.app": None,  # the application layer may import everything
}
#: function-level imports allowed against the direction, each with its reason
LAZY_EXCEPTIONS = {
    # FactorGraph.draw()/to_dot() are conveniences that hand the graph to the plotter
    ("pgm.core.graph", "pgm.plotting.graph_drawing"),
}


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[0] in ("inference", "models"):
        parts = ["pgm"] + parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _layer(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else module


def _pgm_imports(path: Path, typing_too: bool = True) -> list[str]:
    """Absolute ``pgm`` modules imported by ``path`` (relative imports resolved)."""
    package = _module_name(path)
    if path.name != "__init__.py":
        package = package.rsplit(".", 1)[0]
    out = []
    for mod in _imports(path, typing_too):
        if mod.startswith("."):
            dots = len(mod) - len(mod.lstrip("."))
            base = package.split(".")[: len(package.split(".")) - (dots - 1)]
            rest = mod.lstrip(".")
            mod = ".".join(base + ([rest] if rest else []))
        if mod == "pgm" or mod.startswith("pgm."):
            out.append(mod)
    return out


def _layered_sources():
    return [p for folder in LAYERS.values() for p in _py_files(folder)
            if _module_name(p) != "pgm"]


@pytest.mark.parametrize("path", _layered_sources(),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_follow_the_layers(path):
    module = _module_name(path)
    allowed = ALLOWED[_layer(module)]
    if allowed is None:
        return
    for mod in _pgm_imports(path):
        if (module, mod) in LAZY_EXCEPTIONS:
            continue
        assert _layer(mod) in allowed, f"{module} imports {mod} (allowed: {sorted(allowed)})"


def test_every_subpackage_has_a_layer_rule():
    subpackages = {_module_name(p.parent / "__init__.py") for p in _layered_sources()}
    layers = {_layer(m) for m in subpackages if m != "pgm"}
    assert layers <= set(ALLOWED), sorted(layers - set(ALLOWED))


def _all_sources():
    return [p for folder in LAYERS.values() for p in _py_files(folder)]


@pytest.mark.parametrize("path", _all_sources(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_global_random_state_and_no_code_loading(path):
    text = path.read_text()
    for banned in ("np.random.seed", "np.random.rand(", "np.random.randn(", "np.random.normal(",
                   "np.random.uniform(", "np.random.choice(", "np.random.random(",
                   "torch.manual_seed", "import pickle", "pickle.load", " eval(", " exec("):
        assert banned not in text, f"{path.name} uses {banned}"


def _shipped_text_files():
    files = [ROOT / "README.md", ROOT / "CHANGELOG.md"]
    for folder in ("pgm", "inference", "models", "benchmarks", "docs", "tests"):
        files += [p for p in (ROOT / folder).rglob("*")
                  if p.suffix in (".py", ".md", ".txt", ".html", ".js")
                  and "__pycache__" not in p.parts and "results" not in p.parts]
    return sorted(files)


def test_papers_are_cited_by_authors_and_year():
    """A paper is named by its authors and year (``docs/references.md``), never by the
    number of its file in the project's seed folder or a section of an internal spec."""
    import re

    bad = re.compile(r"\b[Ss]eed 00\d\b|SPEC(\.md)?`*\s*§")
    found = [f"{p.relative_to(ROOT)}:{k}" for p in _shipped_text_files()
             for k, line in enumerate(p.read_text(errors="replace").splitlines(), 1)
             if bad.search(line)]
    assert not found, found


def test_no_import_circle_among_the_engine_modules():
    """The modules of ``pgm.inference`` import one another without a circle (imports
    inside functions count; annotations under ``TYPE_CHECKING`` do not): the engine core
    at the bottom, the rule families above it registering into its table."""
    folder = LAYERS["pgm.inference"]
    graph = {}
    for path in _py_files(folder):
        mod = _module_name(path)
        deps = {m for m in _pgm_imports(path, typing_too=False)
                if m.startswith("pgm.inference.") and m != mod}
        # "from . import a, b" inside the package names its submodules
        graph[mod] = deps
    mods = set(graph)
    for mod, deps in graph.items():
        graph[mod] = {d if d in mods else d.rsplit(".", 1)[0] for d in deps} & mods
    graph.pop("pgm.inference", None)  # the package's __init__ imports the families
    for deps in graph.values():
        deps.discard("pgm.inference")
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        path.append(m)
        for d in sorted(graph.get(m, ())):
            if state.get(d) == 1:
                cycle = path[path.index(d):] + [d]
                raise AssertionError("import circle: " + " -> ".join(cycle))
            if d not in state:
                visit(d)
        path.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)


def test_the_engine_step_loop_has_no_plate_branch():
    """What differs between one graph and a plate is the engine's runtime
    (``pgm.inference.single.SingleGraph``, ``pgm.inference.plates.PlateRuntime``): the
    engine and its weight stage never test whether a graph has a plate or replicas."""
    pattern = re.compile(r"(plate|replicas)\s+is\s+(not\s+)?None|if\s+(not\s+)?[\w.]*\.(plate|"
                         r"replicas|plates)\b|\bgraph\.plates\b")
    for name in ("engine.py", "weighting.py", "single.py"):
        text = (LAYERS["pgm.inference"] / name).read_text()
        hits = [line.strip() for line in text.splitlines() if pattern.search(line)]
        assert not hits, f"inference/{name} branches on the plate: {hits}"



def test_files_split_by_concern_stay_small():
    """No module of the toolkit is over 700 lines, and the three that were split by
    concern (the engine, the correlation filter, the runner) stay at most 500."""
    sizes = {p: len(p.read_text().splitlines()) for root in LAYERS.values()
             for p in root.rglob("*.py")}
    big = {str(p.relative_to(ROOT)): n for p, n in sizes.items() if n > 700}
    assert not big, f"modules over 700 lines: {big}"
    for rel in ("inference/engine.py", "pgm/observation/appearance/correlation.py",
                "pgm/app/runner.py"):
        assert sizes[ROOT / rel] <= 500, f"{rel}: {sizes[ROOT / rel]} lines"


def test_no_rule_state_under_string_keys_and_no_code_loading_in_the_core():
    """State between stages is typed (no ``aux[...]``) and the core imports nothing by
    name (saved graphs name their modules; finders registered above it load them)."""
    aux = [str(p.relative_to(ROOT)) for root in LAYERS.values() for p in root.rglob("*.py")
           if "aux[" in p.read_text()]
    assert not aux, f"string-keyed state in {aux}"
    core = [str(p.relative_to(ROOT)) for p in (ROOT / "pgm" / "core").rglob("*.py")
            if re.search(r"\bimportlib\b|\bimport_module\b", p.read_text())]
    assert not core, f"importlib in the core: {core}"


def test_the_tree_passes_the_linter():
    """``ruff check`` with the project's rules (``pyproject.toml``: pyflakes, pycodestyle,
    import order, bugbear, numpy) finds nothing in the package, tests, docs or
    benchmarks."""
    import importlib.util
    import subprocess
    import sys

    if importlib.util.find_spec("ruff") is None:
        pytest.skip("ruff is not installed (the test extra installs it: pip install -e '.[test]')")
    res = subprocess.run([sys.executable, "-m", "ruff", "check", ".", "--output-format",
                          "concise", "--no-cache"], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]

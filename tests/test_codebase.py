"""Codebase rules: import direction, no global random state, no pickle-style loading."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = {"pgm": ROOT / "pgm", "pgm.inference": ROOT / "inference", "pgm.models": ROOT / "models"}


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0 and node.module:
                out.append(node.module)
            elif node.level > 0:
                out.append("." * node.level + (node.module or ""))
    return out


def _py_files(folder: Path):
    return sorted(p for p in folder.rglob("*.py") if "__pycache__" not in p.parts)


@pytest.mark.parametrize("path", _py_files(ROOT / "pgm"), ids=lambda p: p.name)
def test_pgm_core_imports_neither_inference_nor_models(path):
    if path.name == "cli.py":  # the CLI sits on top of everything (STYLE.md §4.1)
        return
    for mod in _imports(path):
        assert not mod.startswith(("pgm.inference", "pgm.models", "inference", "models",
                                   ".inference", ".models")), f"{path.name} imports {mod}"


@pytest.mark.parametrize("path", _py_files(ROOT / "inference"), ids=lambda p: p.name)
def test_inference_does_not_import_models(path):
    for mod in _imports(path):
        assert not mod.startswith(("pgm.models", "models", "..models")), \
            f"{path.name} imports {mod}"


def _all_sources():
    return [p for folder in LAYERS.values() for p in _py_files(folder)]


@pytest.mark.parametrize("path", _all_sources(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_global_random_state_and_no_code_loading(path):
    text = path.read_text()
    for banned in ("np.random.seed", "np.random.rand(", "np.random.randn(", "np.random.normal(",
                   "np.random.uniform(", "np.random.choice(", "np.random.random(",
                   "torch.manual_seed", "import pickle", "pickle.load", " eval(", " exec("):
        assert banned not in text, f"{path.name} uses {banned}"

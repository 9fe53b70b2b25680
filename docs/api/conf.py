"""Sphinx configuration of the API reference (built from the numpydoc docstrings).

Build it with ``python -m sphinx -W -b html docs/api OUT_DIR`` (the ``docs`` extra:
``pip install -e '.[docs]'``); ``tests/test_docs.py`` builds it with warnings as errors.
"""

import importlib.util
import re
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

project = "pgm"
author = "The pgm developers"
copyright = "the pgm developers"  # noqa: A001 - Sphinx's name for it
from pgm import __version__ as release  # the package installed (pip install -e '.[docs]')

version = release

extensions = ["sphinx.ext.autodoc", "sphinx.ext.viewcode", "numpydoc"]

# the optional extras' packages, when not installed, are mocked so the reference builds
autodoc_mock_imports = [m for m in ("torch", "dask", "distributed")
                        if importlib.util.find_spec(m) is None]
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_typehints = "none"  # the numpydoc sections state the types

numpydoc_show_class_members = False  # members are documented by autodoc, once
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

html_theme = "alabaster"
html_title = f"pgm {release} API reference"
exclude_patterns = ["_build"]

# Every public module is documented, found in the source tree when the reference is built:
# a page holds ``.. pgm-modules:: GROUP``, expanded into one section per module of that
# subpackage (``core`` also takes the top-level ``pgm``). A module in no group fails the
# build.
GROUPS = ("core", "factors", "observation", "dynamics", "inference", "models", "io",
          "evaluation", "plotting", "synthetic", "app")


def public_modules() -> list[tuple[str, bool]]:
    """``(module name, is a package)`` of every public module, sorted by name."""
    found = []
    for folder in ("pgm", "inference", "models"):
        for path in (ROOT / folder).rglob("*.py"):
            if "__pycache__" in path.parts:
                continue
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[0] != "pgm":
                parts = ["pgm"] + parts
            package = parts[-1] == "__init__"
            if package:
                parts = parts[:-1]
            if not any(part.startswith("_") for part in parts):
                found.append((".".join(parts), package))
    return sorted(found)


def group_of(module: str) -> str:
    parts = module.split(".")
    group = "core" if len(parts) == 1 else parts[1]
    if group not in GROUPS:
        raise ValueError(f"{module} belongs to no page of the API reference: add "
                         f"{group!r} to GROUPS in docs/api/conf.py and a page for it")
    return group


def group_rst(group: str) -> str:
    out = []
    for module, package in public_modules():
        if group_of(module) != group:
            continue
        title = f"``{module}``"
        out += [title, "-" * len(title), "", f".. automodule:: {module}"]
        out += ["   :no-members:", ""] if package else [""]  # a package's names: documented
    return "\n".join(out)                                   # where they are defined


def _expand_groups(app, docname, source):
    source[0] = re.sub(r"^\.\. pgm-modules:: (\w+)$", lambda m: group_rst(m.group(1)),
                       source[0], flags=re.M)


# The docstrings cite a paper as ``[#key]`` and list it under "References" as a
# ``.. [#key]`` footnote, often citing it again from a class or method docstring of the
# module. On a page of the reference, each docstring's footnotes get labels of their own
# (``key`` prefixed with the documented object's name: two modules on one page may list
# the same paper), and a citation whose footnote is in the same docstring becomes a link;
# a citation of a footnote listed elsewhere stays text, so a footnote may be unreferenced.
suppress_warnings = ["ref.footnote"]

_FOOTNOTE = re.compile(r"^\s*\.\. \[#([\w.:+-]+)\]", re.M)


def _link_footnotes(app, what, name, obj, options, lines):
    text = "\n".join(lines)
    keys = set(_FOOTNOTE.findall(text))
    if not keys:
        return
    label = re.sub(r"[^\w]+", "-", name)

    def relabel(match):
        key = match.group(2)
        if key not in keys:
            return match.group(0)
        if match.group(1):  # the footnote itself
            return f"{match.group(1)}[#{label}-{key}]"
        return f"[#{label}-{key}]_"

    text = re.sub(r"(\.\. )?\[#([\w.:+-]+)\](?!_)", relabel, text)
    lines[:] = text.split("\n")


# numpydoc drops a section it does not know, with a Python warning that -W does not
# catch: a docstring's own heading before its first numpydoc section (``Calling
# conventions`` of RuleTable) becomes a rubric first, so its text is kept. numpydoc's
# signature pass re-reads the raw docstring and would still warn about it: silenced.
warnings.filterwarnings("ignore", message="Unknown section", category=UserWarning)
_NUMPYDOC_SECTIONS = {
    "parameters", "returns", "yields", "receives", "raises", "warns", "other parameters",
    "attributes", "methods", "see also", "notes", "warnings", "references", "examples",
}


def _rubric_own_headings(app, what, name, obj, options, lines):
    for i in range(len(lines) - 1):
        title, rule = lines[i].strip(), lines[i + 1].strip()
        if not title or len(rule) != len(title) or set(rule) != {"-"}:
            continue
        if title.lower() in _NUMPYDOC_SECTIONS:
            return  # numpydoc's sections from here on
        indent = lines[i][: len(lines[i]) - len(lines[i].lstrip())]
        lines[i], lines[i + 1] = f"{indent}.. rubric:: {title}", ""


def setup(app):
    for module, _ in public_modules():  # fail early on a module in no group
        group_of(module)
    app.connect("source-read", _expand_groups)
    # before numpydoc (priority 500) parses the docstring
    app.connect("autodoc-process-docstring", _rubric_own_headings, priority=400)
    # after numpydoc has rewritten the docstring into reST
    app.connect("autodoc-process-docstring", _link_footnotes, priority=600)

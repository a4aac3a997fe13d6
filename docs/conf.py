"""Sphinx configuration of the elastocap documentation (build: sphinx-build -W -b html docs OUT)."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from elastocap import __version__  # noqa: E402

project = "elastocap"
author = "the elastocap authors"
copyright = "the elastocap authors, MIT licence"
version = release = __version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_parser",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "img/*.json", "**/.ipynb_checkpoints"]
templates_path = ["_templates"]

# numpydoc docstrings, read by napoleon
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_param = False  # types as text, not as cross-references ("n", "Rod" are ambiguous)
napoleon_use_keyword = False
napoleon_preprocess_types = False

autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpydoc "Parameters" sections carry the types
autodoc_inherit_docstrings = False

myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

html_theme = "alabaster"
html_static_path: list[str] = []
html_title = f"elastocap {release}"

# Docstrings name types in prose ("ndarray", "list of dict"): not cross-reference targets, and
# a short attribute name ("n", "p") used as a type may match several attributes.
nitpicky = False
suppress_warnings = ["ref.python"]

#: Docstrings written as plain-text overviews (a signature list, formulas with ``*`` and
#: ``|``): shown verbatim rather than parsed as reStructuredText.
PLAIN_TEXT_DOCSTRINGS = {
    "continuation",
    "elastocap.capillary_hessian",
    "elastocap.statics.branches.newton",
}


def _plain_text(app, what, name, obj, options, lines):
    if name in PLAIN_TEXT_DOCSTRINGS and lines:
        lines[:] = ["::", ""] + ["    " + line for line in lines] + [""]
    else:
        lines[:] = _escape_bars(lines)


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _escape_bars(lines: list[str]) -> list[str]:
    """Docstrings write absolute values and norms as ``|x|``, which reStructuredText reads as
    substitution references: escape each bar outside inline literals and literal blocks."""
    out, block = [], None  # block: indent of the paragraph that opened a literal block
    for line in lines:
        if block is not None and line.strip() and _indent(line) <= block:
            block = None
        if block is None:
            parts = line.split("``")
            parts[::2] = [p.replace("|", "\\|") for p in parts[::2]]
            out.append("``".join(parts))
            if line.rstrip().endswith("::"):
                block = _indent(line)
        else:
            out.append(line)
    return out

#: The user guide in reading order. index.md lists those of them that exist (a topic's page may
#: not be written yet), then any other page of guide/ in alphabetical order.
GUIDE_ORDER = [
    "scenes",
    "statics-search",
    "supp-fig5-damping",
    "time-stepping",
    "continuation",
    "phase-diagrams",
    "fig3d",
    "strip",
    "accuracy",
]


def guide_pages() -> list[str]:
    here = {p.stem for p in (Path(__file__).parent / "guide").glob("*.md")}
    first = [n for n in GUIDE_ORDER if n in here]
    return [f"guide/{n}" for n in first + sorted(here - set(first))]


def _fill_guide_toctree(app, docname, source):
    if docname == "index":
        source[0] = source[0].replace("GUIDE_PAGES", "\n".join(guide_pages()))


def setup(app):
    app.connect("source-read", _fill_guide_toctree)
    app.connect("autodoc-process-docstring", _plain_text, priority=400)

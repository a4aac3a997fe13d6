"""The one-way dependencies of ARCHITECTURE.md: continuation imports only numpy/scipy,
dynamics only numpy/numba; neither imports the other nor elastocap."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ALLOWED = {
    "continuation": {"numpy", "scipy", "matplotlib", "continuation"},
    "dynamics": {"numpy", "numba", "dynamics"},
}


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
    return out


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_package_imports_only_allowed(package):
    stdlib = set(sys.stdlib_module_names) | {"__future__"}
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no sources found for {package}"
    for f in files:
        bad = _imports(f) - stdlib - ALLOWED[package]
        assert not bad, f"{f.relative_to(ROOT)} imports {sorted(bad)}"


# Branch.plot(ax=None) makes a pyplot figure for the caller, as matplotlib's own helpers do;
# nothing else in the libraries or the application touches pyplot or selects a backend.
PYPLOT_ALLOWED = {"continuation/_branch.py"}


def _process_wide_matplotlib(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [f"import {a.name}" for a in node.names if a.name == "matplotlib.pyplot"]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "matplotlib.pyplot" or (
                    node.module == "matplotlib" and any(a.name == "pyplot" for a in node.names)):
                found.append(f"from {node.module} import ...")
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == "use" and isinstance(node.func.value, ast.Name)
              and node.func.value.id == "matplotlib"):
            found.append(f"matplotlib.use(...) at line {node.lineno}")
    return found


@pytest.mark.parametrize("package", ["continuation", "dynamics", "elastocap"])
def test_no_process_wide_matplotlib_state(package):
    for f in sorted((ROOT / package).rglob("*.py")):
        rel = f.relative_to(ROOT).as_posix()
        bad = _process_wide_matplotlib(f)
        if rel in PYPLOT_ALLOWED:
            bad = [b for b in bad if not b.startswith(("import", "from"))]
        assert not bad, f"{rel}: {bad} (make figures with elastocap.figure.new_figure)"

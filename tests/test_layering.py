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

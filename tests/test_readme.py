"""The README stays true: its test command is what CI runs, its links and figures exist, it
stays a short reference."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _quick_start_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = text.split("```bash", 1)[1].split("```", 1)[0]
    return [
        line.strip()
        for line in block.strip().splitlines()
        if line.strip() and not line.startswith("#")
    ]


def test_quick_start_has_exactly_two_commands():
    cmds = _quick_start_commands()
    assert len(cmds) == 2, cmds
    assert cmds[0].endswith("elastocap demo")
    assert "pytest" in cmds[1]


def test_ci_runs_the_readme_test_command_verbatim():
    ci = (ROOT / ".ci" / "run").read_text()
    assert _quick_start_commands()[1] in ci.splitlines()


def test_readme_links_and_figures_exist():
    text = (ROOT / "README.md").read_text()
    targets = re.findall(r"\]\(([^)#\s]+)\)", text)
    local = [t for t in targets if "://" not in t]
    assert any(t.startswith("docs/img/") for t in local)
    assert any(t.startswith("docs/guide/") for t in local)
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, missing


def test_readme_is_a_short_reference():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 360
    for heading in ("## Quick start", "## Commands", "## Python API", "## Headline numbers",
                    "## Documentation"):
        assert heading in text
    assert "ARCHITECTURE.md" not in text


def _python_blocks() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return [b.split("```", 1)[0] for b in text.split("```python\n")[1:]]


def test_readme_has_three_api_examples():
    blocks = _python_blocks()
    assert len(blocks) == 3
    assert "trace_branches" in blocks[0] and "assert_folds" in blocks[0]
    assert "import elastocap as ec" in blocks[0]
    assert "run_impact" in blocks[1] and "run_overlay" in blocks[1]
    assert "run_sweep" in blocks[2] and "csv" in blocks[2]


@pytest.mark.slow
def test_readme_python_examples_run(tmp_path, monkeypatch):
    """The three API examples, run in sequence as a user pastes them (about 1 min)."""
    import json

    monkeypatch.chdir(tmp_path)
    # the reference file the first example checks against, as `elastocap folds --json` writes
    (tmp_path / "ref.json").write_text(json.dumps({"folds": [{"value": 3.469794751569}]}))
    ns: dict = {}
    for block in _python_blocks():
        exec(compile(block, "README.md", "exec"), ns)
    assert ns["res"].to_dict()["boundary"]
    assert (tmp_path / "out" / "sweep.csv").stat().st_size > 50
    assert (tmp_path / "out" / "overlay").is_dir()

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
def test_readme_python_examples_run(tmp_path):
    """The three API examples pasted into one script and run with python, as a user would
    (about 1 min): the sweep's local workers are spawned and import the script again."""
    import json
    import subprocess
    import sys

    # the reference file the first example checks against, as `elastocap folds --json` writes
    (tmp_path / "ref.json").write_text(json.dumps({"folds": [{"value": 3.469794751569}]}))
    script = "\n".join(_python_blocks()) + (
        "\nif __name__ == '__main__':\n    assert res.to_dict()['boundary']\n")
    (tmp_path / "readme_examples.py").write_text(script)
    done = subprocess.run([sys.executable, "readme_examples.py"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "out" / "sweep.csv").stat().st_size > 50
    assert (tmp_path / "out" / "overlay").is_dir()

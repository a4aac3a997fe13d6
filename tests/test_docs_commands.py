"""The documentation's commands and API calls are real: every ``elastocap ...`` command line
in docs/guide parses with the real parser, and every call of the README's Python examples
binds to the real signature (without running them; the run is tests/test_readme.py, slow)."""

import ast
import inspect
import re
import shlex
from pathlib import Path

import pytest

import elastocap
from elastocap.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]


def _guide_commands() -> list[tuple[str, str]]:
    """(page, command line) of every command in a fenced block or an inline code span."""
    found = []
    for page in sorted((ROOT / "docs" / "guide").glob("*.md")):
        text = page.read_text(encoding="utf-8")
        blocks = re.findall(r"```[a-z]*\n(.*?)```", text, flags=re.S)
        lines = [ln.strip() for b in blocks for ln in b.splitlines()]
        rest = re.sub(r"```[a-z]*\n.*?```", "", text, flags=re.S)
        lines += [s.strip() for s in re.findall(r"`([^`\n]+)`", rest)]
        for ln in lines:
            ln = ln.split(" #", 1)[0].strip().rstrip("\\").strip()
            if ln.startswith("$ "):
                ln = ln[2:]
            ln = re.split(r" [>|] ", ln)[0]  # a shell redirection or pipe
            if not re.match(r"elastocap [a-z]", ln):
                continue
            # a command line, not a mention of a command (`elastocap branches`) or a
            # synopsis with placeholders ([--json], A|B, ...)
            if len(ln.split()) < 3 or re.search(r"[\[\]|]|\.\.\.|…", ln):
                continue
            found.append((page.name, ln))
    return found


COMMANDS = _guide_commands()


def test_the_guide_shows_commands():
    assert len(COMMANDS) >= 5, COMMANDS


@pytest.mark.parametrize("page,line", COMMANDS, ids=[f"{p}:{c[:50]}" for p, c in COMMANDS])
def test_every_guide_command_parses(page, line):
    argv = shlex.split(line)[1:]
    args = build_parser().parse_args(argv)  # the real parser (a UsageError on a bad line)
    assert args.command == argv[0]


def _dotted(node):
    """``a.b.c`` of an attribute chain rooted at a name, else None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return [node.id, *reversed(parts)] if isinstance(node, ast.Name) else None


def _readme_calls():
    """(call node, dotted name, object) of every README call of an elastocap name; the
    blocks are read together, as a user pastes them in sequence."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    source = "\n".join(b.split("```", 1)[0] for b in text.split("```python\n")[1:])
    tree = ast.parse(source)
    aliases = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "elastocap":
                    aliases[a.asname or a.name] = __import__(a.name, fromlist=["_"])
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("elastocap"):
            mod = __import__(node.module, fromlist=["_"])
            for a in node.names:
                aliases[a.asname or a.name] = getattr(mod, a.name)  # an import that fails
    calls = []
    for node in ast.walk(tree):
        chain = _dotted(node.func) if isinstance(node, ast.Call) else None
        if not chain or chain[0] not in aliases:
            continue
        obj = aliases[chain[0]]
        for attr in chain[1:]:
            obj = getattr(obj, attr)  # a name the package does not have fails here
        calls.append((node, ".".join(chain), obj))
    return calls


def test_readme_api_calls_bind_to_the_real_signatures():
    calls = _readme_calls()
    bound = 0
    for node, name, fn in calls:
        if any(isinstance(a, ast.Starred) for a in node.args) or any(
                k.arg is None for k in node.keywords):
            continue
        sig = inspect.signature(fn)
        try:
            sig.bind(*[None] * len(node.args), **{k.arg: None for k in node.keywords})
        except TypeError as err:
            raise AssertionError(f"README: {name}({ast.unparse(node)[:80]}...): {err}") from None
        bound += 1
    names = {name for _, name, _ in calls}
    # the three examples call the main API, exported from the package
    assert {"ec.load_scene", "ec.trace_branches", "ec.run_impact", "ec.run_overlay",
            "ec.run_sweep", "ec.assert_folds", "ec.BranchSet.load"} <= names, names
    assert {"load_scene", "run_sweep", "assert_folds"} <= set(elastocap.__all__)
    assert bound == len(calls) >= 8


def test_every_parser_option_is_in_the_readme_commands_section():
    """Each option of each subcommand appears in the README's command table or in the
    notes under it (the "## Commands" section)."""
    from elastocap.cli import command_options

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    missing = {c: [o for o in opts if not re.search(re.escape(o) + r"(?![\w-])", section)]
               for c, opts in command_options().items()}
    missing = {c: o for c, o in missing.items() if o}
    assert not missing, f"options not in the README's commands section: {missing}"

"""The ``elastocap`` command: parsing and printing only; the work is in the library.

Every subcommand takes ``--json`` (one JSON object on stdout). Bad input exits with code 2
and a one-line message on stderr, and writes nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence

from elastocap._version import __version__
from elastocap.scene import SceneError, builtin_scene_names, load_scene

DEFAULT_SCENE = "supp-fig5"


class UsageError(Exception):
    """A command-line input error: exit code 2, message on stderr."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would print usage and exit itself
        raise UsageError(message)


def _jsonable(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    return obj


def _print_json(obj) -> None:
    print(json.dumps(_jsonable(obj), indent=2, sort_keys=False))


def _scene_args(p: argparse.ArgumentParser, default: str | None = None) -> None:
    if default is None:
        p.add_argument("scene", help="built-in scene name or path to a TOML file")
    else:
        p.add_argument("scene", nargs="?", default=default, help=f"scene (default: {default})")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scene key, e.g. --set drop.area=1.0 (repeatable)",
    )


def _fmt_block(title: str, d: dict, indent: int = 2) -> list[str]:
    lines = [f"{title}:"]
    for k, v in d.items():
        if isinstance(v, dict):
            lines += [" " * indent + line for line in _fmt_block(k, v, indent)]
        elif isinstance(v, float):
            lines.append(" " * indent + f"{k:<22} {v:.10g}")
        else:
            lines.append(" " * indent + f"{k:<22} {v}")
    return lines


def cmd_scenes(args) -> int:
    names = builtin_scene_names()
    if args.json:
        _print_json(
            {"scenes": [{"name": n, "description": load_scene(n).description} for n in names]}
        )
    else:
        for n in names:
            desc = load_scene(n).description.split(". ")[0]
            print(f"{n:<18} {desc}")
    return 0


def cmd_show(args) -> int:
    scene = load_scene(args.scene, args.overrides)
    summary = scene.summary()
    summary["version"] = __version__
    if args.json:
        _print_json(summary)
        return 0
    print(f"scene {scene.name}  (elastocap {__version__})")
    if scene.description:
        print("  " + " ".join(scene.description.split()))
    for key in ("rod", "drop", "effects", "spreading", "numerics", "derived"):
        if summary[key] is not None:
            print("\n".join(_fmt_block(key, summary[key])))
    return 0


def cmd_demo(args) -> int:
    """The quick-start job on the default scene."""
    return cmd_show(args)


COMMANDS: dict[str, tuple[Callable, str]] = {
    "scenes": (cmd_scenes, "list the built-in scenes"),
    "show": (cmd_show, "print a validated scene and its derived quantities"),
    "demo": (cmd_demo, "the quick-start tour on the default scene"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="elastocap", description="Elasto-capillary continuation and dynamics.")
    parser.add_argument("--version", action="version", version=f"elastocap {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, (func, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(func=func)
        p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
        if name == "show":
            _scene_args(p)
        elif name == "demo":
            _scene_args(p, default=DEFAULT_SCENE)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit code (0 ok, 1 check failed, 2 bad input)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 2
        return int(args.func(args))
    except (UsageError, SceneError) as err:
        print(f"elastocap: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

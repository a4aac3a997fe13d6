"""Command-line options shared by every command that takes a scene (used by elastocap.cli
and elastocap.sweep.cli): the scene, ``--set KEY=VALUE`` and ``--accuracy``."""

from __future__ import annotations

import argparse

from elastocap.scene import Scene, load_scene

__all__ = ["load_scene_from_args", "scene_arguments"]


def scene_arguments(p: argparse.ArgumentParser, default: str | None = None) -> None:
    """Add the scene (positional; optional when ``default`` is given), --set, --accuracy."""
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
    p.add_argument(
        "--accuracy",
        choices=("draft", "default", "publication"),
        help="resolution and tolerance preset (same as --set numerics.accuracy=...)",
    )


def load_scene_from_args(args) -> Scene:
    """The scene of a command: name or path, --set overrides, --accuracy."""
    over = list(args.overrides)
    if getattr(args, "accuracy", None):
        over.append(f"numerics.accuracy={args.accuracy}")
    return load_scene(args.scene, over)



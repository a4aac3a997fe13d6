"""``python -m elastocap.sweep SCENE ...``: the sweep command on its own (the same options
and exit codes as ``elastocap sweep``: 0 ok, 1 some runs raised, 2 bad input)."""

from __future__ import annotations

import argparse
import sys

from elastocap.scene import SceneError
from elastocap.sweep import cli


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise _UsageError(message)


def main(argv=None) -> int:
    parser = _Parser(prog="python -m elastocap.sweep", description=cli.__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    cli.add_arguments(parser)
    try:
        return cli.run(parser.parse_args(argv))
    except (_UsageError, SceneError, ValueError) as err:
        print(f"elastocap: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

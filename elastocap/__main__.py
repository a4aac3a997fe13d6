"""``python -m elastocap``: the same command as ``elastocap``."""

import sys

from elastocap.cli import main

if __name__ == "__main__":
    sys.exit(main())

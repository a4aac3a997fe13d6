"""Regenerate the paper's supplementary Fig 6 (also: `elastocap figures --only supp-fig6`)."""

import sys

from elastocap.paper_figures.supp_fig6 import main

if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "out/figures"))

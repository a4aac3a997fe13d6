"""Regenerate one of the paper's figures (also: `elastocap figures --only supp-fig5`)."""

import sys

from elastocap.paper_figures.supp_fig5 import main

if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "out/figures"))

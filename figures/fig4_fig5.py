"""Regenerate one of the paper's figures (also: `elastocap figures --only fig4-fig5`)."""

import sys

from elastocap.paper_figures.fig4_fig5 import main

if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "out/figures"))

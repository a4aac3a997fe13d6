"""Regenerate one of the paper's figures (also: `elastocap figures --only energy-barrier`)."""

import sys

from elastocap.paper_figures.energy_barrier import main

if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "out/figures"))

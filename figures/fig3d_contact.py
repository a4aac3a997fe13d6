"""Regenerate one of the paper's figures (also: `elastocap figures --only fig3d-contact`)."""

import sys

from elastocap.paper_figures.fig3d_contact import main

if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "out/figures"))

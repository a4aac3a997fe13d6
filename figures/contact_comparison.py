"""Regenerate one of the paper's figures (also: `elastocap figures --only contact-comparison`)."""

import sys

from elastocap.paper_figures.contact_comparison import main

if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "out/figures"))

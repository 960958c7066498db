"""``python -m gmsfric.loop ...`` runs ``gmsfric loop ...`` (same arguments, same runner)."""

import sys

from ..cli import main

sys.exit(main(["loop", *sys.argv[1:]]))

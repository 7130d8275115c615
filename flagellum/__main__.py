"""``python -m flagellum``: the same command line as ``flagellum`` (``flagellum.cli.main``)."""

import sys

from flagellum.cli import main

sys.exit(main())

"""Command-line front end and plotting for the head + flagellum swimmer.

The physics lives in the ``physics`` package; ``flagellum`` only parses arguments, calls the
library and writes files. Entry point: ``flagellum.cli:main`` (console script ``flagellum``).
"""

from __future__ import annotations

__version__ = "0.1.0"

"""Compatibility alias: the sweep moved to ``batch.sweep`` (issue 16).

Kept only because ``scripts/reproduce_fig4.py`` still imports ``flagellum.sweep``; once that
import reads ``from batch.sweep import ...`` this file goes. Nothing in the packages imports it.
"""

from batch.sweep import load_sweep_config, run_sweep  # noqa: F401

"""Benchmarks of the simulator, below the command line: the fidelity ladder and ``bench --quick``
(``fidelity.py``), its report (``report.py``: tables, JSON, the Pareto figure) and the node-count convergence
study (``node_convergence.py``). ``flagellum bench`` and ``scripts/bench_*.py`` call them; they import the
layers below (physics, batch, flagellum_env, agents), never the CLI package ``flagellum``.
"""

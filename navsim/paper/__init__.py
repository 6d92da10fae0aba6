"""Reproductions of the seed papers' experiments.

Each module ``seedNNN`` has ``run(plot_dir=None, quick=False) -> list[dict]`` returning
rows ``{"ref", "quantity", "paper", "navsim", "unit"}`` (``paper`` is ``None`` where the
paper prints no number) and, with ``plot_dir``, writing one PNG per experiment.
"""

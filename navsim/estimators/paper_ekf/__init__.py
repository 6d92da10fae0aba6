"""The track-model INS/GNSS filter of seed 003 (Sokolov & Vdovichenko 2012), as a package.

The model, its equations and the options are described in :mod:`navsim.estimators.paper_ekf.filter`.
"""

from .filter import (
    PaperEkf,
    PaperEkfConfig,
    TrackFunctions,
    input_polynomial_matrix,
    paper_state,
    printed_observer_13,
    printed_state_rhs,
)

__all__ = [
    "PaperEkf",
    "PaperEkfConfig",
    "TrackFunctions",
    "paper_state",
    "input_polynomial_matrix",
    "printed_observer_13",
    "printed_state_rhs",
]

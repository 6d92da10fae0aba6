"""Shared error-state INS machinery (package form; the model and the engine: :mod:`.engine`)."""

from .engine import (
    ATT,
    BA,
    BG,
    N_STATES,
    NAV,
    POS,
    VEL,
    AuxBlocksIns,
    AuxStateIns,
    BodyTerms,
    ErrorStateIns,
    ImuNoise,
    StepTerms,
    body_terms,
    body_velocity_terms,
    compensate_increments,
    correct_state,
    error_dynamics,
    joseph_update,
    lever_arm_terms,
    nis_threshold,
    noise_density,
    solution_rows,
    state_from_prior,
    transition,
)

__all__ = [
    "N_STATES", "POS", "VEL", "ATT", "BG", "BA", "NAV", "ImuNoise", "error_dynamics", "noise_density", "transition",
    "joseph_update", "correct_state", "lever_arm_terms", "compensate_increments", "solution_rows",
    "state_from_prior", "BodyTerms", "StepTerms", "body_terms", "ErrorStateIns", "AuxBlocksIns", "AuxStateIns",
    "body_velocity_terms", "nis_threshold",
]
